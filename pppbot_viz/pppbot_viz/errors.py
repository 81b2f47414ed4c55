"""The live view's one exception."""
from __future__ import annotations

from pppbot_common.errors import PppbotError


class VizError(PppbotError):
    """The live view or the Foxglove bridge can't start or was given a bad value; the message says
    which and what is allowed."""
