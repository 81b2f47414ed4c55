"""Costmaps without ROS: Nav2's cost values, a 2D costmap (static or rolling) and its layers."""
