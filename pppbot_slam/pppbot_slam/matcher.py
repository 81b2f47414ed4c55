"""Correlative scan matching on a smoothed likelihood grid, coarse to fine, refined below a cell.

A :class:`LikelihoodField` is made from points already in the map (the hits of
recent scans, or of older scans for loop closure): each cell holds
``exp(-d² / 2σ²)`` for the distance ``d`` to the nearest map point, σ being the
smear (slam_toolbox's ``correlation_search_space_smear_deviation``). A scan at a
candidate pose scores the mean likelihood of its points (the *response*, 0–1).

:func:`match` searches a window around a prior pose (odometry):

1. coarse: every angle of the coarse step across ±``search_angle_rad``, every
   translation of the coarse grid across the window, on a field at the coarse
   resolution, with a subset of the points — whole cells, so scoring is lookups;
2. fine: around the coarse best, ±½ coarse step at the fine steps, scored with
   cubic-spline interpolation in the fine field;
3. refine: a local optimisation of that smooth response from the fine best
   (sub-cell accuracy).

Responses are multiplied by slam_toolbox's distance and angle penalties (so in a
featureless corridor the match stays near the prior), and the covariance comes
from the spread of the good coarse candidates, as Karto does. No ROS here.

Olson, "Real-Time Correlative Scan Matching", ICRA 2009; Konolige et al.,
"Efficient Sparse Pose Adjustment for 2D Mapping" (Karto), IROS 2010.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage, optimize

from pppbot_common.errors import PppbotError
from pppbot_common.se2 import PoseLike, se2_apply, wrap_angles

#: slam_toolbox (Karto) penalty gain on the squared distance and angle from the prior.
PENALTY_GAIN = 0.2


class MatcherError(PppbotError, ValueError):
    """Bad matcher settings, or nothing to match against; the message names the value."""


@dataclass(frozen=True)
class MatcherSettings:
    """Search window and steps; the defaults are ppp_bot's slam_toolbox parameters."""

    search_size_m: float = 0.5  # correlation_search_space_dimension: full width of the window
    fine_resolution_m: float = 0.01  # correlation_search_space_resolution
    coarse_resolution_m: float = 0.05
    smear_m: float = 0.1  # correlation_search_space_smear_deviation
    search_angle_rad: float = 0.349  # coarse_search_angle_offset: ± around the prior
    coarse_angle_step_rad: float = 0.0349  # coarse_angle_resolution
    fine_angle_step_rad: float = 0.00349  # fine_search_angle_offset
    distance_variance_penalty: float = 0.5
    angle_variance_penalty: float = 1.0
    minimum_distance_penalty: float = 0.5
    minimum_angle_penalty: float = 0.9
    coarse_points: int = 200  # points used in the coarse stage (evenly subsampled)

    def __post_init__(self) -> None:
        for name in ("search_size_m", "fine_resolution_m", "coarse_resolution_m", "smear_m", "coarse_angle_step_rad",
                     "fine_angle_step_rad", "distance_variance_penalty", "angle_variance_penalty"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise MatcherError(f"{name} must be a positive number, not {value}")
        if not (math.isfinite(self.search_angle_rad) and 0 <= self.search_angle_rad <= math.pi):
            raise MatcherError(f"search_angle_rad must be in [0, π], not {self.search_angle_rad}")
        for name in ("minimum_distance_penalty", "minimum_angle_penalty"):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0 <= value <= 1):
                raise MatcherError(f"{name} must be in [0, 1], not {value}")
        if self.fine_resolution_m > self.coarse_resolution_m:
            raise MatcherError(f"fine_resolution_m {self.fine_resolution_m} must not exceed coarse_resolution_m "
                               f"{self.coarse_resolution_m}")
        if self.coarse_points < 3:
            raise MatcherError(f"coarse_points must be at least 3, not {self.coarse_points}")


