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
