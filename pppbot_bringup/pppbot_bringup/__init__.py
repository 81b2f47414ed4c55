"""pppbot bringup (launch_sim), process supervisor, rosbag2 tools and the pppbot command line."""
