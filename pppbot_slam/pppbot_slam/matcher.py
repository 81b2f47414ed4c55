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
2. refine: from the coarse best (within half a coarse step of the optimum),
   Gauss-Newton steps on the smooth response (cubic-spline interpolation) to its
   maximum, below a cell, in a sharper field (``refine_smear_m``) around the scan; the
   better of the two poses is kept;
3. polish (when map and scan have surface normals): point-to-plane least squares, each
   scan point against the nearest map point facing the same way (``polish_iterations``),
   which no grid limits, within one fine step of the refined pose. The result's response
   is that of the search's field.

Responses are multiplied by slam_toolbox's distance and angle penalties (so in a
featureless corridor the match stays near the prior), and the covariance comes
from the spread of the good coarse candidates, as Karto does. No ROS here.

Olson, "Real-Time Correlative Scan Matching", ICRA 2009; Konolige et al.,
"Efficient Sparse Pose Adjustment for 2D Mapping" (Karto), IROS 2010; Kohlbrecher et al.,
"A Flexible and Scalable SLAM System with Full 3D Motion Estimation" (Hector SLAM), SSRR 2011.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from pppbot_common.se2 import PoseLike, se2_apply, wrap_angles
from pppbot_slam.errors import MatcherError
from pppbot_slam.likelihood_field import BLOCK, NORMAL_CLASSES, LikelihoodField, normal_classes, rotate

