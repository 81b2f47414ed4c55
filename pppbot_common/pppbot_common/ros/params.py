"""Declare a node's parameters from its parameter dataclass, and keep it valid at run time."""
from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter

from pppbot_common.params import (
    ParameterError,
    field_default,
    from_values,
    parameter_fields,
    ros_name,
    updated,
)

T = TypeVar("T")


def declare_parameters(node: Node, cls: type[T]) -> T:
    """Declare every field of ``cls`` on ``node`` and return the validated values.

    Types are checked by ``cls`` (so ``20`` is accepted for a float), not by rclpy.

    Raises:
        ParameterError: a value the dataclass rejects; the message names it.
    """
    values = {}
    for field in parameter_fields(cls):
        default = field_default(field)
        name = ros_name(field)
        descriptor = ParameterDescriptor(description=field.metadata["description"], dynamic_typing=True)
        values[name] = node.declare_parameter(name, default, descriptor).value
    return from_values(cls, values)


def on_valid_update(node: Node, current: Callable[[], T], apply: Callable[[T], None]) -> None:
    """Validate runtime ``ros2 param set`` updates; apply the new dataclass when valid.

    An invalid update is refused with the reason (``SetParametersResult``), and the
    running values stay as they were.
    """
    names = {ros_name(f) for f in parameter_fields(type(current()))}

    def ours(params: list[Parameter]) -> dict[str, Any]:
        return {p.name: p.value for p in params if p.name in names}

    def validate(params: list[Parameter]) -> SetParametersResult:
        try:
            updated(current(), ours(params))
        except ParameterError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def after_set(params: list[Parameter]) -> None:
        values = ours(params)
        if values:
            apply(updated(current(), values))

    node.add_on_set_parameters_callback(validate)
    node.add_post_set_parameters_callback(after_set)
