"""Nav2's controller-server checkers: has the robot reached its goal, is it still making progress.

* :class:`SimpleGoalChecker` (``nav2_controller::SimpleGoalChecker``): reached when within
  ``xy_goal_tolerance`` of the goal's position and ``yaw_goal_tolerance`` of its heading.
  When stateful, once the position has been inside its tolerance it counts as inside until
  :meth:`~SimpleGoalChecker.reset` (a new goal), so the robot may drift while it turns.
* :class:`StoppedGoalChecker` (``nav2_controller::StoppedGoalChecker``): as the simple one,
  and the robot's speeds below ``trans_stopped_velocity`` and ``rot_stopped_velocity``.
* :class:`PositionGoalChecker` (``nav2_controller::PositionGoalChecker``): the position only.
* :class:`SimpleProgressChecker` (``nav2_controller::SimpleProgressChecker``): failing when
  the robot has not moved ``required_movement_radius`` from a baseline position within
  ``movement_time_allowance``; the baseline moves to the robot whenever it has.
* :class:`PoseProgressChecker` (``nav2_controller::PoseProgressChecker``): as the simple one,
  a turn of ``required_movement_angle`` counting as progress too.

Settings may change between periods (``ros2 param set``): the checkers read their attributes
each time and keep their state (the stateful goal checker's latch, the progress baseline).
"""
from __future__ import annotations

import math

import numpy as np

from pppbot_common.se2 import PoseLike, wrap_angle
from pppbot_nav.controller.interface import GoalChecker, ProgressChecker  # noqa: F401 (their old home)
from pppbot_nav.errors import ControllerError


def _positive(name: str, value: float) -> float:
    if not (isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value) and value > 0):
        raise ControllerError(f"{name} must be a positive finite number, not {value!r}", name)
    return float(value)


def _finite(value: PoseLike, size: int, name: str) -> np.ndarray:
    array = np.asarray(value, dtype=float).reshape(-1)
    if array.shape != (size,) or not np.isfinite(array).all():
        raise ControllerError(f"{name} must be {size} finite numbers, not {np.asarray(value).tolist()}", name)
    return array


class SimpleGoalChecker:
    """Goal reached: position within ``xy_goal_tolerance`` (m) and heading within ``yaw_goal_tolerance`` (rad)."""

    def __init__(self, xy_goal_tolerance: float = 0.25, yaw_goal_tolerance: float = 0.25,
                 stateful: bool = True) -> None:
        """Raises ControllerError: a tolerance that is not a positive number, a non-bool ``stateful``."""
        self.xy_goal_tolerance = _positive("xy_goal_tolerance", xy_goal_tolerance)
        self.yaw_goal_tolerance = _positive("yaw_goal_tolerance", yaw_goal_tolerance)
        if not isinstance(stateful, bool):
            raise ControllerError(f"stateful must be true or false, not {stateful!r}", "stateful")
        self.stateful = stateful
        self._check_xy = True

    def reset(self) -> None:
        """A new goal: the position is checked again."""
        self._check_xy = True

    def is_goal_reached(self, pose: PoseLike, goal: PoseLike, speed: tuple[float, float] = (0.0, 0.0)) -> bool:
        """Whether ``pose`` (x, y, yaw; m, m, rad) is at ``goal`` (same frame); ``speed`` (v, ω)
        is the robot's, for the checkers that want it stopped.

        Raises:
            ControllerError: a pose or goal that is not three finite numbers.
        """
        x, y, yaw = _finite(pose, 3, "pose")
        gx, gy, gyaw = _finite(goal, 3, "goal")
        if self._check_xy:
            if math.hypot(x - gx, y - gy) > self.xy_goal_tolerance:
                return False
            if self.stateful:
                self._check_xy = False
        return abs(wrap_angle(float(gyaw - yaw))) < self.yaw_goal_tolerance


class StoppedGoalChecker(SimpleGoalChecker):
    """Reached as :class:`SimpleGoalChecker`, and stopped: |v| ≤ ``trans_stopped_velocity`` (m/s) and
    |ω| ≤ ``rot_stopped_velocity`` (rad/s)."""

    def __init__(self, xy_goal_tolerance: float = 0.25, yaw_goal_tolerance: float = 0.25, stateful: bool = True,
                 trans_stopped_velocity: float = 0.25, rot_stopped_velocity: float = 0.25) -> None:
        super().__init__(xy_goal_tolerance, yaw_goal_tolerance, stateful)
        self.trans_stopped_velocity = _positive("trans_stopped_velocity", trans_stopped_velocity)
        self.rot_stopped_velocity = _positive("rot_stopped_velocity", rot_stopped_velocity)

    def is_goal_reached(self, pose: PoseLike, goal: PoseLike, speed: tuple[float, float] = (0.0, 0.0)) -> bool:
        if not super().is_goal_reached(pose, goal, speed):
            return False
        return abs(speed[0]) <= self.trans_stopped_velocity and abs(speed[1]) <= self.rot_stopped_velocity


