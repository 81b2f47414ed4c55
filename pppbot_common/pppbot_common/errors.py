"""Exceptions shared by pppbot packages."""
from __future__ import annotations


class PppbotError(Exception):
    """Base of every pppbot error; its message names the bad value."""


class MessageTypeError(PppbotError, LookupError):
    """A ROS interface type name is malformed or not installed."""


class TimeoutExpired(PppbotError, TimeoutError):
    """A condition waited for did not happen within its timeout."""
