"""Nav2's Regulated Pure Pursuit controller (``nav2_regulated_pure_pursuit_controller``) without ROS.

Each control period, :meth:`PurePursuit.compute` does what the plugin's
``computeVelocityCommands`` does, in the frame of the pose, the path and the costmap:

1. **Prune** the path: the closest path point to the robot, searched from the progress
   of the previous call up to ``max_robot_pose_search_dist`` further along the path (so a
   path that crosses itself does not send the robot back), becomes the new start; the
   local plan runs from there to the last point within the costmap's half extent.
2. **Lookahead**: ``lookahead_dist``, or ``|v|·lookahead_time`` clamped to
   ``[min_lookahead_dist, max_lookahead_dist]``. The carrot is where the circle of that
   radius round the robot leaves the local plan (the first point at least that far,
   interpolated on its segment), or the plan's last point.
3. **Curvature** of the arc through the carrot: ``2·y/L²`` (robot frame, ``L`` the distance).
4. **Rotate to heading**: with the goal's yaw known and the robot within ``goal_dist_tol``
   of the path's end, turn in place to that yaw; else, with the carrot more than
   ``rotate_to_heading_min_angle`` off the heading, turn in place towards it. Turns run at
   ``rotate_to_heading_angular_vel``, slowed to stop on the heading (``√(2·a·|θ|)``) and
   changed by at most ``max_angular_accel·dt_s`` from the current ω.
5. **Regulation** otherwise (Macenski et al., 2023): from ``desired_linear_vel``, the
   curvature constraint (``v·r/r_min`` on arcs tighter than
   ``regulated_linear_scaling_min_radius``) and the cost constraint (the obstacle distance
   recovered from the robot cell's inflated cost, ``d = −ln(cost/252)/inflation_cost_scaling_factor
   + robot_radius``; below ``cost_scaling_dist`` the speed is scaled by
   ``cost_scaling_gain·d/cost_scaling_dist``), the lower of the two, floored at
   ``regulated_linear_scaling_min_speed``; then the approach constraint (within
   ``approach_velocity_scaling_dist`` of the end, ``desired·distance/approach_dist``, never
   below ``min_approach_linear_velocity``); ``ω = v·curvature``.
6. **Collision check**: the command is followed forward in steps of half a costmap cell for
   up to ``max_allowed_time_to_collision_up_to_carrot`` but no farther than the carrot; a
   pose on an inscribed or lethal cell means a collision. Before that is raised
   (:class:`~pppbot_nav.errors.CollisionAhead`), steps 2–5 are tried again with the carrot
   closer (half way to ``min_lookahead_dist``, then at it), each checked as far ahead as the
   first: a far carrot cuts corners that the path itself keeps clear of. Turning
   in place is never a collision (the footprint is a circle), and a robot that is already in
   the inscribed zone may drive on as long as it comes no nearer the closest lethal cell (so
   it can leave the zone, or follow the path along it, but not drive its corners into a wall).

Where this differs from Nav2:

* ``|ω|`` is capped at ``max_angular_vel`` (``v`` scaled down with it, so the arc is kept),
  which Nav2 leaves to the velocity smoother.
* Turning in place, the acceleration limit is applied last, so ω never changes by more than
  ``max_angular_accel·dt_s`` (Nav2 applies its stop-on-heading slow-down after the limit).
* The goal heading is taken when the robot is within ``goal_dist_tol`` of the path's last
  point and the path carries a yaw ((N, 3)); Nav2 measures to the carrot and always has one.
* The collision check steps half a cell, not one: a one-cell wall cannot fall between poses.
* A command that would collide is retried with closer carrots before it fails (Nav2 fails).
* A robot inside the inscribed zone may drive out of it or along it, never nearer the closest
  lethal cell (Nav2's footprint check fails every command there).
* The approach constraint starts when the path remaining from the closest point, not the
  cropped local plan, is shorter than ``approach_velocity_scaling_dist``.
* A robot farther than the costmap's half extent from every path point follows the closest
  one (Nav2 fails with an empty plan).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from pppbot_common.se2 import PoseLike, wrap_angle
from pppbot_nav.controller.interface import Command, Controller, ControlMode  # noqa: F401 (their old home)
from pppbot_nav.costmap.costs import (
    FREE_SPACE,
    INSCRIBED_INFLATED_OBSTACLE,
    LETHAL_OBSTACLE,
    MAX_NON_OBSTACLE,
    NO_INFORMATION,
)
from pppbot_nav.costmap.grid import Costmap
from pppbot_nav.errors import CollisionAhead, ControllerError

#: Carrots closer than this (m²) give zero curvature, as Nav2's ``calculateCurvature``.
_MIN_CARROT_DIST2 = 0.001
#: Below this |v| (m/s) with |ω| above it (rad/s) the collision check steps by rotation.
_STILL_VEL = 0.01
#: Poses per cell of travel in the collision check: Nav2 takes one, which can step over a
#: one-cell obstacle when the poses fall on cell borders.
_CELL_SUBSTEPS = 2
#: Inside the inscribed zone a command may bring the robot this much (in cells) nearer the closest
#: lethal cell: the distance to cell centres ripples by about this much along a straight wall.
_LEAVE_TOLERANCE_CELLS = 0.1
#: Forward-simulated poses of one collision check at most (a bound on work, never reached at sane speeds).
_MAX_SIM_STEPS = 2000


@dataclass(frozen=True)
class PurePursuitSettings:
    """Nav2's RPP parameters (names and defaults), pppbot's footprint, and three additions."""

    desired_linear_vel: float = 0.5  # m/s
    lookahead_dist: float = 0.6  # m, when the lookahead is not velocity-scaled
    min_lookahead_dist: float = 0.3  # m
    max_lookahead_dist: float = 0.9  # m
    lookahead_time: float = 1.5  # s: velocity-scaled lookahead is |v|·lookahead_time
    rotate_to_heading_angular_vel: float = 1.8  # rad/s
    use_velocity_scaled_lookahead_dist: bool = False
    min_approach_linear_velocity: float = 0.05  # m/s
    approach_velocity_scaling_dist: float = 0.6  # m
    use_collision_detection: bool = True
    max_allowed_time_to_collision_up_to_carrot: float = 1.0  # s
    use_regulated_linear_velocity_scaling: bool = True
    use_cost_regulated_linear_velocity_scaling: bool = True
    regulated_linear_scaling_min_radius: float = 0.9  # m
    regulated_linear_scaling_min_speed: float = 0.25  # m/s
    use_rotate_to_heading: bool = True
    rotate_to_heading_min_angle: float = 0.785  # rad
    max_angular_accel: float = 3.2  # rad/s²
    cost_scaling_dist: float = 0.6  # m
    cost_scaling_gain: float = 1.0
    inflation_cost_scaling_factor: float = 3.0  # 1/m: the inflation layer's cost_scaling_factor
    #: Nav2 searches for the closest path point this far along the path from the last one; its
    #: default is the local costmap's half extent, 2.5 m for pppbot's 5 m window.
    max_robot_pose_search_dist: float = 2.5  # m
    robot_radius: float = 0.3  # m: pppbot's circular footprint (the costmap's inscribed radius)
    max_angular_vel: float = 2.0  # rad/s: cap on |ω| while tracking (not in Nav2's RPP)
    #: The goal checker's xy tolerance: inside it the controller only turns to the goal's yaw.
    goal_dist_tol: float = 0.25  # m

    def validate(self) -> None:
        """Raises ControllerError naming the first bad parameter, its value and what is allowed."""
        for f in fields(self):
            value = getattr(self, f.name)
            if f.type in ("bool", bool):
                if not isinstance(value, bool):
                    raise ControllerError(f"{f.name} must be true or false, not {value!r}", f.name)
            elif not (isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)):
                raise ControllerError(f"{f.name} must be a finite number, not {value!r}", f.name)
        for name in ("desired_linear_vel", "lookahead_dist", "min_lookahead_dist", "max_lookahead_dist",
                     "lookahead_time", "rotate_to_heading_angular_vel", "approach_velocity_scaling_dist",
                     "max_allowed_time_to_collision_up_to_carrot", "regulated_linear_scaling_min_radius",
                     "max_angular_accel", "cost_scaling_dist", "inflation_cost_scaling_factor",
                     "max_robot_pose_search_dist", "robot_radius", "max_angular_vel", "goal_dist_tol"):
            if getattr(self, name) <= 0.0:
                raise ControllerError(f"{name} must be positive, not {getattr(self, name)}", name)
        for name in ("min_approach_linear_velocity", "regulated_linear_scaling_min_speed"):
            value = getattr(self, name)
            if not 0.0 <= value <= self.desired_linear_vel:
                raise ControllerError(f"{name} must be in [0, desired_linear_vel = {self.desired_linear_vel}] m/s, "
                                      f"not {value}", name)
        if self.min_lookahead_dist > self.max_lookahead_dist:
            raise ControllerError(f"min_lookahead_dist ({self.min_lookahead_dist}) must not exceed "
                                  f"max_lookahead_dist ({self.max_lookahead_dist})", "min_lookahead_dist")
        if not 0.0 < self.cost_scaling_gain <= 1.0:
            raise ControllerError(f"cost_scaling_gain must be in (0, 1], not {self.cost_scaling_gain}",
                                  "cost_scaling_gain")
        if not 0.0 <= self.rotate_to_heading_min_angle <= math.pi:
            raise ControllerError(f"rotate_to_heading_min_angle must be in [0, π] rad, not "
                                  f"{self.rotate_to_heading_min_angle}", "rotate_to_heading_min_angle")


class PurePursuit:
    """Nav2's Regulated Pure Pursuit, one :meth:`compute` per control period (see the module doc)."""

    def __init__(self, settings: PurePursuitSettings) -> None:
        """Raises ControllerError: bad settings."""
        settings.validate()
        self.settings = settings
        self._path: np.ndarray | None = None  # (N, 2) or (N, 3) as given
        self._xy = np.empty((0, 2))
        self._cum_m = np.empty(0)  # path length from the first point to each point
        self._goal_yaw: float | None = None
        self._start = 0  # progress: the path points before it are passed

    # ------------------------------------------------------------------ path
    def set_path(self, path: np.ndarray) -> None:
        """Follow ``path`` ((N, 2) x, y or (N, 3) x, y, yaw; m, rad) from its start: progress is reset.
        Only the last yaw is used, as the goal's heading.

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
        self._xy = points[:, :2]
        self._cum_m = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(self._xy, axis=0).T))])
        self._goal_yaw = float(points[-1, 2]) if points.shape[1] == 3 else None
        self._start = 0

    def reset(self) -> None:
        """Forget the path (the next :meth:`compute` starts its path afresh)."""
        self._path = None
        self._start = 0

    @property
    def progress_index(self) -> int:
        """Index of the path point the robot was last closest to."""
        return self._start

    def _take_path(self, path: np.ndarray) -> None:
        if self._path is not None and path is self._path:
            return
        points = np.asarray(path)
        if self._path is None or points.shape != self._path.shape or not np.array_equal(points, self._path):
            self.set_path(points)

    # --------------------------------------------------------------- control
    def compute(self, pose: PoseLike, speed: PoseLike, path: np.ndarray, costmap: Costmap | None,
                dt_s: float, costmap_pose: PoseLike | None = None) -> Command:
        """The command for this control period.

        Args:
            pose: the robot's x, y, yaw (m, m, rad) in the frame of ``path``.
            speed: its current v, ω (m/s, rad/s).
            path: (N, 2) or (N, 3) x, y[, yaw]; a path different from the last one resets progress.
            costmap: the local costmap, or None: no collision check and no cost regulation.
            dt_s: the control period (s), which bounds the change of ω when turning in place.
            costmap_pose: the robot's pose in the costmap's frame, when that is not the path's
                (e.g. a path in ``map``, the local costmap in ``odom``); default ``pose``.

        Raises:
            ControllerError: an empty or non-finite path, a non-finite pose or speed, a bad ``dt_s``.
            CollisionAhead: the command would put the robot on an inscribed or lethal cell soon.
        """
        s = self.settings
        x, y, yaw = _finite_vector(pose, 3, "pose", "x, y, yaw")
        in_costmap = (x, y, yaw)
        if costmap_pose is not None:
            mx, my, myaw = _finite_vector(costmap_pose, 3, "costmap_pose", "x, y, yaw")
            in_costmap = (mx, my, myaw)
        v_now, w_now = _finite_vector(speed, 2, "speed", "v, ω")
        if not (math.isfinite(dt_s) and dt_s > 0.0):
            raise ControllerError(f"dt_s must be a positive number of seconds, not {dt_s}", "dt_s")
        self._take_path(path)

        local = self._prune(x, y, costmap)
        c, sn = math.cos(yaw), math.sin(yaw)
        dx, dy = local[:, 0] - x, local[:, 1] - y
        rx, ry = c * dx + sn * dy, -sn * dx + c * dy  # the local plan in the robot's frame

        if s.use_velocity_scaled_lookahead_dist:
            lookahead_m = min(max(abs(v_now) * s.lookahead_time, s.min_lookahead_dist), s.max_lookahead_dist)
        else:
            lookahead_m = s.lookahead_dist
        # A carrot that far may cut a corner into an obstacle's inscribed zone: then closer carrots
        # follow the (collision-free) path more tightly before the command counts as a collision.
        tries = [lookahead_m] + [d for d in (0.5 * (lookahead_m + s.min_lookahead_dist), s.min_lookahead_dist)
                                 if d < lookahead_m - 1e-9]
        collisions: list[CollisionAhead] = []
        horizon_m = 0.0  # every try is checked as far ahead as the first one's carrot
        for distance_m in tries:
            command, carrot_dist_m = self._command(x, y, yaw, w_now, local, rx, ry, distance_m, in_costmap,
                                                   costmap, dt_s)
            if not (s.use_collision_detection and costmap is not None) or command.mode is not ControlMode.TRACKING:
                return command
            horizon_m = horizon_m or carrot_dist_m
            try:
                _check_collision(costmap, in_costmap, command.linear_mps, command.angular_radps, horizon_m, s)
            except CollisionAhead as exc:
                collisions.append(exc)
                continue
            return command
        raise collisions[0]  # the command at the usual lookahead, and why it would collide

    def _command(self, x: float, y: float, yaw: float, w_now: float, local: np.ndarray, rx: np.ndarray,
                 ry: np.ndarray, lookahead_m: float, in_costmap: tuple[float, float, float],
                 costmap: Costmap | None, dt_s: float) -> tuple[Command, float]:
        """Steps 2–5 with the carrot at ``lookahead_m``: the command and the carrot's distance (m)."""
        s = self.settings
        cx, cy = _carrot(rx, ry, lookahead_m)
        carrot_dist2 = cx * cx + cy * cy
        curvature = 2.0 * cy / carrot_dist2 if carrot_dist2 > _MIN_CARROT_DIST2 else 0.0
        c, sn = math.cos(yaw), math.sin(yaw)
        lookahead = (x + c * cx - sn * cy, y + sn * cx + c * cy)

        end_dist_m = math.hypot(rx[-1], ry[-1])
        if s.use_rotate_to_heading and self._goal_yaw is not None and end_dist_m < s.goal_dist_tol:
            mode = ControlMode.ROTATE_TO_GOAL
            linear, angular = 0.0, self._rotate(wrap_angle(self._goal_yaw - yaw), w_now, dt_s)
        elif s.use_rotate_to_heading and abs(math.atan2(cy, cx)) > s.rotate_to_heading_min_angle:
            mode = ControlMode.ROTATE_TO_PATH
            linear, angular = 0.0, self._rotate(math.atan2(cy, cx), w_now, dt_s)
        else:
            mode = ControlMode.TRACKING
            remaining_m = float(self._cum_m[-1] - self._cum_m[self._start])
            linear = self._regulated_speed(curvature, in_costmap[0], in_costmap[1], costmap, remaining_m,
                                           end_dist_m)
            angular = linear * curvature
            if abs(angular) > s.max_angular_vel:
                angular = math.copysign(s.max_angular_vel, angular)
                linear = s.max_angular_vel / abs(curvature)
        return (Command(linear, angular, lookahead, curvature, local.copy(), mode, lookahead_m),
                math.sqrt(carrot_dist2))

    def _prune(self, x: float, y: float, costmap: Costmap | None) -> np.ndarray:
        """The local plan (M ≥ 1, 2) from the closest point on; advances the progress."""
        s = self.settings
        start = self._start
        upper = int(np.searchsorted(self._cum_m, self._cum_m[start] + s.max_robot_pose_search_dist, side="right"))
        window = self._xy[start:max(upper, start + 1)]
        closest = start + int(np.argmin((window[:, 0] - x) ** 2 + (window[:, 1] - y) ** 2))
        self._start = closest
        ahead = self._xy[closest:]
        if costmap is None:
            return ahead
        extent_m = max(costmap.width, costmap.height) * costmap.resolution / 2.0
        beyond = np.hypot(ahead[:, 0] - x, ahead[:, 1] - y) > extent_m
        end = int(np.argmax(beyond)) if beyond.any() else len(ahead)
        return ahead[:max(end, 1)]

    def _rotate(self, angle_rad: float, w_now: float, dt_s: float) -> float:
        """ω (rad/s) turning in place through ``angle_rad``: at rotate_to_heading_angular_vel, slowed
        so as to stop on the heading, within max_angular_accel·dt_s of the current ω."""
        s = self.settings
        speed = min(s.rotate_to_heading_angular_vel, s.max_angular_vel,
                    math.sqrt(2.0 * s.max_angular_accel * abs(angle_rad)))
        target = math.copysign(speed, angle_rad)
        step = s.max_angular_accel * dt_s
        return min(max(target, w_now - step), w_now + step)

    def _regulated_speed(self, curvature: float, x: float, y: float, costmap: Costmap | None,
                         remaining_m: float, end_dist_m: float) -> float:
        """v (m/s) after the curvature, cost and approach constraints."""
        s = self.settings
        curvature_vel = cost_vel = s.desired_linear_vel
        if s.use_regulated_linear_velocity_scaling and curvature != 0.0:
            radius_m = 1.0 / abs(curvature)
            if radius_m < s.regulated_linear_scaling_min_radius:
                curvature_vel *= radius_m / s.regulated_linear_scaling_min_radius
        if s.use_cost_regulated_linear_velocity_scaling and costmap is not None:
            cost = int(costmap.cost_at(x, y, NO_INFORMATION))
            if cost not in (FREE_SPACE, NO_INFORMATION):
                obstacle_m = -math.log(cost / MAX_NON_OBSTACLE) / s.inflation_cost_scaling_factor + s.robot_radius
                if obstacle_m < s.cost_scaling_dist:
                    cost_vel *= s.cost_scaling_gain * obstacle_m / s.cost_scaling_dist
        linear = max(min(curvature_vel, cost_vel), s.regulated_linear_scaling_min_speed)
        if remaining_m < s.approach_velocity_scaling_dist:
            approach_vel = s.desired_linear_vel * end_dist_m / s.approach_velocity_scaling_dist
            linear = min(linear, max(approach_vel, s.min_approach_linear_velocity))
        return min(max(linear, 0.0), s.desired_linear_vel)


