"""Nav2's DWB controller (``dwb_core::DWBLocalPlanner``) without ROS, vectorised over trajectories.

Each control period, :meth:`DWBLocalPlanner.compute` does what Nav2 Jazzy's
``computeVelocityCommands`` does:

1. **Transform the plan** (``transformGlobalPlan``): the plan is searched up to the first point
   more than ``forward_prune_distance`` along it for the first point nearer the robot than
   ``min(prune_distance, half the costmap)``; from there up to the first point farther than
   ``min(forward_prune_distance, half the costmap)`` (half the costmap alone without
   ``shorten_transformed_plan``) it is the transformed plan, in the costmap's frame. With
   ``prune_plan`` the points before it are dropped for good. The goal is the plan's last pose.
2. **Sample twists** (``XYThetaIterator``): per axis, ``v{x,y,theta}_samples`` evenly spaced
   velocities (0 added between a negative and a positive one) over the window reachable from
   the current velocity (clamped to ``[min, max]``) with ``acc_lim``/``decel_lim`` within
   ``sim_time`` (``StandardTrajectoryGenerator``) or one control period ``dt_s``
   (``LimitedAccelGenerator``: Nav2's 1/``controller_frequency``); vθ spans ±``max_vel_theta``.
   Twists faster than ``max_speed_xy``, slower than both ``min_speed_xy`` and ``min_speed_theta``,
   or all zero are skipped (``KinematicParameters::isValidSpeed``).
3. **Simulate** each twist for ``sim_time`` in steps of ``time_granularity`` or of
   ``linear_granularity``/``angular_granularity`` of travel (Euler steps from the robot's pose in
   the costmap's frame); the standard generator ramps the velocity from the current one by the
   acceleration limits, the limited one holds the twist. With ``include_last_point`` the last pose
   appears twice, as in Nav2.
4. **Score** (``coreScoringAlgorithm``): each critic of ``critics`` in order adds
   ``scale·score`` (critics with scale 0 are skipped); a trajectory one critic finds illegal is out.
   The lowest total wins, the first in sampling order on a tie; none legal raises
   :class:`~pppbot_nav.errors.CollisionAhead` (Nav2: "No valid trajectories"), naming how many
   trajectories each critic ruled out and why. Critics are reset on a new path and debriefed with
   the command (zeros when there was none).

Where this differs from Nav2:

* Every critic scores every trajectory (``short_circuit_trajectory_evaluation`` is accepted and has
  no effect): with scales ≥ 0 a cut-short trajectory already scores above the best, so the command
  is the same; only the counts in the "no valid trajectory" message may differ.
* Scales must be ≥ 0 (a negative one breaks Nav2's "total < 0 means none yet" test), unknown
  aggregation types and generator names are errors (Nav2 logs and falls back), and vy must stay 0:
  :class:`~pppbot_nav.controller.pure_pursuit.Command` has no lateral velocity.
* The kinematic defaults are Nav2's bringup values (``max_vel_x`` 0.26 m/s, ``max_vel_theta`` 1.0
  rad/s, ``acc_lim_x`` 2.5, ``decel_lim_x`` −2.5 ...): Nav2 declares them 0.0, which samples no twist.
  ``critics`` defaults to the bringup list (Nav2 requires the parameter).
* ``LimitedAccelGenerator`` takes its period from ``dt_s`` (Nav2: ``sim_period`` or
  ``controller_frequency``). Oscillation's ``oscillation_reset_time`` runs on the sum of ``dt_s``.
* ``RotateToGoal.lookahead_time`` takes pose i at i·step; Nav2 reads the time offsets one past the
  end there. The goal's yaw of an (N, 2) path is the heading of its last segment (Nav2's paths
  always carry one); of a one-point path, the robot's yaw.
* No costmap is an error (Nav2 always has one); a plan with nothing left near the robot raises
  :class:`~pppbot_nav.errors.ControllerError` (Nav2: ``InvalidPath``).
"""
from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np

