"""Shared code of pppbot's packages: errors, node parameters, map files (Nav2 YAML + PGM),
process control, DDS isolation, name:=value arguments, and thin ROS helpers in ``ros/``
(QoS presets, interface lookup, graph waits, a node's main)."""
