"""The ROS side of pppbot_lockstep."""
