"""Synthetic worlds of wall segments and an exact lidar for SLAM tests (no physics, no ROS)."""
from __future__ import annotations

import math

import numpy as np

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
                seed: int = 0) -> np.ndarray:
    """Ranges (inf: no return) of a lidar at ``pose`` with beams from −π: ray-segment intersections."""
    angles = beam_angles(beams)
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
