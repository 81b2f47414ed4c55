"""Differential-drive controller, twist_mux and keyboard teleop for ppp_bot, with a ROS-free
kinematics and odometry core."""
