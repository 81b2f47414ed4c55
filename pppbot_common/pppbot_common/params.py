"""Node parameters as frozen dataclasses with a pure ``validate()``.

Each field is one ROS parameter. ``param()`` attaches its ROS name (dotted names
such as ``linear.x.max_velocity`` are allowed) and a description. Validation raises
:class:`ParameterError` naming the parameter, its value and what is allowed; a
node stops at start on it and rejects runtime updates with it.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator
from typing import Any, TypeVar

from pppbot_common.errors import ParameterError

T = TypeVar("T")


def param(default: Any, description: str, ros_name: str | None = None) -> Any:
    """A dataclass field that is a ROS parameter."""
    metadata = {"description": description, "ros_name": ros_name}
    if isinstance(default, (list, dict)):
        return dataclasses.field(default_factory=lambda: type(default)(default), metadata=metadata)
    return dataclasses.field(default=default, metadata=metadata)


def ros_name(field: dataclasses.Field[Any]) -> str:
    return field.metadata.get("ros_name") or field.name


def parameter_fields(cls: type) -> Iterator[dataclasses.Field[Any]]:
    """The fields of ``cls`` that are ROS parameters: those made by :func:`param`; in a class that
    sets ``PARAMETERS_OF`` (a plugin's parameters that are its settings dataclass's fields, typed
    where they are declared), every field but the names in ``NOT_PARAMETERS``."""
    whole = getattr(cls, "PARAMETERS_OF", None) is not None
    skip: frozenset[str] = getattr(cls, "NOT_PARAMETERS", frozenset())
    return (f for f in dataclasses.fields(cls)
            if "description" in f.metadata or (whole and f.init and f.name not in skip))


def description(cls: type, field: dataclasses.Field[Any]) -> str:
    """A parameter's description: its own, else ``"<PARAMETERS_OF>: <name>"``."""
    return field.metadata.get("description") or f"{cls.PARAMETERS_OF}: {field.name}"  # type: ignore[attr-defined]


def _field_by_ros_name(cls: type, name: str) -> dataclasses.Field[Any] | None:
    return next((f for f in parameter_fields(cls) if ros_name(f) == name), None)


def field_default(field: dataclasses.Field[Any]) -> Any:
    if field.default is not dataclasses.MISSING:
        return field.default
    if field.default_factory is not dataclasses.MISSING:
        return field.default_factory()
    raise TypeError(f"parameter field '{field.name}' has no default")


def coerce(field: dataclasses.Field[Any], value: Any) -> Any:
    """``value`` as the field's type (ints accepted for floats, as YAML and the CLI give them).

    Raises:
        ParameterError: the value has another type.
    """
    default = field_default(field)
    name = ros_name(field)
    if isinstance(default, bool):
        if isinstance(value, bool):
            return value
        raise ParameterError(name, value, "must be true or false")
    if isinstance(default, float):
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return float(value)
        raise ParameterError(name, value, "must be a number")
    if isinstance(default, int):
        if isinstance(value, int) and not isinstance(value, bool):
            return value
        raise ParameterError(name, value, "must be an integer")
    if isinstance(default, str):
        if isinstance(value, str):
            return value
        raise ParameterError(name, value, "must be a string")
    if isinstance(default, (list, tuple)):
        if isinstance(value, (list, tuple)):
            return type(default)(value)
        raise ParameterError(name, value, "must be a list")
    return value


def from_values(cls: type[T], values: dict[str, Any]) -> T:
    """Build and validate ``cls`` from ROS-named values (missing ones keep defaults).

    Raises:
        ParameterError: an unknown name, a wrong type, or what ``validate()`` rejects.
    """
    kwargs = {}
    for name, value in values.items():
        field = _field_by_ros_name(cls, name)
        if field is None:
            raise ParameterError(name, value, f"unknown parameter of {cls.__name__}")
        kwargs[field.name] = coerce(field, value)
    obj = cls(**kwargs)
    validate = getattr(obj, "validate", None)
    if validate is not None:
        validate()
    return obj


def updated(current: T, values: dict[str, Any]) -> T:
    """``current`` with some ROS-named values changed, validated."""
    merged = {ros_name(f): getattr(current, f.name) for f in parameter_fields(type(current))}
    merged.update(values)
    return from_values(type(current), merged)


def check_finite_range(name: str, value: float, low: float = -math.inf, high: float = math.inf,
                       low_open: bool = False) -> None:
    """Raise ParameterError unless ``low (<|<=) value <= high`` and finite."""
    below = value <= low if low_open else value < low
    if not math.isfinite(value) or below or value > high:
        bracket = "(" if low_open else "["
        raise ParameterError(name, value, f"must be a finite number in {bracket}{low}, {high}]")
