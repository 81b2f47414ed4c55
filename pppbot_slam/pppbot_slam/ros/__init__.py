"""ROS adapters of pppbot_slam."""
