"""pppbot_lockstep's errors."""
from __future__ import annotations

from pppbot_common.errors import PppbotError


class LockstepError(PppbotError):
    """A lockstep protocol error; the message names the participant and what it did."""


class LockstepTimeout(LockstepError):
    """A participant did not answer in time (the message names it, the step and the sim time)."""
