"""The evaluation node, its behaviours (drive a route, start AMCL, send goals) and ``pppbot eval`` (rclpy)."""
