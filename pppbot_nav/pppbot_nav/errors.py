"""Errors of the navigation package."""
from __future__ import annotations

from pppbot_common.errors import MapFileError, PppbotError


class MapSaverError(PppbotError, ValueError):
    """A map save request cannot be carried out as asked (bad mode, format or thresholds);
    the message names the value and what is allowed."""


class AmclError(PppbotError, ValueError):
    """AMCL cannot do what was asked (bad settings, an empty map, a malformed scan or pose);
    the message names the value and what is allowed, and ``parameter`` the setting at fault, if one is."""

    def __init__(self, message: str, parameter: str | None = None) -> None:
        super().__init__(message)
        self.parameter = parameter


class OffTheMap(AmclError):
    """An initial pose the map does not hold: its mean outside the map, or a spread wider than it."""


class CostmapError(PppbotError, ValueError):
    """A costmap or layer cannot be built or updated as asked; the message names the value."""


class ControllerError(PppbotError, ValueError):
    """The path-following controller or a checker cannot do what was asked (bad settings, an empty
    or non-finite path, a non-finite pose or speed); the message names the value and what is allowed,
    and ``parameter`` the setting at fault, if one is."""

    def __init__(self, message: str, parameter: str | None = None) -> None:
        super().__init__(message)
        self.parameter = parameter


class CollisionAhead(PppbotError, RuntimeError):
    """The command would hit an obstacle within ``max_allowed_time_to_collision_up_to_carrot``; the
    message says where (the first pose whose cell is inscribed or lethal) and how soon."""


class MapLoadError(MapFileError):
    """A map that cannot be served, with the LoadMap result code that says why."""

    def __init__(self, message: str, result: int) -> None:
        super().__init__(message)
        self.result = result


class LifecycleError(PppbotError, ValueError):
    """A lifecycle manager cannot do what was asked (bad node_names, an unknown command); the
    message names the value and what is allowed."""


class VelocitySmootherError(PppbotError, ValueError):
    """The velocity smoother's limits are not usable (a vector not of three finite numbers, an
    acceleration below zero, a deceleration above it, ...); the message names the value and what is
    allowed, and ``parameter`` the setting at fault."""

    def __init__(self, message: str, parameter: str | None = None) -> None:
        super().__init__(message)
        self.parameter = parameter


class CollisionMonitorError(PppbotError, ValueError):
    """A collision monitor zone or source cannot be built as asked (malformed points, an unknown
    action or shape, a ratio out of range); the message names the value and what is allowed, and
    ``parameter`` the setting at fault (relative to the zone: ``points``, ``action_type``)."""

    def __init__(self, message: str, parameter: str | None = None) -> None:
        super().__init__(message)
        self.parameter = parameter


class WaypointError(PppbotError, ValueError):
    """A follow_waypoints request or a waypoint task executor cannot be carried out as asked (no
    poses, a goal_index out of range, an unknown plugin type); the message names the value and
    what is allowed."""


class SmootherError(PppbotError, ValueError):
    """A path cannot be smoothed as asked (an unknown smoother or plugin type, an empty or non-finite
    path); the message names the value and what is allowed."""


class SmootherTimedOut(PppbotError, RuntimeError):
    """Smoothing took longer than the time it was given (Nav2's SmootherTimedOut)."""


class BehaviorTreeError(PppbotError, ValueError):
    """A behaviour tree cannot be loaded or run as written (bad XML, an unknown node, a missing or
    bad port); the message names the file and line, the node and what is allowed."""
