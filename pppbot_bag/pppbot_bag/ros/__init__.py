"""rosbag2 record and play nodes (rclpy): the bag core (``pppbot_bag``) over topics."""