class LikelihoodField:
    """``exp(-d²/2σ²)`` on a grid of ``resolution_m`` around map points (world frame)."""

    def __init__(self, points_xy: np.ndarray, resolution_m: float, smear_m: float, margin_m: float) -> None:
        points = np.asarray(points_xy, dtype=float).reshape(-1, 2)
        points = points[np.isfinite(points).all(axis=1)]
        if not len(points):
            raise MatcherError("no map points to match against")
        self.resolution_m = resolution_m
        self.origin = np.floor((points.min(axis=0) - margin_m) / resolution_m) * resolution_m
        shape = np.ceil((points.max(axis=0) + margin_m - self.origin) / resolution_m).astype(int) + 1
        cells = np.floor((points - self.origin) / resolution_m).astype(int)
        height, width = shape[1], shape[0]  # [row = y, col = x]
        flat = cells[:, 1] * width + cells[:, 0]
        count = np.bincount(flat, minlength=height * width)
        hit = (count > 0).reshape(height, width)
        # Each hit cell keeps the mean of its points, and distances are measured to that
        # point, not to the cell: rasterising alone would shift walls by up to half a cell.
        mean = np.stack([np.bincount(flat, points[:, k], height * width) for k in (0, 1)], axis=-1)
        has = count > 0
        mean[has] = mean[has] / count[has, None]
        nearest = ndimage.distance_transform_edt(~hit, return_distances=False, return_indices=True)
        rows, cols = np.indices((height, width))
        centres = self.origin + (np.stack([cols, rows], axis=-1) + 0.5) * resolution_m
        distance_m = np.linalg.norm(centres - mean.reshape(height, width, 2)[nearest[0], nearest[1]], axis=-1)
        self.values = np.exp(-0.5 * (distance_m / smear_m) ** 2)
        # Cubic B-spline coefficients: a smooth response whose peak can lie between cell
        # centres (bilinear interpolation peaks only at them, biasing by up to half a cell).
        self._spline = ndimage.spline_filter(self.values, order=3, mode="constant")

    def cells(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Integer (row, col) of world points; may be out of range."""
        ij = np.floor((xy - self.origin) / self.resolution_m).astype(np.int64)
        return ij[..., 1], ij[..., 0]

    def lookup(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Values at integer cells; 0 outside the grid."""
        height, width = self.values.shape
        inside = (rows >= 0) & (rows < height) & (cols >= 0) & (cols < width)
        out = np.zeros(rows.shape)
        out[inside] = self.values[rows[inside], cols[inside]]
        return out

    def interpolate(self, xy: np.ndarray) -> np.ndarray:
        """Values at world points, cubic-spline interpolated between cell centres; 0 outside."""
        grid = (xy - self.origin) / self.resolution_m - 0.5
        return np.asarray(ndimage.map_coordinates(self._spline, [grid[..., 1].ravel(), grid[..., 0].ravel()],
                                                  order=3, mode="constant", cval=0.0,
                                                  prefilter=False)).reshape(xy.shape[:-1])


@dataclass(frozen=True)
class MatchResult:
    pose: np.ndarray  # (x, y, yaw) of the scan's frame in the map
    response: float  # penalised mean likelihood at the result, 0–1
    raw_response: float  # without the penalties
    covariance: np.ndarray  # (3, 3) in x, y, yaw


def _penalty(dx: np.ndarray, dy: np.ndarray, dyaw: np.ndarray, s: MatcherSettings) -> np.ndarray:
    distance = np.maximum(1.0 - PENALTY_GAIN * (dx * dx + dy * dy) / s.distance_variance_penalty,
                          s.minimum_distance_penalty)
    angle = np.maximum(1.0 - PENALTY_GAIN * dyaw * dyaw / s.angle_variance_penalty, s.minimum_angle_penalty)
    return np.asarray(distance * angle)


def _subsample(points: np.ndarray, count: int) -> np.ndarray:
    if len(points) <= count:
        return points
    return points[np.linspace(0, len(points) - 1, count).round().astype(int)]


class ScanMatcher:
    """Matches scans against one map (the points given); reuse it for several scans."""

    def __init__(self, map_points_xy: np.ndarray, settings: MatcherSettings = MatcherSettings()) -> None:
        self.settings = settings
        margin = settings.search_size_m + 1.0
        self.coarse = LikelihoodField(map_points_xy, settings.coarse_resolution_m,
                                      max(settings.smear_m, settings.coarse_resolution_m), margin)
        self.fine = LikelihoodField(map_points_xy, min(settings.fine_resolution_m * 2.5, settings.coarse_resolution_m),
                                    settings.smear_m, margin)

    def response(self, scan_xy: np.ndarray, pose: PoseLike) -> float:
        """Mean interpolated likelihood of the scan's points at ``pose`` (no penalty)."""
        return float(self.fine.interpolate(se2_apply(np.asarray(pose, dtype=float), scan_xy)).mean())

    def match(self, scan_xy: np.ndarray, prior: PoseLike) -> MatchResult:
        """The best pose of the scan (points (K, 2) in its own frame) near ``prior``.

        Raises:
            MatcherError: fewer than 3 finite scan points.
        """
        points = np.asarray(scan_xy, dtype=float).reshape(-1, 2)
        points = points[np.isfinite(points).all(axis=1)]
        if len(points) < 3:
            raise MatcherError(f"a scan needs at least 3 finite points to match, not {len(points)}")
        prior_pose = np.asarray(prior, dtype=float)
        coarse, candidates, responses = self._coarse(_subsample(points, self.settings.coarse_points), prior_pose)
        fine = self._fine(points, prior_pose, coarse)
        refined = self._refine(points, prior_pose, fine)
        raw = self.response(points, refined)
        offset = refined - prior_pose
        penalised = raw * float(_penalty(offset[0], offset[1], wrap_angles(offset[2]), self.settings))
        return MatchResult(refined, penalised, raw, self._covariance(candidates, responses))

    def _coarse(self, points: np.ndarray, prior: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The best coarse pose, and every coarse candidate (C, 3) with its penalised response."""
        s = self.settings
        steps = int(math.floor(s.search_angle_rad / s.coarse_angle_step_rad + 1e-9))
        dyaws = np.arange(-steps, steps + 1) * s.coarse_angle_step_rad
        half = int(math.floor(s.search_size_m / 2 / s.coarse_resolution_m + 1e-9))
        offsets = np.arange(-half, half + 1)
        dy, dx = np.meshgrid(offsets * s.coarse_resolution_m, offsets * s.coarse_resolution_m, indexing="ij")
        all_candidates, all_scores = [], []
        for dyaw in dyaws:
            rotated = se2_apply(np.array([prior[0], prior[1], prior[2] + dyaw]), points)
            rows, cols = self.coarse.cells(rotated)
            # (K, W, W): every point under every integer shift of the window
            grid_rows, grid_cols = np.broadcast_arrays(rows[:, None, None] + offsets[None, :, None],
                                                       cols[:, None, None] + offsets[None, None, :])
            scores = self.coarse.lookup(grid_rows, grid_cols).mean(axis=0)
            all_scores.append((scores * _penalty(dx, dy, np.full(dx.shape, dyaw), s)).ravel())
            all_candidates.append(np.stack([prior[0] + dx.ravel(), prior[1] + dy.ravel(),
                                            np.full(dx.size, prior[2] + dyaw)], axis=-1))
        candidates, scores = np.concatenate(all_candidates), np.concatenate(all_scores)
        return candidates[int(np.argmax(scores))], candidates, scores

    def _fine(self, points: np.ndarray, prior: np.ndarray, coarse: np.ndarray) -> np.ndarray:
        s = self.settings
        # The coarse best is within half a coarse step of the best: search that at the fine steps.
        n_xy = max(1, int(round(s.coarse_resolution_m / 2 / s.fine_resolution_m)))
        n_yaw = max(1, int(round(s.coarse_angle_step_rad / 2 / s.fine_angle_step_rad)))
        shifts = np.arange(-n_xy, n_xy + 1) * s.fine_resolution_m
        dyaws = np.arange(-n_yaw, n_yaw + 1) * s.fine_angle_step_rad
        yaw, dy, dx = np.meshgrid(coarse[2] + dyaws, coarse[1] + shifts, coarse[0] + shifts, indexing="ij")
        candidates = np.stack([dx.ravel(), dy.ravel(), yaw.ravel()], axis=-1)  # (C, 3)
        cos, sin = np.cos(candidates[:, 2]), np.sin(candidates[:, 2])
        world = np.empty((len(candidates), len(points), 2))
        world[..., 0] = candidates[:, 0, None] + cos[:, None] * points[None, :, 0] - sin[:, None] * points[None, :, 1]
        world[..., 1] = candidates[:, 1, None] + sin[:, None] * points[None, :, 0] + cos[:, None] * points[None, :, 1]
        raw = self.fine.interpolate(world).mean(axis=1)
        offsets = candidates - prior
        responses = raw * _penalty(offsets[:, 0], offsets[:, 1], wrap_angles(offsets[:, 2]), s)
        return np.asarray(candidates[int(np.argmax(responses))])

    def _refine(self, points: np.ndarray, prior: np.ndarray, start: np.ndarray) -> np.ndarray:
        s = self.settings
        scale = np.array([s.fine_resolution_m, s.fine_resolution_m, s.fine_angle_step_rad])

        def cost(z: np.ndarray) -> float:
            pose = start + z * scale
            offset = pose - prior
            penalty = float(_penalty(offset[0], offset[1], wrap_angles(offset[2]), s))
            return -self.response(points, pose) * penalty

        result = optimize.minimize(cost, np.zeros(3), method="Powell",
                                   bounds=[(-1.0, 1.0)] * 3, options={"xtol": 0.02, "ftol": 1e-6})
        refined = start + result.x * scale
        if cost(result.x) > cost(np.zeros(3)):
            refined = start
        refined[2] = float(wrap_angles(refined[2]))
        return np.asarray(refined)

    def _covariance(self, candidates: np.ndarray, responses: np.ndarray) -> np.ndarray:
        """Spread of the coarse candidates within 90 % of the best response (as Karto estimates it
        from its search), with a floor of one fine step."""
        s = self.settings
        good = responses >= 0.9 * responses.max()
        weights = responses[good] / responses[good].sum()
        mean = (candidates[good] * weights[:, None]).sum(axis=0)
        centred = candidates[good] - mean
        covariance = (centred * weights[:, None]).T @ centred
        floor = np.diag([s.fine_resolution_m ** 2, s.fine_resolution_m ** 2, s.fine_angle_step_rad ** 2])
        return np.asarray(covariance + floor)
