"""The bag tools' one exception."""
from __future__ import annotations

from pppbot_common.errors import PppbotError


class BagError(PppbotError):
    """A bag can't be written, read or recovered; the message names the file or value."""
