"""``name:=value`` command-line arguments, as ``ros2 launch`` takes them.

Each tool declares its arguments (name, default, description, optional choices);
values are text, converted by the declared default's type (bool, int, float, str).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from pppbot_common.errors import ArgumentError

_TRUE = {"true", "1", "yes", "on"}
_FALSE = {"false", "0", "no", "off"}


@dataclass(frozen=True)
class Argument:
    name: str
    default: Any
    description: str
    choices: tuple[str, ...] = ()

    def convert(self, text: str) -> Any:
        """``text`` as this argument's type.

        Raises:
            ArgumentError: not of the type, or not one of the choices.
        """
        if self.choices and text not in self.choices:
            raise ArgumentError(f"{self.name}:={text}: allowed values are {', '.join(self.choices)}")
        kind = type(self.default)
        if kind is bool:
            low = text.lower()
            if low in _TRUE | _FALSE:
                return low in _TRUE
            raise ArgumentError(f"{self.name}:={text}: must be true or false")
        if kind in (int, float):
            try:
                return kind(text)
            except ValueError:
                what = "an integer" if kind is int else "a number"
                raise ArgumentError(f"{self.name}:={text}: must be {what}") from None
        return text


def parse_assignments(argv: Sequence[str], arguments: Sequence[Argument]) -> dict[str, Any]:
    """Values of every declared argument (defaults for those not given).

    Raises:
        ArgumentError: an item not of the form ``name:=value``, an unknown name
            (the known ones are listed), a repeated name, or a bad value.
    """
    declared = {a.name: a for a in arguments}
    values = {a.name: a.default for a in arguments}
    given: set[str] = set()
    for item in argv:
        name, sep, text = item.partition(":=")
        if not sep or not name:
            raise ArgumentError(f"'{item}' is not of the form name:=value")
        if name not in declared:
            raise ArgumentError(f"unknown argument '{name}'; known: {', '.join(declared)}")
        if name in given:
            raise ArgumentError(f"argument '{name}' given twice")
        given.add(name)
        values[name] = declared[name].convert(text)
    return values


def describe(arguments: Sequence[Argument]) -> str:
    """The ``--show-args`` text: each argument with its description, default and choices."""
    lines = ["Arguments (pass arguments as '<name>:=<value>'):", ""]
    for a in arguments:
        default = str(a.default).lower() if isinstance(a.default, bool) else a.default
        lines.append(f"    '{a.name}':")
        lines.append(f"        {a.description}")
        if a.choices:
            lines.append(f"        Choices: {', '.join(a.choices)}")
        lines.append(f"        (default: '{default}')")
        lines.append("")
    return "\n".join(lines)
