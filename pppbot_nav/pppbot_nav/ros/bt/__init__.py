"""Nav2's behaviour-tree nodes on ROS messages, and the navigator's trees."""
