"""The planner's typed failures: each becomes a ``ComputePathToPose`` result error code."""
from __future__ import annotations

from pppbot_common.errors import PppbotError


class PlannerError(PppbotError, RuntimeError):
    """A path cannot be planned; the message says where and why."""


class StartOutsideMap(PlannerError):
    """The start is off the costmap."""


class GoalOutsideMap(PlannerError):
    """The goal is off the costmap."""


class StartOccupied(PlannerError):
    """The start is on an obstacle (not merely inside its inflation)."""


class GoalOccupied(PlannerError):
    """The goal and every cell within the goal tolerance are obstacles or inscribed."""


class NoValidPath(PlannerError):
    """No collision-free path joins the start and the goal."""


class PlannerTimedOut(PlannerError):
    """The search took longer than ``max_planning_time``."""
