"""ppp_bot robot description (modular xacro) and a robot_state_publisher node."""