from pppbot_common.se2 import PoseLike
from pppbot_nav.controller.dwb_critic_plugins import critic_type, make_critics, unknown_critic
from pppbot_nav.controller.dwb_critics import (
    Context,
    RotateToGoal,
    Trajectories,
    TrajectoryCritic,
)
from pppbot_nav.controller.pure_pursuit import Command, ControlMode
from pppbot_nav.costmap.grid import Costmap
from pppbot_nav.errors import CollisionAhead, ControllerError
from pppbot_nav.plugins import plugins

STANDARD_GENERATOR = "dwb_plugins::StandardTrajectoryGenerator"
LIMITED_ACCEL_GENERATOR = "dwb_plugins::LimitedAccelGenerator"
#: Nav2 bringup's critics (``nav2_params.yaml``); ppp_bot uses the same list.
DEFAULT_CRITICS = ("RotateToGoal", "Oscillation", "BaseObstacle", "GoalAlign", "PathAlign", "PathDist", "GoalDist")
#: Nav2's velocity iterator tolerance (``dwb_plugins::EPSILON``).
_EPSILON = 1e-5


@dataclass(frozen=True)
class DWBSettings:
    """DWB's own parameters under Nav2's names (relative to the plugin: ``FollowPath.``); each critic's
    are its plugin's (:mod:`pppbot_nav.controller.dwb_critic_plugins`)."""

    critics: tuple[str, ...] = DEFAULT_CRITICS
    prune_plan: bool = True
    prune_distance: float = 2.0  # m
    forward_prune_distance: float = 2.0  # m; negative: the whole plan
    shorten_transformed_plan: bool = True
    short_circuit_trajectory_evaluation: bool = True  # accepted, no effect on the command (module doc)
    trajectory_generator_name: str = STANDARD_GENERATOR
    # KinematicParameters (Nav2 bringup's values; the plugin declares 0.0)
    min_vel_x: float = 0.0  # m/s
    min_vel_y: float = 0.0  # m/s
    max_vel_x: float = 0.26  # m/s
    max_vel_y: float = 0.0  # m/s
    max_vel_theta: float = 1.0  # rad/s
    min_speed_xy: float = 0.0  # m/s; negative: no minimum
    max_speed_xy: float = 0.26  # m/s; negative: no maximum
    min_speed_theta: float = 0.0  # rad/s; negative: no minimum
    acc_lim_x: float = 2.5  # m/s²
    acc_lim_y: float = 0.0  # m/s²
    acc_lim_theta: float = 3.2  # rad/s²
    decel_lim_x: float = -2.5  # m/s² (negative, as Nav2)
    decel_lim_y: float = 0.0  # m/s²
    decel_lim_theta: float = -3.2  # rad/s²
    # XYThetaIterator
    vx_samples: int = 20
    vy_samples: int = 5
    vtheta_samples: int = 20
    # StandardTrajectoryGenerator
    sim_time: float = 1.7  # s
    discretize_by_time: bool = False
    time_granularity: float = 0.5  # s
    linear_granularity: float = 0.5  # m
    angular_granularity: float = 0.025  # rad
    include_last_point: bool = True
    limit_vel_cmd_in_traj: bool = False
    # Read by RotateToGoal (the plugin's own parameters, as in Nav2: not the goal checker's)
    xy_goal_tolerance: float = 0.25  # m
    trans_stopped_velocity: float = 0.25  # m/s
    #: The local costmap's footprint (its robot_radius and footprint_padding), for ObstacleFootprint.
    robot_radius: float = 0.3  # m
    footprint_padding: float = 0.01  # m

    def validate(self) -> None:
        """Raises ControllerError naming the first bad parameter, its value and what is allowed."""
        for f in fields(self):
            _check_type(f.name, str(f.type), getattr(self, f.name))
        if not self.critics:
            raise ControllerError("critics must name at least one critic (Nav2's: "
                                  f"{', '.join(plugins('DWB critic'))})", "critics")
        for name in self.critics:
            if critic_type(name) is None:
                raise ControllerError(unknown_critic(name), "critics")
        if self.trajectory_generator_name not in (STANDARD_GENERATOR, LIMITED_ACCEL_GENERATOR):
            raise ControllerError(f"trajectory_generator_name must be {STANDARD_GENERATOR!r} or "
                                  f"{LIMITED_ACCEL_GENERATOR!r}, not {self.trajectory_generator_name!r}",
                                  "trajectory_generator_name")
        self._check_ranges()

    def _check_ranges(self) -> None:
        positive = ("sim_time", "time_granularity", "linear_granularity", "angular_granularity", "robot_radius")
        at_least_zero = ("prune_distance", "max_vel_theta", "acc_lim_x", "acc_lim_y", "acc_lim_theta",
                         "xy_goal_tolerance", "trans_stopped_velocity", "footprint_padding")
        for name in positive:
            if getattr(self, name) <= 0.0:
                raise ControllerError(f"{name} must be positive, not {getattr(self, name)}", name)
        for name in at_least_zero:
            if getattr(self, name) < 0.0:
                raise ControllerError(f"{name} must be 0 or more, not {getattr(self, name)}", name)
        for name in ("decel_lim_x", "decel_lim_y", "decel_lim_theta"):
            if getattr(self, name) > 0.0:
                raise ControllerError(f"{name} must be 0 or negative (Nav2's sign), not {getattr(self, name)}", name)
        for name in ("vx_samples", "vy_samples", "vtheta_samples"):
            if getattr(self, name) < 1:
                raise ControllerError(f"{name} must be 1 or more, not {getattr(self, name)}", name)
        if self.min_vel_x > self.max_vel_x:
            raise ControllerError(f"min_vel_x ({self.min_vel_x}) must not exceed max_vel_x ({self.max_vel_x})",
                                  "min_vel_x")
        for name in ("min_vel_y", "max_vel_y"):
            if getattr(self, name) != 0.0:
                raise ControllerError(f"{name} must be 0 on pppbot's differential base, not {getattr(self, name)}",
                                      name)


