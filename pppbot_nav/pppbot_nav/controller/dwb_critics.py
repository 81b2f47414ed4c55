"""Nav2 DWB's trajectory critics (``dwb_critics``), each scoring every trajectory at once, without ROS.

A critic gets all of a period's trajectories as one :class:`Trajectories` record and returns, per
trajectory, a raw score (≥ 0) and whether it is illegal (Nav2's ``IllegalTrajectoryException``) with
Nav2's reason. The planner weighs raw scores by :meth:`TrajectoryCritic.effective_scale`
(``<Critic>.scale``; half a cell times that for map grids, as Nav2's ``getScale``).

* ``RotateToGoal``: once within ``xy_goal_tolerance`` of the goal, trajectories must slow down; once
  stopped (``trans_stopped_velocity``) only turns in place are legal, scored by the yaw left to the
  goal at the end (or at ``lookahead_time``).
* ``Oscillation``: once vx (or, at most ``x_only_threshold`` fast, vy or ω) changed sign, the old sign
  is illegal until the robot has moved ``oscillation_reset_dist``, turned ``oscillation_reset_angle``
  or ``oscillation_reset_time`` has passed.
* ``BaseObstacle``: the cost under each pose (lethal, inscribed, unknown or off the grid: illegal);
  the last pose's, or the sum with ``sum_scores``. ``ObstacleFootprint``: the same along the outline
  of Nav2's 16-gon footprint of ``robot_radius`` padded by ``footprint_padding`` (Bresenham lines, as
  Nav2); only lethal and unknown are illegal.
* ``PathDist`` / ``GoalDist``: Manhattan cell distances to the plan's first run of cells on the costmap
  (not unknown) / to the last of them, at the trajectory's poses (``aggregation_type`` last, sum,
  product). ``PathAlign`` / ``GoalAlign``: the same at ``forward_point_distance`` ahead of the poses
  (the goal cell moved as far on, away from the robot); PathAlign is off that near the goal.
* ``PreferForward``: ``penalty`` for backing or strafing, else ``theta_scale·|ω|``. ``Twirling``: ``|ω|``.

Nav2's map-grid queue (``MapGridQueue::validCellToQueue``) takes every cell, obstacles and unknown
ones too, so its wavefront is the exact L1 distance transform used here: its obstacle score is never
given out, and cells are unreachable only when no plan cell is on the costmap.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, ClassVar

import numpy as np
from scipy import ndimage

from pppbot_nav.costmap.costs import INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE, NO_INFORMATION
from pppbot_nav.costmap.grid import Costmap

if TYPE_CHECKING:
    from pppbot_nav.controller.dwb import DWBSettings

#: Vertices of Nav2's circular footprint (``makeFootprintFromRadius``).
_FOOTPRINT_VERTICES = 16
#: Poses whose footprint outline is rasterised at once.
_FOOTPRINT_CHUNK = 4096


@dataclass(frozen=True)
class Trajectories:
    """T simulated trajectories in the costmap's frame; poses past ``counts[t]`` repeat the last one."""

    velocity: np.ndarray  # (T, 3) vx, vy, ω each trajectory commands (m/s, m/s, rad/s)
    poses: np.ndarray  # (T, P, 3) x, y, yaw (m, m, rad; yaw not wrapped)
    counts: np.ndarray  # (T,) poses of each trajectory: start, one per step, the last again if include_last_point
    steps: np.ndarray  # (T,) simulation steps of each trajectory (pose i is at i·step_s)
    step_s: np.ndarray  # (T,) duration of a step (s)
    _cells: dict[int, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict, compare=False, repr=False)

    def __len__(self) -> int:
        return int(self.velocity.shape[0])

    def mask(self) -> np.ndarray:
        """(T, P) True where a pose belongs to its trajectory."""
        return np.arange(self.poses.shape[1])[None, :] < self.counts[:, None]

    def last(self) -> np.ndarray:
        """(T, 3) each trajectory's last pose."""
        return self.poses[np.arange(len(self)), self.counts - 1]

    def cells(self, costmap: Costmap) -> tuple[np.ndarray, np.ndarray]:
        """(T, P) :func:`cells_of` the poses, computed once for the critics that share them."""
        if id(costmap) not in self._cells:
            self._cells[id(costmap)] = cells_of(costmap, self.poses[..., 0], self.poses[..., 1])
        return self._cells[id(costmap)]


