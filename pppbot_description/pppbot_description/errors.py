"""Errors of the robot description package."""
from __future__ import annotations

from pppbot_common.errors import PppbotError


class DescriptionError(PppbotError, ValueError):
    """A robot description (xacro or URDF) is malformed; the message names file, line and element."""
