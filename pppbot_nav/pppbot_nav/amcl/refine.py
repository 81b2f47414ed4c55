"""Refining the filter's estimate by fitting the whole scan to the map (beyond Nav2's AMCL).

The particle filter's estimate is a weighted mean of particles that the motion noise
keeps spread by several centimetres, and it weighs only ``max_beams`` beams through a
wide ``sigma_hit``: good for robustness, coarse for accuracy. Here the estimate is
polished with every beam: Gauss-Newton on the distance from each beam's end point to
the map's nearest occupied cell (bilinear in the cell-centre distance field), with
Cauchy weights so that beams on things the map lacks count little — the point-to-map
least squares of scan matchers such as Hector SLAM. The result is kept only when it
stays near the filter's estimate and fits better than it; otherwise the filter's estimate
stands. The particles themselves are left as they are.
"""
from __future__ import annotations

import math

import numpy as np

from pppbot_nav.amcl.laser import MapField, Scan

ITERATIONS = 10
#: Cauchy scale (m): a beam this far from the map counts half.
ROBUST_SCALE_M = 0.05
DAMPING = 1e-3
#: A refined estimate farther than this from the filter's (m, rad) is not trusted.
MAX_SHIFT_M = 0.3
MAX_TURN_RAD = 0.15
#: End points farther than this from any wall (m) are left out (unmapped things, glass, max range).
INLIER_DISTANCE_M = 0.3
#: Fewer inliers than this and there is too little to fit.
MIN_INLIERS = 20


#: An end point within this of a wall (m) counts as fitting the map (:meth:`ScanFitter.fit_fraction`).
FIT_DISTANCE_M = 0.1


class ScanFitter:
    def __init__(self, field: MapField) -> None:
        self.grid = field.grid
        self.distance = field.occupied_distance_m  # cell centre to nearest occupied centre (m)

    def _sample(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Bilinear distance (m) and its gradient at points; off the map the edge value."""
        g = self.grid
        fx = (x - g.origin[0]) / g.resolution - 0.5
        fy = (y - g.origin[1]) / g.resolution - 0.5
        h, w = self.distance.shape[0], self.distance.shape[1]
        # (np.minimum/np.maximum: the same as np.clip, without its per-call overhead on every scan)
        fx, fy = np.minimum(np.maximum(fx, 0.0), w - 1.001), np.minimum(np.maximum(fy, 0.0), h - 1.001)
        c0, r0 = np.floor(fx).astype(int), np.floor(fy).astype(int)
        ax, ay = fx - c0, fy - r0
        d = self.distance
        d00, d01, d10, d11 = d[r0, c0], d[r0, c0 + 1], d[r0 + 1, c0], d[r0 + 1, c0 + 1]
        value = (d00 * (1 - ax) + d01 * ax) * (1 - ay) + (d10 * (1 - ax) + d11 * ax) * ay
        gx = ((d01 - d00) * (1 - ay) + (d11 - d10) * ay) / g.resolution
        gy = ((d10 - d00) * (1 - ax) + (d11 - d01) * ax) / g.resolution
        return value, gx, gy

    def fit_fraction(self, pose: np.ndarray, scan: Scan) -> float:
        """The share of ``scan``'s end points (beams that hit) within :data:`FIT_DISTANCE_M` of a
        wall of the map with the robot at ``pose``: near 1 where the scan fits, well below it at a
        place that only looks alike (a maze cell two cells off fits 40–85 %)."""
        hit = scan.ranges < scan.range_max
        if not hit.any() or not np.isfinite(self.distance).all():
            return 0.0
        r, b = scan.ranges[hit], scan.bearings[hit]
        d, _, _ = self._sample(*_transform(np.asarray(pose, dtype=float), scan.origin[0] + r * np.cos(b),
                                           scan.origin[1] + r * np.sin(b)))
        return float(np.mean(d <= FIT_DISTANCE_M))

    def refine(self, start: np.ndarray, scan: Scan) -> np.ndarray | None:
        """The pose near ``start`` (x, y, yaw) where ``scan``'s end points lie closest to the map's
        walls; None when too few beams hit near a wall or the fit does not improve."""
        if not np.isfinite(self.distance).all():
            return None  # a map without walls
        hit = scan.ranges < scan.range_max
        r, b = scan.ranges[hit], scan.bearings[hit]
        qx, qy = scan.origin[0] + r * np.cos(b), scan.origin[1] + r * np.sin(b)
        pose = np.asarray(start, dtype=float).copy()
        d0, _, _ = self._sample(*_transform(pose, qx, qy))
        inlier = d0 < INLIER_DISTANCE_M
        if inlier.sum() < MIN_INLIERS:
            return None
        qx, qy = qx[inlier], qy[inlier]
        start_cost = _cost(d0[inlier])
        for _ in range(ITERATIONS):
            wx, wy = _transform(pose, qx, qy)
            d, gx, gy = self._sample(wx, wy)
            c, s = math.cos(pose[2]), math.sin(pose[2])
            dtheta = gx * (-s * qx - c * qy) + gy * (c * qx - s * qy)
            jac = np.column_stack([gx, gy, dtheta])
            weight = 1.0 / (1.0 + (d / ROBUST_SCALE_M) ** 2)
            jtw = jac.T * weight
            hessian = jtw @ jac
            hessian += DAMPING * np.diag(np.diag(hessian) + 1e-9)
            step = np.linalg.solve(hessian, -jtw @ d)
            pose += step
            if abs(step[0]) + abs(step[1]) < 1e-5 and abs(step[2]) < 1e-5:
                break
        d, _, _ = self._sample(*_transform(pose, qx, qy))
        cost = _cost(d)
        shift = math.hypot(pose[0] - start[0], pose[1] - start[1])
        turn = abs(math.remainder(pose[2] - start[2], 2.0 * math.pi))
        if cost >= start_cost or shift > MAX_SHIFT_M or turn > MAX_TURN_RAD:
            return None
        pose[2] = math.remainder(pose[2], 2.0 * math.pi)
        return pose


def _transform(pose: np.ndarray, qx: np.ndarray, qy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return pose[0] + c * qx - s * qy, pose[1] + s * qx + c * qy


def _cost(d: np.ndarray) -> float:
    """The Cauchy loss of the distances (what the weights minimise)."""
    return float(np.log1p((d / ROBUST_SCALE_M) ** 2).sum())
