"""ROS adapters of the controller, mux and teleop."""