_KINDS: dict[str, tuple[str, Callable[[Any], bool]]] = {
    "bool": ("true or false", lambda v: isinstance(v, bool)),
    "int": ("an integer", lambda v: isinstance(v, int) and not isinstance(v, bool)),
    "str": ("a string", lambda v: isinstance(v, str)),
    "tuple[str, ...]": ("a list of names", lambda v: isinstance(v, tuple) and all(isinstance(n, str) for n in v)),
    "float": ("a finite number",
              lambda v: isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)),
}


def _check_type(name: str, kind: str, value: object) -> None:
    what, ok = _KINDS[kind]
    if not ok(value):
        raise ControllerError(f"{name} must be {what}, not {value!r}", name)


def _project(v0: np.ndarray | float, acc: float, decel: float, dt: np.ndarray | float,
             target: np.ndarray | float) -> Any:
    """Velocity after ``dt`` from ``v0`` towards ``target`` at the limits (Nav2's ``projectVelocity``)."""
    return np.where(np.less(v0, target), np.minimum(target, np.add(v0, np.multiply(acc, dt))),
                    np.maximum(target, np.add(v0, np.multiply(decel, dt))))


def axis_samples(current: float, low: float, high: float, acc: float, decel: float, window_s: float,
                 samples: int) -> list[float]:
    """One axis's velocities, in Nav2's order (``OneDVelocityIterator``): evenly spaced over the window
    reachable in ``window_s``, with 0 slipped in where the samples cross it."""
    current = min(max(current, low), high)
    top = float(_project(current, acc, decel, window_s, high))
    bottom = float(_project(current, acc, decel, window_s, low))
    if abs(bottom - top) < _EPSILON:
        return [bottom]
    increment = (top - bottom) / max(1, max(2, samples) - 1)
    out, value, zero_pending = [], bottom, True
    while value <= top + _EPSILON:
        out.append(value)
        if zero_pending and value < 0.0 < value + increment <= top + _EPSILON:
            out.append(0.0)
            zero_pending = False
        value += increment
    return out