#: slam_toolbox (Karto) penalty gain on the squared distance and angle from the prior.
PENALTY_GAIN = 0.2


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
    #: The smear of the field the sub-cell refinement climbs (see :meth:`ScanMatcher.refine_field`).
    refine_smear_m: float = 0.05
    #: Point-to-plane steps after the refinement (0: none; see :meth:`ScanMatcher.polish`).
    polish_iterations: int = 10
    #: Refine and score against the map points themselves (their nearest neighbour, a k-d tree)
    #: instead of interpolated grids (see :meth:`ScanMatcher.exact_values`).
    refine_exact: bool = True

    def __post_init__(self) -> None:
        for name in ("search_size_m", "fine_resolution_m", "coarse_resolution_m", "smear_m", "refine_smear_m",
                     "coarse_angle_step_rad",
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
        if self.polish_iterations < 0:
            raise MatcherError(f"polish_iterations must be 0 or more, not {self.polish_iterations}")


#: Branch and bound: shifts are bounded in blocks of BLOCK × BLOCK cells, and at most
#: MAX_BLOCKS blocks are scored cell by cell.
MAX_BLOCKS = 400
#: Gauss-Newton refinement: at most this many steps, damped by this fraction of the diagonal.
GAUSS_NEWTON_ITERATIONS = 10
GAUSS_NEWTON_DAMPING = 0.1
#: The exact refinement's iterations: nearest points change between steps, so it creeps where
#: the grid's smooth field jumps (a wall drawn twice 4 cm apart: 20 steps to the right one).
EXACT_GAUSS_NEWTON_ITERATIONS = 30
#: Point-to-plane polish: a scan point pairs with the nearest map point within this distance
#: (m) whose normal is within 60° of its own, and weighs by Cauchy's kernel of this scale (m).
#: The search has put the pose within a fine step, so a true pair is a few cm apart at most
#: (at 10 cm, in a cone field, each cone's points paired across it and the drive's error doubled).
POLISH_PAIR_M = 0.05
POLISH_KERNEL_M = 0.02
POLISH_NORMAL_COS = 0.5
#: ... and steps only along directions whose curvature is at least this share of the
#: largest (see ``_well_posed_step``), the heading counted at this lever (m).
POLISH_WELL_POSED = 0.05
POLISH_LEVER_M = 1.0
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


def _well_posed_step(hessian: np.ndarray, gradient: np.ndarray) -> np.ndarray:
    """The damped Gauss-Newton step ``-H⁻¹g`` taken only along the directions the scan pins: those
    of ``hessian``'s eigenvalues at least :data:`POLISH_WELL_POSED` of the largest (heading in
    metres at a 1 m lever, so the three compare). Along a corridor's length a few faint
    features would otherwise slide the pose; there it stays where the search put it."""
    scale = np.array([1.0, 1.0, POLISH_LEVER_M])
    values, vectors = np.linalg.eigh(hessian / np.outer(scale, scale))
    keep = values >= POLISH_WELL_POSED * max(float(values[-1]), 1e-12)
    scaled_gradient = gradient / scale
    damped = values[keep] * (1.0 + GAUSS_NEWTON_DAMPING)
    step = -(vectors[:, keep] @ ((vectors[:, keep].T @ scaled_gradient) / damped))
    return np.asarray(step / scale)


def _subsample(points: np.ndarray, count: int) -> np.ndarray:
    if len(points) <= count:
        return points
    return points[np.linspace(0, len(points) - 1, count).round().astype(int)]


class ScanMatcher:
    """Matches scans against one map (the points given); reuse it for several scans."""

    def __init__(self, map_points_xy: np.ndarray, settings: MatcherSettings = MatcherSettings(),
                 map_normals_xy: np.ndarray | None = None) -> None:
        """``map_normals_xy``: the map points' unit surface normals; with them, scans given
        with normals are matched face to face (see :data:`NORMAL_CLASSES`)."""
        self.settings = settings
        self._map = (np.asarray(map_points_xy, dtype=float), map_normals_xy)
        self._margin = settings.search_size_m + 1.0
        self.coarse = LikelihoodField(map_points_xy, settings.coarse_resolution_m,
                                      max(settings.smear_m, settings.coarse_resolution_m), self._margin, map_normals_xy)
        self._fine_field: LikelihoodField | None = None
        self._tree: cKDTree | None = None

    @property
    def fine(self) -> LikelihoodField:
        """The field scored with interpolation: the coarse one when the smear spans two of its
        cells or more (a cubic spline then follows exp(-d²/2σ²) closely), else a finer one."""
        s = self.settings
        if self._fine_field is None:
            if s.smear_m >= 2 * s.coarse_resolution_m:
                self._fine_field = self.coarse
            else:
                resolution = max(min(s.fine_resolution_m * 2.5, s.coarse_resolution_m), s.smear_m / 2)
                self._fine_field = LikelihoodField(self._map[0], resolution, s.smear_m, self._margin, self._map[1])
        return self._fine_field

    def refine_field(self, scan_points: np.ndarray, pose: np.ndarray) -> LikelihoodField:
        """The field the refinement from ``pose`` climbs: the smear's field when it is already as
        sharp as ``refine_smear_m``, else one of that smear over the map points near the scan's.
        A wide smear makes the search robust but flattens the peak: on the generated worlds'
        drives (tune set) the SLAM pose's error was 1.2–3.4 times that with a refinement at 5 cm."""
        s = self.settings
        if s.refine_smear_m >= s.smear_m:
            return self.fine
        placed = se2_apply(pose, scan_points)
        reach_m = float(np.hypot(scan_points[:, 0], scan_points[:, 1]).max()) * s.coarse_angle_step_rad
        margin = s.coarse_resolution_m + reach_m + 4 * s.refine_smear_m  # as far as the refinement may move
        low, high = placed.min(axis=0) - margin, placed.max(axis=0) + margin
        map_points, map_normals = self._map
        near = np.all((map_points >= low) & (map_points <= high), axis=1)
        if near.sum() < 3:
            return self.fine
        resolution = max(min(s.fine_resolution_m * 2.5, s.coarse_resolution_m), s.refine_smear_m / 2)
        return LikelihoodField(map_points[near], resolution, s.refine_smear_m, margin,
                               None if map_normals is None else np.asarray(map_normals)[near])

    def response(self, scan_xy: np.ndarray, pose: PoseLike, scan_normals_xy: np.ndarray | None = None) -> float:
        """Mean interpolated likelihood of the scan's points at ``pose`` (no penalty)."""
        pose = np.asarray(pose, dtype=float)
        classes = None if scan_normals_xy is None else normal_classes(rotate(scan_normals_xy, pose[2]))
        return self._likelihood(scan_xy, classes, pose)

    def likelihoods(self, scan_xy: np.ndarray, pose: PoseLike, scan_normals_xy: np.ndarray | None = None) -> np.ndarray:
        """Each scan point's likelihood at ``pose`` (K,) at the smear: interpolated in its field, or
        exact (``refine_exact``)."""
        pose = np.asarray(pose, dtype=float)
        classes = None if scan_normals_xy is None else normal_classes(rotate(scan_normals_xy, pose[2]))
        if self.settings.refine_exact:
            return self.exact_values(se2_apply(pose, scan_xy), classes, self.settings.smear_m)[0]
        return np.asarray(self.fine.interpolate(se2_apply(pose, scan_xy), classes))

    @property
    def tree(self) -> cKDTree:
        """A k-d tree of the map points (made on first use)."""
        if self._tree is None:
            self._tree = cKDTree(self._map[0])
        return self._tree

    def exact_values(self, world_xy: np.ndarray, classes: np.ndarray | None,
                     sigma_m: float) -> tuple[np.ndarray, np.ndarray]:
        """``exp(-d²/2σ²)`` of each point (K, 2, in the map) to its nearest map point, 0 where that
        point faces away from the scan point's normal class (as the grids' classes do) or lies
        beyond 4σ; and the offsets point − nearest (K, 2). What the likelihood grids sample at
        their cells, without their cells (no half-cell shift, no interpolation between them)."""
        distances, nearest = self.tree.query(world_xy, distance_upper_bound=4.0 * sigma_m)
        found = np.isfinite(distances)
        index = np.where(found, nearest, 0)
        map_points, map_normals = self._map
        offsets = np.where(found[:, None], world_xy - map_points[index], 0.0)
        values = np.where(found, np.exp(-0.5 * (np.where(found, distances, 0.0) / sigma_m) ** 2), 0.0)
        if classes is not None and map_normals is not None and NORMAL_CLASSES > 1:
            angle = classes * (2 * np.pi / NORMAL_CLASSES)
            normals = np.asarray(map_normals)[index]
            values = np.where(normals[:, 0] * np.cos(angle) + normals[:, 1] * np.sin(angle) > 0, values, 0.0)
        return np.asarray(values), np.asarray(offsets)

    def _likelihood(self, points: np.ndarray, classes: np.ndarray | None, pose: np.ndarray,
                    field: LikelihoodField | None = None) -> float:
        """Mean interpolated likelihood of points (in their normal classes) placed at ``pose``, in
        ``field`` (default: the smear's)."""
        return float((field or self.fine).interpolate(se2_apply(pose, points), classes).mean())

    def match(self, scan_xy: np.ndarray, prior: PoseLike, scan_normals_xy: np.ndarray | None = None,
              coarse_only: bool = False) -> MatchResult:
        """The best pose of the scan (points (K, 2) in its own frame, with their unit surface
        normals when the map has them) near ``prior``; ``coarse_only`` stops after the coarse
        search (its best candidate, response and covariance).

        Raises:
            MatcherError: fewer than 3 finite scan points.
        """
        points = np.asarray(scan_xy, dtype=float).reshape(-1, 2)
        finite = np.isfinite(points).all(axis=1)
        points = points[finite]
        normals = None if scan_normals_xy is None else np.asarray(scan_normals_xy, dtype=float).reshape(-1, 2)[finite]
        if len(points) < 3:
            raise MatcherError(f"a scan needs at least 3 finite points to match, not {len(points)}")
        prior_pose = np.asarray(prior, dtype=float)
        few = _subsample(np.arange(len(points)), self.settings.coarse_points)
        coarse, candidates, responses = self._coarse(points[few], None if normals is None else normals[few],
                                                     prior_pose)
        if coarse_only:
            top = float(responses.max())
            penalty = self._penalty_at(coarse, prior_pose)
            return MatchResult(coarse, top, top / max(penalty, 1e-12), self._covariance(candidates, responses))
        classes = None if normals is None else normal_classes(rotate(normals, coarse[2]))
        s = self.settings
        best, best_score = coarse, -1.0
        if s.refine_exact:
            sigma = min(s.refine_smear_m, s.smear_m)
            for pose in (coarse, self._gauss_newton_exact(points, classes, coarse, sigma)):
                score = self._exact_mean(points, classes, pose, sigma) * self._penalty_at(pose, prior_pose)
                if score > best_score:
                    best, best_score = pose, score
        else:
            field = self.refine_field(points, coarse)
            for pose in (coarse, self._gauss_newton(points, classes, coarse, field)):
                score = self._likelihood(points, classes, pose, field) * self._penalty_at(pose, prior_pose)
                if score > best_score:
                    best, best_score = pose, score
        if normals is not None and self._map[1] is not None and s.polish_iterations:
            best = self.polish(points, normals, best)
        raw = self._exact_mean(points, classes, best, s.smear_m) if s.refine_exact \
            else self._likelihood(points, classes, best)
        return MatchResult(best, raw * self._penalty_at(best, prior_pose), raw,
                           self._covariance(candidates, responses))

    def _exact_mean(self, points: np.ndarray, classes: np.ndarray | None, pose: np.ndarray, sigma_m: float) -> float:
        return float(self.exact_values(se2_apply(pose, points), classes, sigma_m)[0].mean())

    def _gauss_newton_exact(self, points: np.ndarray, classes: np.ndarray | None, start: np.ndarray,
                            sigma_m: float) -> np.ndarray:
        """:meth:`_gauss_newton`'s steps on the exact likelihood (:meth:`exact_values`): each point's
        gradient ``-f·(p − q)/σ²`` towards its nearest map point ``q``, no grid, no spline; the same
        damping and the same limit of a coarse step from ``start``."""
        s = self.settings
        sigma2 = sigma_m ** 2
        limit = np.array([s.coarse_resolution_m, s.coarse_resolution_m, s.coarse_angle_step_rad])
        pose = np.asarray(start, dtype=float).copy()
        best, best_score = pose.copy(), -1.0
        for _ in range(EXACT_GAUSS_NEWTON_ITERATIONS):
            arm = rotate(points, pose[2])
            values, offsets = self.exact_values(pose[:2] + arm, classes, sigma_m)
            score = float(values.mean())
            if score > best_score:
                best, best_score = pose.copy(), score
            gx, gy = -values * offsets[:, 0] / sigma2, -values * offsets[:, 1] / sigma2
            gradient = np.stack([gx, gy, gy * arm[:, 0] - gx * arm[:, 1]], axis=-1).sum(axis=0)
            norm = np.maximum(np.hypot(offsets[:, 0], offsets[:, 1]), 1e-12)
            ux, uy = -offsets[:, 0] / norm, -offsets[:, 1] / norm
            direction = np.stack([ux, uy, uy * arm[:, 0] - ux * arm[:, 1]], axis=-1)
            hessian = (direction * values[:, None]).T @ direction
            hessian += np.diag(GAUSS_NEWTON_DAMPING * np.diag(hessian) + 1e-12)
            step = np.linalg.solve(hessian, sigma2 * gradient)
            pose = np.clip(pose + step, start - limit, start + limit)
            if abs(step[0]) < 1e-4 and abs(step[1]) < 1e-4 and abs(step[2]) < 1e-4:
                break
        if self._exact_mean(points, classes, pose, sigma_m) > best_score:
            best = pose
        best[2] = float(wrap_angles(best[2]))
        return best

    def polish(self, points: np.ndarray, normals: np.ndarray, pose: np.ndarray) -> np.ndarray:
        """Point-to-plane least squares from ``pose``: each scan point pairs with the nearest map
        point facing its way (:data:`POLISH_PAIR_M`, :data:`POLISH_NORMAL_COS`), its residual is
        the distance along that map point's normal, weighed by Cauchy's kernel; damped Gauss-
        Newton steps only along what the walls pin (so a corridor's length stays put).

        The likelihood field's optimum is blurred by its smear and cells; this one is not (a
        maze drive's keyframe-to-keyframe heading error: 3.3–4.9 → 1.5–2.6 mrad). The search
        has found the optimum to within its fine step (``fine_resolution_m``,
        ``fine_angle_step_rad``), so the polish moves no further than that from ``pose``: where
        it wants to, it follows pairs the search did not see (on the real CARMEN logs, with
        180 beams to a scan, an unbounded polish turned one match in a hundred by over 1°)."""
        s = self.settings
        map_points, map_normals = self._map
        assert map_normals is not None
        limit = np.array([s.fine_resolution_m, s.fine_resolution_m, s.fine_angle_step_rad])
        start = np.asarray(pose, dtype=float)
        pose = start.copy()
        for _ in range(s.polish_iterations):
            arm = rotate(points, pose[2])
            distances, nearest = self.tree.query(pose[:2] + arm, distance_upper_bound=POLISH_PAIR_M)
            paired = np.isfinite(distances)
            paired[paired] &= (rotate(normals[paired], pose[2]) * map_normals[nearest[paired]]).sum(axis=1) \
                > POLISH_NORMAL_COS
            if paired.sum() < 3:
                break
            normal = map_normals[nearest[paired]]
            residual = ((pose[:2] + arm[paired] - map_points[nearest[paired]]) * normal).sum(axis=1)
            jacobian = np.column_stack([normal, normal[:, 1] * arm[paired, 0] - normal[:, 0] * arm[paired, 1]])
            weight = 1.0 / (1.0 + (residual / POLISH_KERNEL_M) ** 2)
            hessian = (jacobian * weight[:, None]).T @ jacobian
            step = _well_posed_step(hessian, jacobian.T @ (weight * residual))
            pose = np.clip(pose + step, start - limit, start + limit)
            if np.abs(step).max() < 1e-6:
                break
        pose[2] = float(wrap_angles(pose[2]))
        return pose

    def _penalty_at(self, pose: np.ndarray, prior: np.ndarray) -> float:
        offset = pose - prior
        return float(_penalty(offset[0], offset[1], wrap_angles(offset[2]), self.settings))

    def _gauss_newton(self, points: np.ndarray, classes: np.ndarray | None, start: np.ndarray,
                      field: LikelihoodField) -> np.ndarray:
        """From the coarse best (near the optimum: the coarse search scores a subset of the
        points, so not always within half a coarse step of it), the pose of the
        highest mean likelihood: Gauss-Newton steps, each the point-to-surface least squares
        that the field's Gaussian shape implies. Near a point's nearest map surface the
        likelihood is ``f = exp(-d²/2σ²)``, so its gradient ∇f points to the surface and
        ``σ²|∇f|/f`` is the distance ``d``; weighting each point by ``f`` (iteratively
        reweighted least squares with Welsch's kernel) makes the step
        ``(Σ f aᵀa)⁻¹ σ² Σ ∇f·∂x/∂pose`` with ``a`` the surface direction moved by the pose,
        whose fixed point is the maximum of the mean likelihood. Gradients are central
        differences of the spline. Steps are damped (Levenberg-Marquardt), so a direction the
        scan does not constrain (along a corridor) stays put, and kept within a whole coarse
        step of ``start`` (half a step clipped some maxima: the maze's drift over 20 keyframes
        was 20 % worse with it)."""
        s = self.settings
        sigma2 = field.smear_m ** 2
        h = 0.25 * field.resolution_m
        deltas = np.array([[0.0, 0.0], [h, 0.0], [-h, 0.0], [0.0, h], [0.0, -h]])[:, None, :]
        point_classes = None if classes is None else classes[None, :]
        limit = np.array([s.coarse_resolution_m, s.coarse_resolution_m, s.coarse_angle_step_rad])
        pose = np.asarray(start, dtype=float).copy()
        best, best_score = pose.copy(), -1.0
        for _ in range(GAUSS_NEWTON_ITERATIONS):
            c, sn = math.cos(pose[2]), math.sin(pose[2])
            arm = np.stack([c * points[:, 0] - sn * points[:, 1], sn * points[:, 0] + c * points[:, 1]], axis=-1)
            values = field.interpolate(pose[:2] + arm + deltas, point_classes)
            score = float(values[0].mean())
            if score > best_score:
                best, best_score = pose.copy(), score
            gx, gy = (values[1] - values[2]) / (2 * h), (values[3] - values[4]) / (2 * h)
            gradient = np.stack([gx, gy, gy * arm[:, 0] - gx * arm[:, 1]], axis=-1).sum(axis=0)
            norm = np.maximum(np.hypot(gx, gy), 1e-12)
            ux, uy = gx / norm, gy / norm
            direction = np.stack([ux, uy, uy * arm[:, 0] - ux * arm[:, 1]], axis=-1)
            hessian = (direction * values[0][:, None]).T @ direction
            hessian += np.diag(GAUSS_NEWTON_DAMPING * np.diag(hessian) + 1e-12)
            step = np.linalg.solve(hessian, sigma2 * gradient)
            pose = np.clip(pose + step, start - limit, start + limit)
            if abs(step[0]) < 1e-4 and abs(step[1]) < 1e-4 and abs(step[2]) < 1e-4:
                break
        values = field.interpolate(pose[:2] + rotate(points, pose[2]), classes)
        if float(values.mean()) > best_score:
            best = pose
        best[2] = float(wrap_angles(best[2]))
        return best

    def _coarse(self, points: np.ndarray, normals: np.ndarray | None,
                prior: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The best coarse pose, and the coarse candidates scored (C, 3) with their penalised responses.

        A small window is searched exhaustively. A large one (loop closure) is searched
        branch and bound, as Cartographer does: blocks of BLOCK × BLOCK shifts are bounded
        from above by a field holding each block's maximum, and only blocks whose bound
        beats the best exact score so far are scored cell by cell. The result is the same
        as the exhaustive search's.
        """
        s = self.settings
        steps = int(math.floor(s.search_angle_rad / s.coarse_angle_step_rad + 1e-9))
        dyaws = np.arange(-steps, steps + 1) * s.coarse_angle_step_rad
        half = int(math.floor(s.search_size_m / 2 / s.coarse_resolution_m + 1e-9))
        per_yaw = []
        for dyaw in dyaws:
            rotated = se2_apply(np.array([prior[0], prior[1], prior[2] + dyaw]), points)
            rows, cols = self.coarse.cells(rotated)
            classes = None if normals is None else normal_classes(rotate(normals, prior[2] + dyaw))
            per_yaw.append((float(dyaw), rows, cols, classes))
        if 2 * half + 1 <= 3 * BLOCK:
            scored = [self._score_shifts(prior, entry, np.arange(-half, half + 1), np.arange(-half, half + 1))
                      for entry in per_yaw]
        else:
            scored = self._branch_and_bound(prior, per_yaw, half)
        candidates = np.concatenate([c for c, _ in scored])
        scores = np.concatenate([r for _, r in scored])
        return candidates[int(np.argmax(scores))], candidates, scores

    def _score_shifts(self, prior: np.ndarray, entry: tuple[float, np.ndarray, np.ndarray, np.ndarray | None],
                      row_shifts: np.ndarray, col_shifts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Candidates (C, 3) and penalised responses (C,) of one yaw over a grid of cell shifts."""
        s = self.settings
        dyaw, rows, cols, classes = entry
        # (K, R, C): every point under every shift
        scores = self.coarse.lookup(rows[:, None, None] + row_shifts[None, :, None],
                                    cols[:, None, None] + col_shifts[None, None, :],
                                    None if classes is None else classes[:, None, None])
        dy, dx = np.meshgrid(row_shifts * s.coarse_resolution_m, col_shifts * s.coarse_resolution_m, indexing="ij")
        penalised = scores.mean(axis=0) * _penalty(dx, dy, np.full(dx.shape, dyaw), s)
        candidates = np.stack([prior[0] + dx.ravel(), prior[1] + dy.ravel(), np.full(dx.size, prior[2] + dyaw)],
                              axis=-1)
        return candidates, penalised.ravel()

    def _branch_and_bound(self, prior: np.ndarray, per_yaw: list[tuple[float, np.ndarray, np.ndarray,
                                                                         np.ndarray | None]],
                          half: int) -> list[tuple[np.ndarray, np.ndarray]]:
        s = self.settings
        starts = np.arange(-half, half + 1, BLOCK)
        bounds, keys = [], []
        for y, (dyaw, rows, cols, classes) in enumerate(per_yaw):
            # the block maximum of the cells [r, r + BLOCK) is stored at r
            upper = self.coarse.lookup(rows[:, None, None] + starts[None, :, None],
                                       cols[:, None, None] + starts[None, None, :],
                                       None if classes is None else classes[:, None, None], block_max=True).mean(axis=0)
            nearest = np.clip(0, starts, np.minimum(starts + BLOCK - 1, half)) * s.coarse_resolution_m
            ny, nx = np.meshgrid(nearest, nearest, indexing="ij")
            upper = upper * _penalty(nx, ny, np.full(nx.shape, dyaw), s)
            bounds.append(upper.ravel())
            keys += [(y, i, j) for i in range(len(starts)) for j in range(len(starts))]
        bound = np.concatenate(bounds)
        order = np.argsort(-bound)
        best = -1.0
        scored = []
        for rank in order[:MAX_BLOCKS]:
            if bound[rank] <= best:
                break
            y, i, j = keys[rank]
            row_shifts = np.arange(starts[i], min(starts[i] + BLOCK, half + 1))
            col_shifts = np.arange(starts[j], min(starts[j] + BLOCK, half + 1))
            candidates, responses = self._score_shifts(prior, per_yaw[y], row_shifts, col_shifts)
            best = max(best, float(responses.max()))
            scored.append((candidates, responses))
        return scored

    def _covariance(self, candidates: np.ndarray, responses: np.ndarray) -> np.ndarray:
        """Spread of the coarse candidates within 90 % of the best response (as Karto estimates it
        from its search), with a floor of one fine step."""
        s = self.settings
        if not responses.max() > 0:  # nothing matched anywhere: the whole window is possible
            return np.diag([(s.search_size_m / 2) ** 2, (s.search_size_m / 2) ** 2, max(s.search_angle_rad, 0.1) ** 2])
        good = responses >= 0.9 * responses.max()
        weights = responses[good] / responses[good].sum()
        mean = (candidates[good] * weights[:, None]).sum(axis=0)
        centred = candidates[good] - mean
        covariance = (centred * weights[:, None]).T @ centred
        floor = np.diag([s.fine_resolution_m ** 2, s.fine_resolution_m ** 2, s.fine_angle_step_rad ** 2])
        return np.asarray(covariance + floor)
