"""rosbag2 bags without ROS 2's rosbag2: MCAP storage, metadata.yaml (version 9),
splitting, compression, reading back, recovery. No rclpy here; the recorder and the
player nodes in ``pppbot_bag.ros`` adapt this to topics; ``pppbot_bag.cli`` is ``pppbot bag``."""
