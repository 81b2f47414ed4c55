"""The robot's footprint as Nav2's costmap publishes it (``published_footprint``): a circle of the
robot's radius made a polygon, padded, placed at the robot's pose in the costmap's frame."""
from __future__ import annotations

import math

import numpy as np

#: Nav2's makeFootprintFromRadius: a circular robot as a polygon of this many points
CIRCLE_POINTS = 16


def circle_footprint(radius_m: float, padding_m: float = 0.0, points: int = CIRCLE_POINTS) -> np.ndarray:
    """A circular footprint ((points, 2), in the robot's frame), ``padding_m`` wider, as Nav2 pads it.

    Raises:
        ValueError: a radius or padding that is not a finite number, a negative padded radius, or
            fewer than three points.
    """
    if not (math.isfinite(radius_m) and math.isfinite(padding_m)) or radius_m + padding_m < 0 or points < 3:
        raise ValueError(f"a footprint needs a finite radius + padding >= 0 and 3 or more points, got radius "
                         f"{radius_m}, padding {padding_m}, {points} points")
    angles = 2.0 * math.pi * np.arange(points) / points
    r = radius_m + padding_m
    return np.column_stack((r * np.cos(angles), r * np.sin(angles)))


def placed(footprint: np.ndarray, pose: tuple[float, float, float]) -> np.ndarray:
    """``footprint`` ((N, 2), robot frame) at ``pose`` (x, y, yaw) in the costmap's frame."""
    x, y, yaw = pose
    c, s = math.cos(yaw), math.sin(yaw)
    f = np.asarray(footprint, dtype=float).reshape(-1, 2)
    return np.column_stack((x + c * f[:, 0] - s * f[:, 1], y + s * f[:, 0] + c * f[:, 1]))