class PositionGoalChecker:
    """Reached within ``xy_goal_tolerance`` (m) of the goal's position, whatever the heading."""

    def __init__(self, xy_goal_tolerance: float = 0.25, stateful: bool = True) -> None:
        self.xy_goal_tolerance = _positive("xy_goal_tolerance", xy_goal_tolerance)
        if not isinstance(stateful, bool):
            raise ControllerError(f"stateful must be true or false, not {stateful!r}", "stateful")
        self.stateful = stateful
        self._reached = False

    def reset(self) -> None:
        self._reached = False

    def is_goal_reached(self, pose: PoseLike, goal: PoseLike, speed: tuple[float, float] = (0.0, 0.0)) -> bool:
        x, y, _ = _finite(pose, 3, "pose")
        gx, gy, _ = _finite(goal, 3, "goal")
        if self.stateful and self._reached:
            return True
        self._reached = math.hypot(x - gx, y - gy) <= self.xy_goal_tolerance
        return self._reached


class SimpleProgressChecker:
    """Progress: the robot moves ``required_movement_radius`` (m) every ``movement_time_allowance`` (s)."""

    def __init__(self, required_movement_radius: float = 0.5, movement_time_allowance: float = 10.0) -> None:
        """Raises ControllerError: a radius or allowance that is not a positive number."""
        self.required_movement_radius = _positive("required_movement_radius", required_movement_radius)
        self.movement_time_allowance = _positive("movement_time_allowance", movement_time_allowance)
        self._baseline_xy: np.ndarray | None = None
        self._baseline_s = 0.0

    def reset(self) -> None:
        """A new goal: the next :meth:`check` sets the baseline."""
        self._baseline_xy = None

    def failure(self) -> str:
        """Why :meth:`check` failed."""
        return f"the robot moved less than {self.required_movement_radius} m in {self.movement_time_allowance} s"

    def check(self, pose_xy: PoseLike, now_s: float) -> bool:
        """False when the robot at ``pose_xy`` (x, y, m; extra elements such as yaw are ignored) has
        stayed within required_movement_radius of the baseline for longer than movement_time_allowance
        up to ``now_s`` (s, any clock that only runs forward).

        Raises:
            ControllerError: a non-finite position or time.
        """
        xy = _finite(np.asarray(pose_xy, dtype=float).reshape(-1)[:2], 2, "pose_xy")
        if not math.isfinite(now_s):
            raise ControllerError(f"now_s must be a finite time in seconds, not {now_s}", "now_s")
        if self._baseline_xy is None or math.hypot(*(xy - self._baseline_xy)) > self.required_movement_radius:
            self._baseline_xy, self._baseline_s = xy, float(now_s)
            return True
        return now_s - self._baseline_s <= self.movement_time_allowance


class PoseProgressChecker(SimpleProgressChecker):
    def failure(self) -> str:
        return (f"the robot moved less than {self.required_movement_radius} m and turned less than "
                f"{self.required_movement_angle} rad in {self.movement_time_allowance} s")

    """Progress: the robot moves ``required_movement_radius`` (m) or turns ``required_movement_angle``
    (rad) every ``movement_time_allowance`` (s)."""

    def __init__(self, required_movement_radius: float = 0.5, movement_time_allowance: float = 10.0,
                 required_movement_angle: float = 0.5) -> None:
        super().__init__(required_movement_radius, movement_time_allowance)
        self.required_movement_angle = _positive("required_movement_angle", required_movement_angle)
        self._baseline_yaw = 0.0

    def check(self, pose_xy: PoseLike, now_s: float) -> bool:
        """As :meth:`SimpleProgressChecker.check`; ``pose_xy`` must carry the yaw: (x, y, yaw)."""
        pose = _finite(pose_xy, 3, "pose")
        turned = abs(wrap_angle(float(pose[2] - self._baseline_yaw))) > self.required_movement_angle
        if self._baseline_xy is None or turned:
            self._baseline_xy, self._baseline_s, self._baseline_yaw = pose[:2], float(now_s), float(pose[2])
            return True
        before = self._baseline_xy
        ok = super().check(pose[:2], now_s)
        if self._baseline_xy is not before:  # moved far enough: the heading baseline moves too
            self._baseline_yaw = float(pose[2])
        return ok
