"""MuJoCo simulator node for ppp_bot: Gazebo-style SDF worlds, spawning, lidar, IMU, clock, ground-truth maps."""
