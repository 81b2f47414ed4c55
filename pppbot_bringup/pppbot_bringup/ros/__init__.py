"""ROS adapters of the command line (rclpy)."""
