"""Exceptions shared by pppbot packages."""
from __future__ import annotations

from typing import Any


class PppbotError(Exception):
    """Base of every pppbot error; its message names the bad value."""


class MessageTypeError(PppbotError, LookupError):
    """A ROS interface type name is malformed or not installed."""


class TimeoutExpired(PppbotError, TimeoutError):
    """A condition waited for did not happen within its timeout."""


class ParameterError(PppbotError, ValueError):
    """A parameter value is not allowed; the message names parameter, value and rule."""

    def __init__(self, name: str, value: Any, allowed: str) -> None:
        super().__init__(f"parameter '{name}' = {value!r}: {allowed}")
        self.name, self.value, self.allowed = name, value, allowed


class ArgumentError(PppbotError, ValueError):
    """A malformed, unknown or invalid ``name:=value`` argument; the message says which."""


class TransformError(PppbotError, LookupError):
    """No transform between two frames at a time; the message names frames and times."""


class MapFileError(PppbotError, ValueError):
    """A map file is missing, malformed or unreadable; the message names file and key."""


class TemplateError(PppbotError, ValueError):
    """A field a template cannot patch (unknown, a string, or a sequence it would have to resize)."""


class ParameterFileError(PppbotError, ValueError):
    """A ROS 2 parameter file is unreadable, not YAML, or not of the params-file shape; the message
    names the file, where in it (line and column when known) and what is allowed."""

    def __init__(self, path: Any, what: str, line: int | None = None, column: int | None = None) -> None:
        where = f"line {line}, column {column}: " if line is not None and column is not None else ""
        super().__init__(f"{path}: {where}{what}")
        self.path, self.what, self.line, self.column = path, what, line, column
