"""pppbot bringup (launch_sim), process supervisor, evaluation and the pppbot command line."""
