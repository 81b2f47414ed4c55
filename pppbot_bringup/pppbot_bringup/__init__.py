"""pppbot bringup (launch_sim), process supervisor and the pppbot command line."""