def sample_twists(s: DWBSettings, velocity: tuple[float, float, float], window_s: float) -> np.ndarray:
    """(K, 3) the twists (vx, vy, ω) DWB tries, x slowest and ω fastest, invalid speeds dropped."""
    xs = axis_samples(velocity[0], s.min_vel_x, s.max_vel_x, s.acc_lim_x, s.decel_lim_x, window_s, s.vx_samples)
    ys = axis_samples(velocity[1], s.min_vel_y, s.max_vel_y, s.acc_lim_y, s.decel_lim_y, window_s, s.vy_samples)
    ths = axis_samples(velocity[2], -s.max_vel_theta, s.max_vel_theta, s.acc_lim_theta, s.decel_lim_theta,
                       window_s, s.vtheta_samples)
    twists = np.stack([g.ravel() for g in np.meshgrid(xs, ys, ths, indexing="ij")], axis=1)
    speed_sq = twists[:, 0] ** 2 + twists[:, 1] ** 2
    w = np.abs(twists[:, 2])
    too_fast = (s.max_speed_xy >= 0.0) & (speed_sq > s.max_speed_xy ** 2)
    too_slow = (s.min_speed_xy >= 0.0) & (speed_sq < s.min_speed_xy ** 2) & (s.min_speed_theta >= 0.0) & (
        w < s.min_speed_theta)
    still = (speed_sq == 0.0) & (twists[:, 2] == 0.0)
    return twists[~(too_fast | too_slow | still)]


def generate_trajectories(s: DWBSettings, pose: np.ndarray, velocity: np.ndarray, twists: np.ndarray
                          ) -> Trajectories:
    """Simulate each twist of ``twists`` (K, 3) from ``pose`` (x, y, yaw) at ``velocity`` (vx, vy, ω)."""
    count = len(twists)
    if s.discretize_by_time:
        steps = np.full(count, max(1, math.ceil(s.sim_time / s.time_granularity)))
    else:
        linear = np.hypot(twists[:, 0], twists[:, 1]) * s.sim_time / s.linear_granularity
        angular = np.abs(twists[:, 2]) * s.sim_time / s.angular_granularity
        steps = np.maximum(np.ceil(np.maximum(linear, angular)), 1).astype(int)
    step_s = s.sim_time / steps
    longest = int(steps.max(initial=1))
    active = np.arange(1, longest + 1)[None, :] <= steps[:, None]
    limits = ((s.acc_lim_x, s.decel_lim_x), (s.acc_lim_y, s.decel_lim_y), (s.acc_lim_theta, s.decel_lim_theta))
    first = twists.copy()
    moves = np.zeros((3, count, longest))  # per axis, the distance covered in each step
    for axis, (acc, decel) in enumerate(limits):
        target = twists[:, axis]
        if velocity[axis] == 0.0 and not target.any():
            continue  # vy of a differential base
        if s.trajectory_generator_name == STANDARD_GENERATOR:
            # Nav2 steps v towards the target by acc·dt (decel·dt) and holds it once there.
            rate = np.where(velocity[axis] < target, acc, decel)
            with np.errstate(divide="ignore", invalid="ignore"):
                reach_s = np.where(rate != 0.0, (target - velocity[axis]) / rate, np.inf)
            elapsed = np.minimum(np.arange(1, longest + 1)[None, :] * step_s[:, None], reach_s[:, None])
            speed = velocity[axis] + rate[:, None] * elapsed
            first[:, axis] = speed[:, 0]
        else:
            speed = np.broadcast_to(target[:, None], active.shape)
        moves[axis] = np.where(active, speed * step_s[:, None], 0.0)
    poses = np.empty((count, longest + 1 + int(s.include_last_point), 3))
    poses[:, 0] = pose
    np.cumsum(moves[2], axis=1, out=poses[:, 1:longest + 1, 2])
    poses[:, 1:longest + 1, 2] += pose[2]
    heading = poses[:, :longest, 2]  # the yaw at each step's start: Nav2 moves, then turns
    c, sn = np.cos(heading), np.sin(heading)
    dx, dy = moves[0] * c, moves[0] * sn
    if moves[1].any():
        dx, dy = dx - moves[1] * sn, dy + moves[1] * c
    np.cumsum(dx, axis=1, out=poses[:, 1:longest + 1, 0])
    np.cumsum(dy, axis=1, out=poses[:, 1:longest + 1, 1])
    poses[:, 1:longest + 1, :2] += pose[:2]
    if s.include_last_point:
        poses[:, -1] = poses[:, -2]
    command = first if s.limit_vel_cmd_in_traj else twists
    return Trajectories(command, poses, steps + 1 + int(s.include_last_point), steps, step_s)


