"""A LaserScan as the SLAM cores take it, for the mapping and the localization node alike."""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
from sensor_msgs.msg import LaserScan

from pppbot_slam.async_mapper import ScanInput
from pppbot_slam.occupancy import OccupancyError, ScanRays


def scan_input(msg: LaserScan, stamp: float, frame: str, odom_pose: np.ndarray, sensor: np.ndarray,
               warn: Callable[[str, str], None]) -> ScanInput | None:
    """The scan with its odometry pose and sensor offset, or None (said through ``warn``) when its
    ranges or angles are malformed."""
    try:
        rays = ScanRays.from_laser(msg.angle_min, msg.angle_increment, np.asarray(msg.ranges, dtype=float),
                                   msg.range_min, msg.range_max)
    except OccupancyError as exc:
        warn("scan", f"dropping a malformed scan: {exc}")
        return None
    return ScanInput(stamp, frame, odom_pose, sensor, rays, tag=msg.header.stamp)