def _finite_vector(value: PoseLike, size: int, name: str, what: str) -> tuple[float, ...]:
    array = np.asarray(value, dtype=float).reshape(-1)
    if array.shape != (size,):
        raise ControllerError(f"{name} must be {size} numbers ({what}), not {np.asarray(value).tolist()}", name)
    if not np.isfinite(array).all():
        raise ControllerError(f"{name} must be finite ({what}), not {array.tolist()}", name)
    return tuple(float(a) for a in array)


def _carrot(rx: np.ndarray, ry: np.ndarray, lookahead_m: float) -> tuple[float, float]:
    """Where the circle of radius ``lookahead_m`` round the origin leaves the polyline (rx, ry):
    the first point at least that far, moved back along its segment onto the circle; the last
    point if none is that far."""
    far = np.hypot(rx, ry) >= lookahead_m
    if not far.any():
        return float(rx[-1]), float(ry[-1])
    i = int(np.argmax(far))
    if i == 0:
        return float(rx[0]), float(ry[0])
    # p(t) = a + t·(b − a) with |a| < r ≤ |b|: one root of |p(t)|² = r² in (0, 1].
    ax, ay, dx, dy = rx[i - 1], ry[i - 1], rx[i] - rx[i - 1], ry[i] - ry[i - 1]
    qa = dx * dx + dy * dy
    qb = 2.0 * (ax * dx + ay * dy)
    qc = ax * ax + ay * ay - lookahead_m * lookahead_m
    t = (-qb + math.sqrt(max(qb * qb - 4.0 * qa * qc, 0.0))) / (2.0 * qa)
    return float(ax + t * dx), float(ay + t * dy)


