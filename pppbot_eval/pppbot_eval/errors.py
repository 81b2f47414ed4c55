"""Errors of the evaluation cores; every message names the bad value, file or field."""
from __future__ import annotations

from pppbot_common.errors import PppbotError


class EvalError(PppbotError, ValueError):
    """Base of the evaluation's errors."""


class RouteError(EvalError):
    """A routes file is missing or malformed, a route name is unknown, or a route cannot be driven."""


class PoseSeriesError(EvalError):
    """A pose series is malformed or two series can't be compared; the message names the value."""


class NoOverlapError(PoseSeriesError):
    """No estimate sample lies within the truth's time span; the message gives both spans."""


class MapQualityError(EvalError):
    """Two grids can't be compared as asked; the message names the bad value."""


class NavigationMetricError(EvalError):
    """A bad footprint, tolerance or speed; the message names the value."""


class PathError(EvalError):
    """No path for the robot; the message gives the coordinates."""


class StartBlocked(PathError):
    """The start is not in free space and no free cell lies within twice the robot radius."""


class GoalBlocked(PathError):
    """The goal is outside the grid or not in free space."""


class NoPath(PathError):
    """Start and goal are in free space that is not connected."""


class GoalSamplingError(EvalError):
    """No navigation goals can be drawn as asked; the message names the value or the place."""


class BatchSpecError(EvalError):
    """A batch spec or batch flag that cannot be run: the message names the file, the entry and the key."""


class RayError(EvalError):
    """Ray is missing, or its cluster cannot be reached."""
