"""Thin helpers over rclpy shared by pppbot's nodes, tools and tests.

Only modules under a package's ``ros`` subpackage may import rclpy or message
packages; everything else in pppbot is ROS-free core (tests/test_core_imports.py).
"""