def _to_frame(points: np.ndarray, source: tuple[float, ...], target: tuple[float, ...]) -> np.ndarray:
    """(N, 2) points moved from the frame where the robot is at ``source`` to where it is at ``target``."""
    turn = target[2] - source[2]
    c, s = math.cos(turn), math.sin(turn)
    dx, dy = points[:, 0] - source[0], points[:, 1] - source[1]
    return np.c_[target[0] + c * dx - s * dy, target[1] + s * dx + c * dy]


class DWBLocalPlanner:
    """Nav2's DWB local planner, one :meth:`compute` per control period (see the module doc)."""

    def __init__(self, settings: DWBSettings, critics: Mapping[str, TrajectoryCritic] | None = None) -> None:
        """``critics``: the critics ``settings.critics`` names, by that name, made from their parameters
        (the controller server makes them from its own, :func:`make_critics` from values given);
        default: each with its defaults.

        Raises ControllerError: bad settings (an unknown critic among them), or a critic not given.
        """
        settings.validate()
        self.settings = settings
        made = make_critics(settings.critics) if critics is None else critics
        missing = [name for name in settings.critics if name not in made]
        if missing:
            raise ControllerError(f"critic {missing[0]!r} of critics was not made (the controller server makes "
                                  "each from its parameters)", "critics")
        self.critics = [made[name] for name in settings.critics]
        self._path: np.ndarray | None = None  # as given
        self._plan = np.empty((0, 2))  # what is left of the path (prune_plan drops passed points)
        self._goal_yaw: float | None = None
        self._dropped = 0  # path points pruned away
        self._progress = 0  # index in the path of the transformed plan's first point
        self._clock_s = 0.0
        self._best = np.empty((0, 3))

    def set_footprint(self, robot_radius: float, footprint_padding: float) -> None:
        """The local costmap's footprint changed: the critics see it from the next period (every
        critic keeps its state, Oscillation's, and the path its progress)."""
        changed = replace(self.settings, robot_radius=robot_radius, footprint_padding=footprint_padding)
        changed.validate()
        self.settings = changed

    def set_path(self, path: np.ndarray) -> None:
        """Follow ``path`` ((N, 2) x, y or (N, 3) x, y, yaw; m, rad): critics are reset, as Nav2's
        ``setPlan``. The last yaw is the goal's heading.

        Raises:
            ControllerError: an empty path, a wrong shape or a non-finite value.
        """
        points = np.array(path, dtype=float, copy=True)
        if points.ndim != 2 or points.shape[1] not in (2, 3):
            raise ControllerError(f"path must be an (N, 2) or (N, 3) array of x, y[, yaw], not shape {points.shape}",
                                  "path")
        if len(points) == 0:
            raise ControllerError("path is empty: it needs at least one point", "path")
        bad = np.flatnonzero(~np.isfinite(points).all(axis=1))
        if bad.size:
            raise ControllerError(f"path point {bad[0]} is not finite: {points[bad[0]].tolist()}", "path")
        self._path = points
        self._plan = points[:, :2]
        if points.shape[1] == 3:
            self._goal_yaw = float(points[-1, 2])
        else:
            steps = np.flatnonzero(np.hypot(*np.diff(points, axis=0).T) > 0.0)
            self._goal_yaw = (float(np.arctan2(*(points[steps[-1] + 1] - points[steps[-1]])[::-1]))
                              if steps.size else None)
        self._dropped = self._progress = 0
        for critic in self.critics:
            critic.reset()

    def reset(self) -> None:
        """Forget the path (the next :meth:`compute` starts it afresh)."""
        self._path = None
        self._dropped = self._progress = 0

    @property
    def progress_index(self) -> int:
        """Index in the path of the first point of the last transformed plan."""
        return self._progress

    @property
    def best_trajectory(self) -> np.ndarray:
        """(P, 3) x, y, yaw of the last chosen trajectory, in the path's frame (Nav2's local_plan)."""
        return self._best

    def _take_path(self, path: np.ndarray) -> None:
        if self._path is not None and path is self._path:
            return
        points = np.asarray(path)
        if self._path is None or points.shape != self._path.shape or not np.array_equal(points, self._path):
            self.set_path(points)

    def compute(self, pose: PoseLike, speed: PoseLike, path: np.ndarray, costmap: Costmap | None,
                dt_s: float, costmap_pose: PoseLike | None = None) -> Command:
        """The command for this control period.

        Args:
            pose: the robot's x, y, yaw (m, m, rad) in the frame of ``path``.
            speed: its current v, ω (m/s, rad/s).
            path: (N, 2) or (N, 3) x, y[, yaw]; a path different from the last one resets the critics.
            costmap: the local costmap (required).
            dt_s: the control period (s): the LimitedAccelGenerator's window, the oscillation clock.
            costmap_pose: the robot's pose in the costmap's frame; default ``pose``.

        Returns:
            The best trajectory's twist; ``lookahead`` is the transformed plan's last point (the point
            GoalDist draws the robot to) and ``local_plan`` the transformed plan, both in the path's frame;
            ``mode`` is ROTATE_TO_GOAL when RotateToGoal has the robot near the goal and v is 0.

        Raises:
            ControllerError: bad pose, speed, path or ``dt_s``, no costmap, nothing of the path left near
                the robot.
            CollisionAhead: every trajectory is illegal (Nav2's "No valid trajectories").
        """
        s = self.settings
        robot = _finite_vector(pose, 3, "pose", "x, y, yaw")
        in_costmap = robot if costmap_pose is None else _finite_vector(costmap_pose, 3, "costmap_pose", "x, y, yaw")
        v_now, w_now = _finite_vector(speed, 2, "speed", "v, ω")
        if not (math.isfinite(dt_s) and dt_s > 0.0):
            raise ControllerError(f"dt_s must be a positive number of seconds, not {dt_s}", "dt_s")
        if costmap is None:
            raise ControllerError("DWB needs the local costmap: none given", "costmap")
        self._take_path(path)

        local = self._transform_plan(robot, costmap)
        goal_yaw = robot[2] if self._goal_yaw is None else self._goal_yaw
        goal_xy = _to_frame(self._plan[-1:], robot, in_costmap)[0]
        velocity = np.array([v_now, 0.0, w_now])
        ctx = Context(np.array(in_costmap), velocity, np.array([*goal_xy, goal_yaw + in_costmap[2] - robot[2]]),
                      _to_frame(local, robot, in_costmap), costmap, self._clock_s, s)
        for critic in self.critics:
            critic.prepare(ctx)
        window_s = s.sim_time if s.trajectory_generator_name == STANDARD_GENERATOR else dt_s
        traj = generate_trajectories(s, ctx.pose, velocity, sample_twists(s, (v_now, 0.0, w_now), window_s))
        self._clock_s += dt_s
        try:
            best = self._choose(traj)
        except CollisionAhead:
            for critic in self.critics:
                critic.debrief(np.zeros(3))
            self._best = np.empty((0, 3))
            raise
        for critic in self.critics:
            critic.debrief(traj.velocity[best])
        poses = traj.poses[best, :traj.counts[best]]
        self._best = np.c_[_to_frame(poses[:, :2], in_costmap, robot), poses[:, 2] - in_costmap[2] + robot[2]]
        return self._command(traj.velocity[best], robot, local)

    def _transform_plan(self, robot: tuple[float, ...], costmap: Costmap) -> np.ndarray:
        """(M ≥ 1, 2) the transformed plan in the path's frame; drops passed points with prune_plan."""
        s = self.settings
        plan = self._plan
        if len(plan) == 0:
            raise ControllerError("nothing is left of the path: it was pruned away while the robot was far "
                                  "from it (set a new path)", "path")
        half_m = max(costmap.width, costmap.height) * costmap.resolution / 2.0
        forward_m = math.inf if s.forward_prune_distance < 0.0 else s.forward_prune_distance
        start_m = min(half_m, s.prune_distance) if s.prune_plan else half_m
        end_m = min(half_m, forward_m) if s.shorten_transformed_plan else half_m
        along = np.cumsum(np.hypot(*np.diff(plan, axis=0).T))  # path length to points 1..N-1
        beyond = np.flatnonzero(along > forward_m)
        search_end = int(beyond[0]) + 1 if beyond.size else len(plan)
        dist = np.hypot(plan[:, 0] - robot[0], plan[:, 1] - robot[1])
        near = np.flatnonzero(dist[:search_end] < start_m)
        begin = int(near[0]) if near.size else search_end
        far = np.flatnonzero(dist[begin:] > end_m)
        end = begin + int(far[0]) if far.size else len(plan)
        local = plan[begin:end]
        self._progress = self._dropped + begin
        if s.prune_plan:
            self._plan = plan[begin:]
            self._dropped += begin
        if len(local) == 0:
            raise ControllerError(f"no path point within {min(start_m, end_m):.2f} m of the robot at "
                                  f"({robot[0]:.2f}, {robot[1]:.2f}) (Nav2: resulting plan has 0 poses)", "path")
        return local.copy()

    def _choose(self, traj: Trajectories) -> int:
        """Index of the legal trajectory with the lowest total cost (the first on a tie)."""
        total = np.zeros(len(traj))
        verdict = np.full(len(traj), -1)  # index into ``why`` of the first critic to rule a trajectory out
        why: list[str] = []
        for critic in self.critics:
            scale = critic.effective_scale()
            if scale == 0.0 or len(traj) == 0:
                continue
            scores, illegal = critic.score(traj)
            total += scores * scale
            for code in np.unique(illegal[(illegal > 0) & (verdict < 0)]):
                verdict[(illegal == code) & (verdict < 0)] = len(why)
                why.append(f"{critic.name}/{critic.reasons[code - 1]}")
        legal = verdict < 0
        if not legal.any():
            counts = Counter(verdict.tolist())
            detail = ", ".join(f"{why[i]} {100.0 * n / len(traj):.0f}%" for i, n in counts.most_common())
            raise CollisionAhead(f"no valid trajectory among {len(traj)} (Nav2: No valid trajectories)"
                                 + (f": {detail}" if detail else ": no twist in the dynamic window"))
        return int(np.argmin(np.where(legal, total, np.inf)))

    def _command(self, twist: np.ndarray, robot: tuple[float, ...], local: np.ndarray) -> Command:
        linear, angular = float(twist[0]), float(twist[2])
        rotating = any(isinstance(c, RotateToGoal) and c.in_window and c.effective_scale() != 0.0
                       for c in self.critics)
        mode = ControlMode.ROTATE_TO_GOAL if rotating and linear == 0.0 else ControlMode.TRACKING
        target = (float(local[-1, 0]), float(local[-1, 1]))
        return Command(linear, angular, target, angular / linear if linear != 0.0 else 0.0, local, mode,
                       math.hypot(target[0] - robot[0], target[1] - robot[1]))


def _finite_vector(value: PoseLike, size: int, name: str, what: str) -> tuple[float, ...]:
    array = np.asarray(value, dtype=float).reshape(-1)
    if array.shape != (size,) or not np.isfinite(array).all():
        raise ControllerError(f"{name} must be {size} finite numbers ({what}), not {np.asarray(value).tolist()}",
                              name)
    return tuple(float(a) for a in array)
