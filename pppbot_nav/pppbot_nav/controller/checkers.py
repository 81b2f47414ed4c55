"""Nav2's controller-server checkers: has the robot reached its goal, is it still making progress.

* :class:`SimpleGoalChecker` (``nav2_controller::SimpleGoalChecker``): reached when within
  ``xy_goal_tolerance`` of the goal's position and ``yaw_goal_tolerance`` of its heading.
  When stateful, once the position has been inside its tolerance it counts as inside until
  :meth:`~SimpleGoalChecker.reset` (a new goal), so the robot may drift while it turns.
* :class:`SimpleProgressChecker` (``nav2_controller::SimpleProgressChecker``): failing when
  the robot has not moved ``required_movement_radius`` from a baseline position within
  ``movement_time_allowance``; the baseline moves to the robot whenever it has.
"""
from __future__ import annotations

import math

import numpy as np

from pppbot_common.se2 import PoseLike, wrap_angle
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

    def is_goal_reached(self, pose: PoseLike, goal: PoseLike) -> bool:
        """Whether ``pose`` (x, y, yaw; m, m, rad) is at ``goal`` (same frame).

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
