"""What the controller server decides each control period while it follows a path
(Nav2's ``controller_server`` loop), without ROS.

Each period, in this order:

1. No transform from the path's frame to the robot: stop and wait; after
   ``max(failure_tolerance, 1 s)`` without one the goal fails (``TF_ERROR``).
2. The goal checker says the robot has arrived: the goal succeeds.
3. The progress checker says the robot has not moved ``required_movement_radius`` in
   ``movement_time_allowance``: the goal fails (``FAILED_TO_MAKE_PROGRESS``).
4. The controller's command. When it has none (a collision ahead, a bad input), the robot
   stops. The goal fails (``NO_VALID_CONTROL``) once that has lasted longer than
   ``failure_tolerance`` (-1: never, as Nav2). A command clears the failure clock.
"""
from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

from pppbot_common.se2 import PoseLike
from pppbot_nav.controller.checkers import GoalChecker, ProgressChecker
from pppbot_nav.controller.pure_pursuit import Command, Controller
from pppbot_nav.costmap.grid import Costmap
from pppbot_nav.errors import CollisionAhead, ControllerError

#: Transforms may lag this long at least before a goal fails for want of one (s).
MIN_TF_TOLERANCE_S = 1.0


class FollowEnd(enum.Enum):
    """How a followed path ends (the node maps these to nav2_msgs' FollowPath result codes)."""

    SUCCEEDED = "succeeded"
    TF_ERROR = "tf error"
    FAILED_TO_MAKE_PROGRESS = "failed to make progress"
    NO_VALID_CONTROL = "no valid control"


@dataclass(frozen=True)
class FollowStep:
    """One period's decision: a command to send, a stop (``command`` None, with ``problem``
    saying why), or the end of the goal (``end`` and ``message``)."""

    command: Command | None = None
    problem: str = ""
    end: FollowEnd | None = None
    message: str = ""


class Follower:
    """The per-period follow policy for one path; keeps the failure clock between periods."""

    def __init__(self, controller: Controller, goal_checker: GoalChecker,
                 progress_checker: ProgressChecker, failure_tolerance_s: float) -> None:
        self.controller = controller
        self.goal_checker = goal_checker
        self.progress_checker = progress_checker
        self.failure_tolerance_s = failure_tolerance_s
        self.failing_since_s: float | None = None

    def _failing_for(self, now_s: float) -> float:
        if self.failing_since_s is None:
            self.failing_since_s = now_s
        return now_s - self.failing_since_s

    def step(self, now_s: float, pose: PoseLike | None,  # noqa: PLR0911 (one return per way a period ends)
             goal: tuple[float, float, float], path3: np.ndarray,
             speed: tuple[float, float], costmap: Costmap | None, period_s: float,
             pose_in_costmap: PoseLike | None = None, no_pose_reason: str = "") -> FollowStep:
        """This period's decision. ``pose`` is the robot in the path's frame, None when there is
        no transform (``no_pose_reason`` says why); ``pose_in_costmap`` the robot in the
        costmap's frame."""
        if pose is None:
            if self._failing_for(now_s) > max(self.failure_tolerance_s, MIN_TF_TOLERANCE_S):
                return FollowStep(end=FollowEnd.TF_ERROR, message=f"no transform for the path: {no_pose_reason}")
            return FollowStep(problem=f"no transform for the path: {no_pose_reason}")
        if self.goal_checker.is_goal_reached(pose, goal, speed):
            return FollowStep(end=FollowEnd.SUCCEEDED)
        if not self.progress_checker.check(np.asarray(pose, dtype=float), now_s):
            return FollowStep(end=FollowEnd.FAILED_TO_MAKE_PROGRESS, message=self.progress_checker.failure())
        try:
            command = self.controller.compute(pose, speed, path3, costmap, period_s, costmap_pose=pose_in_costmap)
        except (CollisionAhead, ControllerError) as exc:
            if self.failure_tolerance_s >= 0 and self._failing_for(now_s) > self.failure_tolerance_s:
                return FollowStep(end=FollowEnd.NO_VALID_CONTROL, message=str(exc))
            return FollowStep(problem=f"no command this period: {exc}")
        self.failing_since_s = None
        return FollowStep(command=command)
