"""ROS adapters of the robot description (robot_state_publisher)."""
