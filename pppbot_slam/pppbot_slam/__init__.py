"""Online asynchronous grid SLAM with loop closure for ppp_bot (slam_toolbox's role)."""
