"""pppbot_bringup's exceptions; each message says which package, executable or verb."""
from __future__ import annotations

from pppbot_common.errors import PppbotError


class RunError(PppbotError):
    """The package or executable does not exist; the message says which."""


class VerbConflict(PppbotError):
    """Two installed packages declare the same verb."""
