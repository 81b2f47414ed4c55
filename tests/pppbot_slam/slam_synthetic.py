"""Synthetic worlds of wall segments and an exact lidar for SLAM tests (no physics, no ROS)."""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from pppbot_common.se2 import se2_compose, se2_inverse

# A 6 × 4 m room with a 1 × 0.6 m box and a pillar: enough structure to pin every axis.
ROOM = np.array([
    [-3, -2, 3, -2], [3, -2, 3, 2], [3, 2, -3, 2], [-3, 2, -3, -2],
    [1, 0.5, 2, 0.5], [2, 0.5, 2, 1.1], [2, 1.1, 1, 1.1], [1, 1.1, 1, 0.5],
    [-1.6, -1.0, -1.3, -1.0], [-1.3, -1.0, -1.3, -0.7], [-1.3, -0.7, -1.6, -0.7], [-1.6, -0.7, -1.6, -1.0],
], dtype=float)
CORRIDOR = np.array([[-20, -0.7, 20, -0.7], [-20, 0.7, 20, 0.7]], dtype=float)


def box(x0: float, y0: float, x1: float, y1: float) -> np.ndarray:
    return np.array([[x0, y0, x1, y0], [x1, y0, x1, y1], [x1, y1, x0, y1], [x0, y1, x0, y0]], dtype=float)


def wall_points(segments: np.ndarray, spacing: float = 0.02) -> np.ndarray:
    pieces = []
    for x0, y0, x1, y1 in segments:
        n = max(2, int(math.hypot(x1 - x0, y1 - y0) / spacing) + 1)
        t = np.linspace(0, 1, n)[:, None]
        pieces.append(np.array([x0, y0]) + t * np.array([x1 - x0, y1 - y0]))
    return np.vstack(pieces)


def beam_angles(beams: int = 640) -> np.ndarray:
    return np.linspace(-math.pi, math.pi, beams, endpoint=False)


def cast_ranges(segments: np.ndarray, pose: np.ndarray, beams: int = 640, noise: float = 0.0,
                seed: int = 0, angles: np.ndarray | None = None) -> np.ndarray:
    """Ranges (inf: no return) of a lidar at ``pose`` with beams from −π (or at ``angles``, rad in
    the sensor frame): ray-segment intersections."""
    angles = beam_angles(beams) if angles is None else np.asarray(angles, dtype=float)
    beams = len(angles)
    d = np.stack([np.cos(angles + pose[2]), np.sin(angles + pose[2])], axis=1)
    a, b = segments[:, :2], segments[:, 2:]
    e = b - a
    denom = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]
    w = a[None, :, :] - pose[None, None, :2]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (w[..., 0] * e[None, :, 1] - w[..., 1] * e[None, :, 0]) / denom
        u = (w[..., 0] * d[:, None, 1] - w[..., 1] * d[:, None, 0]) / denom
    t = np.where((denom != 0) & (t > 0) & (u >= 0) & (u <= 1), t, np.inf)
    ranges = t.min(axis=1)
    if noise:
        ranges = ranges + np.random.default_rng(seed).normal(0, noise, beams)
    return ranges


def cast(segments: np.ndarray, pose: np.ndarray, beams: int = 640, max_range: float = 20.0,
         noise: float = 0.0, seed: int = 0) -> np.ndarray:
    """Scan points (sensor frame) of a lidar at ``pose``."""
    ranges = cast_ranges(segments, pose, beams, noise, seed)
    angles = beam_angles(beams)
    keep = ranges < max_range
    return np.stack([np.cos(angles), np.sin(angles)], axis=1)[keep] * ranges[keep, None]


# A ring corridor 2 m wide around a 6 × 4 m block, with pillars so that the straight parts
# are not featureless.
PILLARS = [box(x - 0.15, y - 0.15, x + 0.15, y + 0.15) for x, y in
           [(-1.5, -3.6), (2.0, -3.6), (4.6, 0.5), (0.5, 3.6), (-2.5, 3.6), (-4.6, -1.0)]]
RING = np.vstack([box(-5, -4, 5, 4), box(-3, -2, 3, 2), *PILLARS])


def ring_path(step_m: float = 0.1, overlap_m: float = 4.0) -> np.ndarray:
    """Around the block counter-clockwise from (0, −3), and on past the start by ``overlap_m``."""
    corners = np.array([[0, -3], [4, -3], [4, 3], [-4, 3], [-4, -3], [0, -3], [overlap_m, -3]], dtype=float)
    poses = []
    for a, b in zip(corners[:-1], corners[1:], strict=True):
        yaw = math.atan2(*(b - a)[::-1])
        n = int(round(np.linalg.norm(b - a) / step_m))
        poses += [(*(a + (b - a) * k / n), yaw) for k in range(n)]
    return np.array(poses)


def drifting_odometry(truth: np.ndarray, yaw_per_m: float, scale: float) -> np.ndarray:
    odom = [truth[0].copy()]
    for prev, cur in zip(truth[:-1], truth[1:], strict=True):
        step = se2_compose(se2_inverse(prev), cur)
        moved = math.hypot(step[0], step[1])
        odom.append(se2_compose(odom[-1], [step[0] * scale, step[1] * scale, step[2] + yaw_per_m * moved]))
    return np.array(odom)


def feed(mapper: Any, world: np.ndarray, truth: np.ndarray, odom: np.ndarray, first: int = 0) -> None:
    """Scans of ``world`` from ``truth[first:]`` into a mapper with their odometry, at 10 Hz
    (scan k is stamped 0.1·k s)."""
    for k in range(first, len(truth)):
        mapper.process(0.1 * k, odom[k - first], scan_rays(world, truth[k], seed=k))


def scan_rays(world: np.ndarray, pose: np.ndarray, seed: int) -> Any:
    """A 640-beam scan of ``world`` from ``pose`` (1 cm noise) as the mapper takes it."""
    from pppbot_slam.occupancy import ScanRays

    angles = beam_angles()
    return ScanRays.from_laser(float(angles[0]), float(angles[1] - angles[0]),
                               cast_ranges(world, pose, noise=0.01, seed=seed), 0.08, 20.0)
