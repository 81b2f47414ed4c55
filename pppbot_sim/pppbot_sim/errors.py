"""Errors of the simulator package."""
from __future__ import annotations

from pppbot_common.errors import PppbotError


class WorldError(PppbotError, ValueError):
    """A world file is missing, malformed or uses what is not supported; names file, line, element."""


class PluginError(WorldError):
    """A Gazebo plugin (DiffDrive) that cannot work as written; names the file, line and element."""


class SpawnError(PppbotError, ValueError):
    """The robot cannot be put into the world (bad URDF for simulation, bad pose)."""


class SimulationDiverged(PppbotError, RuntimeError):
    """The physics state became non-finite or absurdly large."""


class WorldGenError(PppbotError, ValueError):
    """A bad family, seed or size; the message names it and what is allowed."""
