"""Random reachable navigation goals on a ground-truth grid (no ROS here).

A goal is a pose whose position has at least ``clearance_m`` to every obstacle cell
(so it is a valid goal for a costmap that inflates by the robot radius, with room to
spare) and lies in the free space the robot can reach from its start: the
4-connected region, of the cells farther than ``robot_radius_m`` from obstacles,
that holds the start. Goals come as a chain, each at least ``min_distance_m`` in a
straight line from the one before (the first from the start), with a uniform random
heading; every goal is then reachable from every other, whatever happens between.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy import ndimage

from pppbot_common.maps import OccupancyGrid
from pppbot_eval.errors import GoalSamplingError
from pppbot_eval.map_quality import cell_centers_xy, cells_of, in_grid
from pppbot_eval.shortest_path import free_space


def reachable_region(truth: OccupancyGrid, start_xy: Sequence[float], robot_radius_m: float) -> np.ndarray:
    """(height, width) bool: the free space (robot centre farther than ``robot_radius_m`` from obstacles)
    4-connected to the start's cell.

    Raises:
        GoalSamplingError: the start is outside the grid or not in free space.
    """
    free = free_space(truth, robot_radius_m)
    row, col = (int(v) for v in cells_of(truth, np.asarray(start_xy, dtype=float)))
    if not in_grid(truth, np.array(row), np.array(col)) or not free[row, col]:
        raise GoalSamplingError(f"start ({start_xy[0]}, {start_xy[1]}) m is not in free space for a robot of "
                                f"radius {robot_radius_m} m (cell ({row}, {col}))")
    labels, _ = ndimage.label(free)
    return np.asarray(labels == labels[row, col])


def sample_goals(truth: OccupancyGrid, start_xy: Sequence[float], count: int, rng: np.random.Generator,
                 robot_radius_m: float = 0.3, clearance_m: float = 0.45,
                 min_distance_m: float = 2.0) -> list[tuple[float, float, float]]:
    """``count`` goals (x, y, yaw) in the truth's frame, drawn with ``rng`` (see the module doc).

    Raises:
        GoalSamplingError: a bad count or distance, a blocked start, no cell with the clearance in
            the reachable region, or no candidate far enough from the previous goal.
    """
    if count < 0:
        raise GoalSamplingError(f"count must be a non-negative number of goals, not {count}")
    for name, value in (("robot_radius_m", robot_radius_m), ("clearance_m", clearance_m),
                        ("min_distance_m", min_distance_m)):
        if not (math.isfinite(value) and value >= 0):
            raise GoalSamplingError(f"{name} must be a non-negative number, not {value}")
    region = reachable_region(truth, start_xy, robot_radius_m)
    rows, cols = np.nonzero(region & free_space(truth, max(clearance_m, robot_radius_m)))
    if not rows.size:
        raise GoalSamplingError(f"no cell reachable from ({start_xy[0]}, {start_xy[1]}) m has {clearance_m} m "
                                "of clearance for a goal")
    centres = cell_centers_xy(truth, rows, cols)
    goals: list[tuple[float, float, float]] = []
    previous = np.asarray(start_xy, dtype=float)
    for _ in range(count):
        far = np.flatnonzero(np.linalg.norm(centres - previous, axis=1) >= min_distance_m)
        if not far.size:
            raise GoalSamplingError(f"no goal candidate is {min_distance_m} m from ({previous[0]:.2f}, "
                                    f"{previous[1]:.2f}) m")
        x, y = centres[int(rng.choice(far))]
        goals.append((round(float(x), 3), round(float(y), 3), round(float(rng.uniform(-math.pi, math.pi)), 3)))
        previous = np.array([x, y])
    return goals
