"""ROS adapters of pppbot_nav."""
