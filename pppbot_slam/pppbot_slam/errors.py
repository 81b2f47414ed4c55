"""The SLAM core's exceptions; each message names the setting, value, file or field."""
from __future__ import annotations

from pppbot_common.errors import PppbotError


class MapperError(PppbotError, ValueError):
    """A bad mapper setting; the message names it and its value."""


class PoseGraphError(PppbotError, ValueError):
    """A bad node index, pose or covariance; the message names the value."""


class PoseGraphFileError(PppbotError, ValueError):
    """A pose-graph file that cannot be written or read; the message names the file and the field."""


class OccupancyError(PppbotError, ValueError):
    """Bad occupancy settings, scan or pose; the message names the field and its value."""


class MatcherError(PppbotError, ValueError):
    """Bad matcher settings, or nothing to match against; the message names the value."""


class SessionStartError(PppbotError, ValueError):
    """A pose graph cannot be continued as asked (match type, start pose); the message names it."""


class LocalizerError(PppbotError, ValueError):
    """Localization cannot start as asked (an empty pose graph, a bad start pose); the message names it."""