def _check_collision(costmap: Costmap, pose: tuple[float, float, float], linear: float, angular: float,
                     carrot_dist_m: float, s: PurePursuitSettings) -> None:
    """Raise CollisionAhead if following (linear, angular) from ``pose`` meets an inscribed or lethal
    cell: the current pose, then one pose per half costmap cell of travel (or, turning in place, per
    cell swept by the footprint's rim) for up to max_allowed_time_to_collision_up_to_carrot, stopping
    once farther than the carrot. Unknown cells and cells off the costmap are not collisions."""
    x0, y0, yaw0 = pose
    if abs(linear) < _STILL_VEL:
        return  # the footprint is a circle: turning in place sweeps no new cell
    step_s = costmap.resolution / _CELL_SUBSTEPS / abs(linear) if abs(linear) > 0.0 else math.inf
    horizon_s = s.max_allowed_time_to_collision_up_to_carrot
    steps = 0 if not math.isfinite(step_s) else min(math.ceil(horizon_s / step_s) - 1, _MAX_SIM_STEPS)
    t = np.arange(0, steps + 1) * step_s
    yaw = yaw0 + angular * t
    if abs(angular) > 1e-9:
        radius = linear / angular
        xs = x0 + radius * (np.sin(yaw) - math.sin(yaw0))
        ys = y0 - radius * (np.cos(yaw) - math.cos(yaw0))
    else:
        xs = x0 + linear * t * math.cos(yaw0)
        ys = y0 + linear * t * math.sin(yaw0)
    beyond = np.hypot(xs - x0, ys - y0) > carrot_dist_m
    if beyond.any():
        keep = int(np.argmax(beyond))
        xs, ys, t = xs[:keep], ys[:keep], t[:keep]
    costs = costmap.cost_at(xs, ys, NO_INFORMATION)
    # A robot already inside the inscribed zone (it drifted close to a wall: the zone is the
    # conservative circle round a smaller body) may drive out of it, or along it, but not
    # nearer the obstacle: the body's corners would reach it.
    inside = costs[0] == INSCRIBED_INFLATED_OBSTACLE
    floor = LETHAL_OBSTACLE if inside else INSCRIBED_INFLATED_OBSTACLE
    hit = (costs >= floor) & (costs != NO_INFORMATION)
    command = f"command v={linear:.3f} m/s, ω={angular:.3f} rad/s from ({x0:.3f}, {y0:.3f})"
    if hit.any():
        k = int(np.argmax(hit))
        kind = "lethal" if costs[k] > INSCRIBED_INFLATED_OBSTACLE else "inscribed"
        raise CollisionAhead(
            f"{command} would reach ({xs[k]:.3f}, {ys[k]:.3f}) in {t[k]:.2f} s, a {kind} cell "
            f"(cost {int(costs[k])}) in frame {costmap.frame_id!r}")
    if inside:
        clearance = _lethal_clearance(costmap, xs, ys, s.robot_radius)
        nearer = clearance < clearance[0] - _LEAVE_TOLERANCE_CELLS * costmap.resolution
        if nearer.any():
            k = int(np.argmax(nearer))
            raise CollisionAhead(
                f"{command}, inside the inscribed zone, would come nearer an obstacle: "
                f"{clearance[0]:.3f} → {clearance[k]:.3f} m from the closest lethal cell at "
                f"({xs[k]:.3f}, {ys[k]:.3f}) in {t[k]:.2f} s, frame {costmap.frame_id!r}")


def _lethal_clearance(costmap: Costmap, xs: np.ndarray, ys: np.ndarray, radius_m: float) -> np.ndarray:
    """Distance (m) from each point to the closest lethal cell's centre, at most ``radius_m``."""
    lo = costmap.cell_of(xs.min() - radius_m, ys.min() - radius_m)
    hi = costmap.cell_of(xs.max() + radius_m, ys.max() + radius_m)
    row_lo, col_lo = max(int(lo[0]), 0), max(int(lo[1]), 0)
    row_hi, col_hi = min(int(hi[0]) + 1, costmap.height), min(int(hi[1]) + 1, costmap.width)
    rows, cols = np.nonzero(costmap.costs[row_lo:row_hi, col_lo:col_hi] == LETHAL_OBSTACLE)
    if rows.size == 0:
        return np.full(xs.shape, radius_m)
    cx = costmap.origin[0] + (cols + col_lo + 0.5) * costmap.resolution
    cy = costmap.origin[1] + (rows + row_lo + 0.5) * costmap.resolution
    distance = np.hypot(xs[:, None] - cx[None, :], ys[:, None] - cy[None, :]).min(axis=1)
    return np.minimum(distance, radius_m)
