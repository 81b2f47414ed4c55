"""Shared pure-Python helpers for pppbot: SE(2) math, map file I/O, grid ray casting, process control, and thin ROS helpers (QoS, message types, graph waits)."""
