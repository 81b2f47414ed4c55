"""The viz node and the Foxglove bridge: ROS messages in, rerun and Foxglove out."""
