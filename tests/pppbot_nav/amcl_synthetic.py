"""A synthetic world for AMCL tests: wall segments, their occupancy grid and an exact lidar."""
from __future__ import annotations

import math

import numpy as np

from pppbot_common.maps import OCCUPIED, UNKNOWN, OccupancyGrid
from pppbot_common.se2 import se2_compose
from pppbot_nav.amcl.laser import LaserSettings, Scan

RESOLUTION = 0.05
LIDAR = (0.1, 0.0, 0.0)  # the lidar in the base frame
BEAMS = 360
RANGE_MAX = 12.0


def box(x0: float, y0: float, x1: float, y1: float) -> list[list[float]]:
    return [[x0, y0, x1, y0], [x1, y0, x1, y1], [x1, y1, x0, y1], [x0, y1, x0, y0]]


# An 8 × 6 m room with an L-shaped wall, a box and a pillar: no symmetry to confuse a global search.
WALLS = np.array([*box(-4, -3, 4, 3), [-1, -3, -1, 0.5], [-1, 0.5, -2.5, 0.5], *box(1.5, 0.8, 2.5, 1.6),
                  *box(2.0, -2.0, 2.3, -1.7)], dtype=float)


def grid(segments: np.ndarray = WALLS, margin_m: float = 0.5) -> OccupancyGrid:
    """Occupied cells along the segments, free inside their bounds, unknown in a margin around.
    Cell centres lie on the walls' lines (a wall on a cell boundary would be drawn half a cell off)."""
    low = segments.reshape(-1, 2).min(axis=0) - margin_m - RESOLUTION / 2
    high = segments.reshape(-1, 2).max(axis=0) + margin_m
    shape = np.ceil((high - low) / RESOLUTION).astype(int)[::-1]
    data = np.zeros(shape, dtype=np.int8)
    data[:round(margin_m / RESOLUTION)] = UNKNOWN
    data[-round(margin_m / RESOLUTION):] = UNKNOWN
    data[:, :round(margin_m / RESOLUTION)] = UNKNOWN
    data[:, -round(margin_m / RESOLUTION):] = UNKNOWN
    result = OccupancyGrid(data, RESOLUTION, (float(low[0]), float(low[1]), 0.0))
    for x0, y0, x1, y1 in segments:
        t = np.linspace(0.0, 1.0, int(math.hypot(x1 - x0, y1 - y0) / (RESOLUTION / 4)) + 2)
        rows, cols = result.cell_of(x0 + t * (x1 - x0), y0 + t * (y1 - y0))
        result.data[rows, cols] = OCCUPIED
    return result


def ranges(pose: np.ndarray, segments: np.ndarray = WALLS, beams: int = BEAMS, noise_m: float = 0.0,
           rng: np.random.Generator | None = None) -> np.ndarray:
    """Exact ranges (inf: nothing within reach) of the lidar on a robot at ``pose``, beams from −π."""
    lidar = np.array([pose[0] + math.cos(pose[2]) * LIDAR[0], pose[1] + math.sin(pose[2]) * LIDAR[0]])
    angles = pose[2] + LIDAR[2] + np.linspace(-math.pi, math.pi, beams, endpoint=False)
    d = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    a, e = segments[:, :2], segments[:, 2:] - segments[:, :2]
    denom = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]
    w = a[None, :, :] - lidar[None, None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (w[..., 0] * e[None, :, 1] - w[..., 1] * e[None, :, 0]) / denom
        u = (w[..., 0] * d[:, None, 1] - w[..., 1] * d[:, None, 0]) / denom
    t = np.where((denom != 0) & (t > 0) & (u >= 0) & (u <= 1), t, np.inf).min(axis=1)
    if noise_m:
        t = t + (rng or np.random.default_rng(0)).normal(0.0, noise_m, beams)
    return np.where(t > RANGE_MAX, np.inf, t)


def scan(pose: np.ndarray, settings: LaserSettings = LaserSettings(), max_beams: int | None = None,
         noise_m: float = 0.0, rng: np.random.Generator | None = None) -> Scan:
    return Scan.from_laser(ranges(pose, noise_m=noise_m, rng=rng), -math.pi, 2 * math.pi / BEAMS, 0.12, RANGE_MAX,
                           LIDAR, settings, max_beams)


#: A loop round the room, clear of every wall by 0.4 m or more.
ROUTE = np.array([[0.5, -1.0], [3.2, -1.0], [3.2, 2.2], [-3.0, 2.2], [-3.0, -2.2], [-1.6, -2.2]])


def drive(route: np.ndarray = ROUTE, step_m: float = 0.05, turn_step_rad: float = 0.1, slip: float = 0.01,
          seed: int = 0) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """Poses along ``route`` (turning on the spot, then straight): (distance so far, true pose,
    odometry pose) every step; odometry scales each step by 1 + N(0, ``slip``)."""
    rng = np.random.default_rng(seed)
    truth = np.array([*route[0], 0.0])
    odom = np.zeros(3)
    distance = 0.0
    out = [(0.0, truth.copy(), odom.copy())]
    for target in route[1:]:
        while True:
            d = target - truth[:2]
            if math.hypot(*d) < 1e-6:
                break
            turn = math.remainder(math.atan2(d[1], d[0]) - truth[2], 2 * math.pi)
            if abs(turn) > 1e-6:
                step = np.array([0.0, 0.0, float(np.clip(turn, -turn_step_rad, turn_step_rad))])
            else:
                step = np.array([min(step_m, math.hypot(*d)), 0.0, 0.0])
            truth = se2_compose(truth, step)
            odom = se2_compose(odom, step * (1.0 + rng.normal(0.0, slip, 3)))
            distance += step[0]
            out.append((distance, truth.copy(), odom.copy()))
    return out
