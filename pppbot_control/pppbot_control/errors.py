"""pppbot_control's exceptions."""
from __future__ import annotations

from pppbot_common.errors import PppbotError


class MuxConfigError(PppbotError, ValueError):
    """A malformed topics/locks entry; names the entry and the field."""