@dataclass(frozen=True)
class Context:
    """What every critic's ``prepare`` sees, all in the costmap's frame."""

    pose: np.ndarray  # (3,) the robot's x, y, yaw
    velocity: np.ndarray  # (3,) its vx, vy, ω
    goal: np.ndarray  # (3,) the path's last pose
    plan: np.ndarray  # (M, 2) the transformed (pruned, shortened) plan
    costmap: Costmap
    now_s: float  # the planner's clock: the sum of the control periods so far
    #: the DWB controller's own parameters (a critic reads some, as Nav2's read them under the
    #: controller's name: RotateToGoal's xy_goal_tolerance, the footprint)
    settings: DWBSettings
    grids: dict[bytes, np.ndarray] = field(default_factory=dict)  # map grids by source cells, shared


Verdict = tuple[np.ndarray, np.ndarray]  # raw scores (T,) float; 0 (legal) or 1 + reason index (T,) int


def cells_of(costmap: Costmap, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Flat cell indices (row·width + col, 0 off the grid) of points and whether each is on the grid."""
    col = np.floor((x - costmap.origin[0]) / costmap.resolution)
    row = np.floor((y - costmap.origin[1]) / costmap.resolution)
    on = (col >= 0) & (col < costmap.width) & (row >= 0) & (row < costmap.height)
    flat = np.where(on, row * costmap.width + col, 0).astype(np.intp)
    return flat, on


def first_failure(codes: np.ndarray) -> np.ndarray:
    """(T,) the first non-zero code along each row of (T, P) ``codes``, 0 if none."""
    first = np.argmax(codes != 0, axis=1)
    return codes[np.arange(codes.shape[0]), first]


class TrajectoryCritic:
    """Nav2's ``dwb_core::TrajectoryCritic``: ``reset`` on a new path, ``prepare`` once a period, ``score``
    all trajectories, ``debrief`` with the chosen command."""

    reasons: ClassVar[tuple[str, ...]] = ()

    def __init__(self, name: str, scale: float) -> None:
        self.name = name
        self.scale = scale

    def reset(self) -> None:
        """A new path (Nav2's ``setPlan``)."""

    def prepare(self, ctx: Context) -> bool:
        """Per-period set-up; False when it failed (Nav2 warns and scores anyway)."""
        return True

    def effective_scale(self) -> float:
        return self.scale

    def score(self, traj: Trajectories) -> Verdict:
        raise NotImplementedError

    def debrief(self, velocity: np.ndarray) -> None:
        """The command chosen this period (zeros when none was)."""


class RotateToGoal(TrajectoryCritic):
    reasons = ("Not slowing down near goal.", "Nonrotation command near goal.")

    def __init__(self, name: str, scale: float, slowing_factor: float, lookahead_time: float) -> None:
        super().__init__(name, scale)
        self.slowing_factor = slowing_factor
        self.lookahead_time = lookahead_time
        self.reset()

    def reset(self) -> None:
        self.in_window = False
        self.rotating = False
        self._speed_sq = 0.0
        self._goal_yaw = 0.0

    def prepare(self, ctx: Context) -> bool:
        dxy_sq = float(np.sum((ctx.pose[:2] - ctx.goal[:2]) ** 2))
        self.in_window = self.in_window or dxy_sq <= ctx.settings.xy_goal_tolerance ** 2
        self._speed_sq = float(ctx.velocity[0] ** 2 + ctx.velocity[1] ** 2)
        stopped = self._speed_sq <= ctx.settings.trans_stopped_velocity ** 2
        self.rotating = self.rotating or (self.in_window and stopped)
        self._goal_yaw = float(ctx.goal[2])
        return True

    def score(self, traj: Trajectories) -> Verdict:
        n = len(traj)
        if not self.in_window:
            return np.zeros(n), np.zeros(n, dtype=int)
        vx, vy = traj.velocity[:, 0], traj.velocity[:, 1]
        rotation = np.abs(np.angle(np.exp(1j * (self._goal_yaw - self._end_yaw(traj)))))
        if not self.rotating:
            speed_sq = vx * vx + vy * vy
            return speed_sq * self.slowing_factor + rotation, np.where(speed_sq >= self._speed_sq, 1, 0)
        return rotation, np.where((np.abs(vx) > 0) | (np.abs(vy) > 0), 2, 0)

    def _end_yaw(self, traj: Trajectories) -> np.ndarray:
        if self.lookahead_time < 0.0:
            return traj.last()[:, 2]
        # Pose i is at i·step_s; past the last step, the last pose (Nav2's projectPose).
        at = np.minimum(self.lookahead_time / traj.step_s, traj.steps.astype(float))
        i = np.minimum(np.floor(at).astype(int), traj.steps)
        j = np.minimum(i + 1, traj.counts - 1)
        rows = np.arange(len(traj))
        ratio = at - i
        return traj.poses[rows, i, 2] * (1.0 - ratio) + traj.poses[rows, j, 2] * ratio


class _Trend:
    """The sign history of one velocity component (Nav2's ``OscillationCritic::CommandTrend``)."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.sign = 0
        self.positive_only = False
        self.negative_only = False

    def update(self, velocity: float) -> bool:
        flipped = False
        if velocity < 0.0:
            flipped = self.sign > 0
            self.negative_only = self.negative_only or flipped
            self.sign = -1
        elif velocity > 0.0:
            flipped = self.sign < 0
            self.positive_only = self.positive_only or flipped
            self.sign = 1
        return flipped

    def oscillating(self, velocity: np.ndarray) -> np.ndarray:
        return (self.positive_only & (velocity < 0.0)) | (self.negative_only & (velocity > 0.0))

    def flipped(self) -> bool:
        return self.positive_only or self.negative_only


class Oscillation(TrajectoryCritic):
    reasons = ("Trajectory is oscillating.",)

    def __init__(self, name: str, scale: float, reset_dist: float, reset_angle: float, reset_time_s: float,
                 x_only_threshold: float) -> None:
        super().__init__(name, scale)
        self.reset_dist = reset_dist
        self.reset_angle = reset_angle
        self.reset_time_s = reset_time_s
        self.x_only_threshold = x_only_threshold
        self.trends = (_Trend(), _Trend(), _Trend())  # x, y, θ
        self._pose = np.zeros(3)
        self._now_s = 0.0
        self._flip_pose = np.zeros(3)
        self._flip_s = 0.0

    def reset(self) -> None:
        for trend in self.trends:
            trend.reset()

    def prepare(self, ctx: Context) -> bool:
        self._pose = ctx.pose.copy()
        self._now_s = ctx.now_s
        return True

    def score(self, traj: Trajectories) -> Verdict:
        bad = np.zeros(len(traj), dtype=bool)
        for k, trend in enumerate(self.trends):
            bad |= trend.oscillating(traj.velocity[:, k])
        return np.zeros(len(traj)), bad.astype(int)

    def debrief(self, velocity: np.ndarray) -> None:
        x, y, theta = self.trends
        flag = x.update(float(velocity[0]))
        if self.x_only_threshold < 0.0 or abs(float(velocity[0])) <= self.x_only_threshold:
            flag = y.update(float(velocity[1])) or flag
            flag = theta.update(float(velocity[2])) or flag
        if flag:
            self._flip_pose = self._pose.copy()
            self._flip_s = self._now_s
        if any(trend.flipped() for trend in self.trends) and self._reset_available():
            self.reset()

    def _reset_available(self) -> bool:
        moved_sq = float(np.sum((self._pose[:2] - self._flip_pose[:2]) ** 2))
        if self.reset_dist >= 0.0 and moved_sq > self.reset_dist ** 2:
            return True
        # Nav2 compares the yaws without wrapping them.
        if self.reset_angle >= 0.0 and abs(self._pose[2] - self._flip_pose[2]) > self.reset_angle:
            return True
        return self.reset_time_s >= 0.0 and self._now_s - self._flip_s > self.reset_time_s


class BaseObstacle(TrajectoryCritic):
    reasons: ClassVar[tuple[str, ...]] = ("Trajectory Goes Off Grid.", "Trajectory Hits Obstacle.")

    def __init__(self, name: str, scale: float, sum_scores: bool) -> None:
        super().__init__(name, scale)
        self.sum_scores = sum_scores
        self._costmap: Costmap | None = None

    def prepare(self, ctx: Context) -> bool:
        self._costmap = ctx.costmap
        return True

    def _pose_costs(self, traj: Trajectories, costmap: Costmap) -> tuple[np.ndarray, np.ndarray]:
        """(T, P) cost of each pose and its failure code (0 legal)."""
        flat, on = traj.cells(costmap)
        cost = costmap.costs.ravel()[flat].astype(float)
        # Lethal, inscribed and unknown are the three values from 253 up.
        return cost, np.where(~on, 1, np.where(cost >= INSCRIBED_INFLATED_OBSTACLE, 2, 0))

    def score(self, traj: Trajectories) -> Verdict:
        assert self._costmap is not None, "score before prepare"
        cost, codes = self._pose_costs(traj, self._costmap)
        valid = traj.mask()
        illegal = first_failure(codes * valid)
        if self.sum_scores:
            return np.where(valid, cost, 0.0).sum(axis=1), illegal
        return cost[np.arange(len(traj)), traj.counts - 1], illegal


class ObstacleFootprint(BaseObstacle):
    reasons = ("Trajectory Goes Off Grid.", "Footprint Goes Off Grid.", "Trajectory Hits Obstacle.",
               "Trajectory Hits Unknown Region.")

    def __init__(self, name: str, scale: float, sum_scores: bool) -> None:
        super().__init__(name, scale, sum_scores)
        self._made_for: tuple[float, float] | None = None
        self.footprint = np.zeros((_FOOTPRINT_VERTICES, 2))

    def prepare(self, ctx: Context) -> bool:
        """The footprint is the controller's (the local costmap's robot_radius and footprint_padding)."""
        radius, padding = ctx.settings.robot_radius, ctx.settings.footprint_padding
        if self._made_for != (radius, padding):
            angles = np.arange(_FOOTPRINT_VERTICES) * 2.0 * math.pi / _FOOTPRINT_VERTICES
            vertices = np.c_[np.cos(angles), np.sin(angles)] * radius
            # (16, 2) in the robot's frame, padded as Nav2's padFootprint: by the sign of each coordinate,
            # so cos(π/2)·r, 6e-17, counts as positive there too.
            self.footprint = vertices + np.sign(vertices) * padding
            self._made_for = (radius, padding)
        return super().prepare(ctx)

    def _pose_costs(self, traj: Trajectories, costmap: Costmap) -> tuple[np.ndarray, np.ndarray]:
        _, centre_on = traj.cells(costmap)
        cost, codes = np.zeros(centre_on.shape), np.where(centre_on, 0, 1)
        laid = traj.mask() & centre_on  # the poses whose footprint is laid down
        poses = traj.poses[laid]
        pose_cost, pose_code = np.empty(len(poses)), np.empty(len(poses), dtype=int)
        for start in range(0, len(poses), _FOOTPRINT_CHUNK):  # bounds memory: 16 edges of a few cells each
            part = slice(start, start + _FOOTPRINT_CHUNK)
            pose_cost[part], pose_code[part] = self._outline_costs(poses[part], costmap)
        cost[laid], codes[laid] = pose_cost, pose_code
        return cost, codes

    def _outline_costs(self, poses: np.ndarray, costmap: Costmap) -> tuple[np.ndarray, np.ndarray]:
        """(N,) the highest cost under the footprint outline at ``poses`` (N, 3), and its failure code."""
        c, s = np.cos(poses[:, 2, None]), np.sin(poses[:, 2, None])
        fx, fy = self.footprint[:, 0], self.footprint[:, 1]
        col = np.floor((poses[:, 0, None] + fx * c - fy * s - costmap.origin[0]) / costmap.resolution).astype(np.int32)
        row = np.floor((poses[:, 1, None] + fx * s + fy * c - costmap.origin[1]) / costmap.resolution).astype(np.int32)
        corner_on = ((col >= 0) & (col < costmap.width) & (row >= 0) & (row < costmap.height)).all(axis=1)
        col, row = np.clip(col, 0, costmap.width - 1), np.clip(row, 0, costmap.height - 1)
        # Each edge is a short line: look its cells up by (dx, dy) instead of walking it.
        dx, dy = np.roll(col, -1, axis=1) - col, np.roll(row, -1, axis=1) - row
        reach = int(max(np.abs(dx).max(initial=0), np.abs(dy).max(initial=0)))
        tx, ty = _outline_cells(*np.meshgrid(np.zeros(1, np.int32), np.zeros(1, np.int32),
                                             np.arange(-reach, reach + 1), np.arange(-reach, reach + 1),
                                             indexing="ij"))
        offsets = (ty * costmap.width + tx).reshape(2 * reach + 1, 2 * reach + 1, -1)  # by dx, dy: flat cells
        cells = (row * costmap.width + col)[..., None] + offsets[dx + reach, dy + reach]
        cost = costmap.costs.ravel()[cells.reshape(len(poses), -1)]  # (N, edges·cells)
        lethal, unknown = (cost == LETHAL_OBSTACLE).any(axis=1), (cost == NO_INFORMATION).any(axis=1)
        return cost.max(axis=1).astype(float), np.select([~corner_on, lethal, unknown], [2, 3, 4], 0)


def _outline_cells(x0: np.ndarray, y0: np.ndarray, x1: np.ndarray, y1: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Cells (x, y) of the lines from (x0, y0) to (x1, y1) (integer arrays, any shape S), as Nav2's
    Bresenham ``LineIterator`` walks them: shape S + (K,) flattened into the last axis of S, each line
    padded with its end cell."""
    dx, dy = np.abs(x1 - x0), np.abs(y1 - y0)
    sx, sy = np.where(x1 >= x0, 1, -1), np.where(y1 >= y0, 1, -1)
    den = np.maximum(dx, dy)
    k = np.minimum(np.arange(int(den.max()) + 1), den[..., None])  # (..., K)
    den_safe = np.maximum(den, 1)[..., None]
    minor_x = (dy[..., None] // 2 + k * dx[..., None]) // den_safe  # x steps when y is the major axis
    minor_y = (dx[..., None] // 2 + k * dy[..., None]) // den_safe
    x_major = (dx >= dy)[..., None]
    xs = x0[..., None] + sx[..., None] * np.where(x_major, k, minor_x)
    ys = y0[..., None] + sy[..., None] * np.where(x_major, minor_y, k)
    shape = (*xs.shape[:-2], -1)
    return xs.reshape(shape), ys.reshape(shape)


def adjust_plan_resolution(plan: np.ndarray, resolution: float) -> np.ndarray:
    """Nav2's ``nav_2d_utils::adjustPlanResolution``: points inserted into gaps wider than two cells.
    Its step count leaves gaps up to about 2.5 cells, as Nav2 does."""
    if len(plan) < 2:
        return plan
    min_dist = 2.0 * resolution
    out = [plan[:1]]
    for last, point in zip(plan[:-1], plan[1:], strict=True):
        dist = math.hypot(*(point - last))
        if dist > min_dist:
            steps = int((dist - min_dist) / resolution) - 1
            if steps > 1:
                out.append(last + np.arange(1, steps)[:, None] * (point - last) / steps)
        out.append(point[None])
    return np.concatenate(out)


def _plan_run(costmap: Costmap, plan: np.ndarray) -> np.ndarray:
    """Flat cells of the plan's first run of points on the costmap and not unknown."""
    flat, on = cells_of(costmap, plan[:, 0], plan[:, 1])
    usable = on & (costmap.costs.ravel()[flat] != NO_INFORMATION)
    if not usable.any():
        return np.empty(0, dtype=np.intp)
    start = int(np.argmax(usable))
    stop = start + int(np.argmax(~usable[start:])) if not usable[start:].all() else len(usable)
    return flat[start:stop]


class MapGrid(TrajectoryCritic):
    """Nav2's ``MapGridCritic``: a score per cell, looked up at the trajectory's poses."""

    reasons = ("Trajectory Goes Off Grid.", "Trajectory Hits Unreachable Area.")
    stop_on_failure = True

    def __init__(self, name: str, scale: float, aggregation_type: str) -> None:
        super().__init__(name, scale)
        self.aggregation = aggregation_type.lower()
        self.grid = np.empty(0)
        self._costmap: Costmap | None = None
        self.unreachable_score = 0.0
        self.reachable = False

    def effective_scale(self) -> float:
        resolution = self._costmap.resolution if self._costmap is not None else 0.0
        return resolution * 0.5 * self.scale

    def _set_sources(self, ctx: Context, sources: np.ndarray) -> bool:
        """Grid of L1 cell distances to ``sources`` (flat cells); all unreachable when there are none."""
        costmap = self._costmap = ctx.costmap
        size = costmap.width * costmap.height
        self.unreachable_score = float(size + 1)  # Nav2's obstacle score, size, is never given out
        self.reachable = sources.size > 0
        if not self.reachable:
            self.grid = np.full(size, self.unreachable_score)
            return False
        key = np.unique(sources).tobytes()
        if key not in ctx.grids:
            free = np.ones(size, dtype=bool)
            free[sources] = False
            ctx.grids[key] = ndimage.distance_transform_cdt(free.reshape(costmap.costs.shape),
                                                            metric="taxicab").ravel().astype(float)
        self.grid = ctx.grids[key]
        return True

    def _points(self, poses: np.ndarray) -> np.ndarray:
        """(..., 2) where poses (..., 3) are scored."""
        return poses[..., :2]

    def score(self, traj: Trajectories) -> Verdict:
        costmap = self._costmap
        assert costmap is not None, "score before prepare"
        if self.aggregation == "last" and not self.stop_on_failure:  # Nav2 reads the last pose only
            last = self._points(traj.last())
            flat, on = cells_of(costmap, last[:, 0], last[:, 1])
            return np.where(on, self.grid[flat], 0.0), np.where(on, 0, 1)
        if type(self)._points is MapGrid._points:
            flat, on = traj.cells(costmap)
        else:
            points = self._points(traj.poses)
            flat, on = cells_of(costmap, points[..., 0], points[..., 1])
        valid = traj.mask()
        codes = np.where(on, 0, 1)
        if self.stop_on_failure and not self.reachable:  # a grid of distances, or all unreachable
            codes = np.where(on, 2, 1)
        illegal = first_failure(codes * valid)
        if self.aggregation == "last":
            last_flat = flat[np.arange(len(traj)), traj.counts - 1]
            return self.grid[last_flat], illegal
        values = np.where(valid & on, self.grid[flat], 0.0)
        if self.aggregation == "sum":
            return values.sum(axis=1), illegal
        with np.errstate(over="ignore"):
            return np.prod(np.where(valid, values, 1.0), axis=1), illegal


class PathDist(MapGrid):
    def prepare(self, ctx: Context) -> bool:
        plan = adjust_plan_resolution(ctx.plan, ctx.costmap.resolution)
        return self._set_sources(ctx, _plan_run(ctx.costmap, plan))


class GoalDist(MapGrid):
    def prepare(self, ctx: Context) -> bool:
        return self._set_sources(ctx, self._goal_cell(ctx, ctx.plan))

    @staticmethod
    def _goal_cell(ctx: Context, plan: np.ndarray) -> np.ndarray:
        run = _plan_run(ctx.costmap, adjust_plan_resolution(plan, ctx.costmap.resolution))
        return run[-1:]


def _forward(poses: np.ndarray, distance_m: float) -> np.ndarray:
    """(..., 2) points ``distance_m`` ahead of poses (..., 3) (Nav2's ``getForwardPose``)."""
    yaw = poses[..., 2]
    return poses[..., :2] + distance_m * np.stack([np.cos(yaw), np.sin(yaw)], axis=-1)


class PathAlign(PathDist):
    stop_on_failure = False

    def __init__(self, name: str, scale: float, aggregation_type: str, forward_point_distance: float) -> None:
        super().__init__(name, scale, aggregation_type)
        self.forward_point_distance = forward_point_distance
        self.zero_scale = False

    def prepare(self, ctx: Context) -> bool:
        # Near the goal, keeping the nose on the path destabilises the robot: the critic is off.
        self._costmap = ctx.costmap
        self.zero_scale = float(np.sum((ctx.pose[:2] - ctx.goal[:2]) ** 2)) <= self.forward_point_distance ** 2
        return True if self.zero_scale else super().prepare(ctx)

    def effective_scale(self) -> float:
        return 0.0 if self.zero_scale else super().effective_scale()

    def _points(self, poses: np.ndarray) -> np.ndarray:
        return _forward(poses, self.forward_point_distance)


class GoalAlign(GoalDist):
    stop_on_failure = False

    def __init__(self, name: str, scale: float, aggregation_type: str, forward_point_distance: float) -> None:
        super().__init__(name, scale, aggregation_type)
        self.forward_point_distance = forward_point_distance

    def prepare(self, ctx: Context) -> bool:
        # The nose is drawn to where it will be on arriving (before turning to the goal's yaw).
        heading = math.atan2(ctx.goal[1] - ctx.pose[1], ctx.goal[0] - ctx.pose[0])
        plan = ctx.plan.copy()
        plan[-1] += self.forward_point_distance * np.array([math.cos(heading), math.sin(heading)])
        return self._set_sources(ctx, self._goal_cell(ctx, plan))

    def _points(self, poses: np.ndarray) -> np.ndarray:
        return _forward(poses, self.forward_point_distance)


class PreferForward(TrajectoryCritic):
    def __init__(self, name: str, scale: float, penalty: float, strafe_x: float, strafe_theta: float,
                 theta_scale: float) -> None:
        super().__init__(name, scale)
        self.penalty, self.strafe_x, self.strafe_theta, self.theta_scale = penalty, strafe_x, strafe_theta, theta_scale

    def score(self, traj: Trajectories) -> Verdict:
        vx, w = traj.velocity[:, 0], np.abs(traj.velocity[:, 2])
        backing_or_strafing = (vx < 0.0) | ((vx < self.strafe_x) & (w < self.strafe_theta))
        return np.where(backing_or_strafing, self.penalty, w * self.theta_scale), np.zeros(len(traj), dtype=int)


class Twirling(TrajectoryCritic):
    def score(self, traj: Trajectories) -> Verdict:
        return np.abs(traj.velocity[:, 2]), np.zeros(len(traj), dtype=int)
