"""Declare a node's parameters from its parameter dataclass, and keep it valid at run time."""
from __future__ import annotations

from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter

from pppbot_common.params import (
    ParameterError,
    description,
    field_default,
    from_values,
    parameter_fields,
    ros_name,
    updated,
)

T = TypeVar("T")


def declare_parameters(node: Node, cls: type[T], prefix: str = "") -> T:
    """Declare every field of ``cls`` on ``node`` and return the validated values.

    ``prefix`` goes before each name: a plugin's parameters sit under its name (``FollowPath.``).
    Types are checked by ``cls`` (so ``20`` is accepted for a float), not by rclpy.

    Raises:
        ParameterError: a value the dataclass rejects; the message names it (with its prefix).
    """
    values = {}
    for field in parameter_fields(cls):
        default = field_default(field)
        name = ros_name(field)
        descriptor = ParameterDescriptor(description=description(cls, field), dynamic_typing=True)
        values[name] = node.declare_parameter(prefix + name, list(default) if isinstance(default, tuple) else default,
                                              descriptor).value
    try:
        return from_values(cls, values)
    except ParameterError as exc:
        if not prefix:
            raise
        raise ParameterError(prefix + exc.name, exc.value, exc.allowed) from exc


@dataclass(frozen=True)
class LiveParameters:
    """A group of a node's parameters (one dataclass, declared under ``prefix``) for run-time sets:
    ``live`` names those that may change while the node runs (None: all); ``apply`` takes the new,
    validated dataclass and must keep the node's state."""

    prefix: str
    current: Callable[[], Any]
    apply: Callable[[Any], None]
    live: Collection[str] | None = None
    why_not: str = "it is read once, at start-up (as in Nav2); restart the node to change it"
    #: The others are refused only while this says so (a lifecycle node that reads them at configure).
    fixed_while: Callable[[], bool] | None = None


def serve_live_parameters(node: Node, groups: Sequence[LiveParameters]) -> None:
    """Validate run-time ``ros2 param set`` requests against ``groups``; apply each changed group.

    A request is refused whole, with the reason (``SetParametersResult``), when one of its
    parameters may not change at run time or its group rejects the new value; the running values
    then stay as they were. Parameters of no group (``use_sim_time``) are left to rclpy.
    """
    def split(params: list[Parameter]) -> dict[int, dict[str, Any]]:
        by_group: dict[int, dict[str, Any]] = {}
        for p in params:
            for i, group in enumerate(groups):
                if not p.name.startswith(group.prefix):
                    continue
                name = p.name[len(group.prefix):]
                if name in {ros_name(f) for f in parameter_fields(type(group.current()))}:
                    by_group.setdefault(i, {})[name] = p.value
                    break
        return by_group

    def validate(params: list[Parameter]) -> SetParametersResult:
        for i, values in split(params).items():
            group = groups[i]
            fixed = sorted(set(values) - set(group.live)) if group.live is not None else []
            if fixed and (group.fixed_while is None or group.fixed_while()):
                return SetParametersResult(successful=False, reason=f"'{group.prefix}{fixed[0]}' cannot change "
                                                                    f"while the node runs: {group.why_not}")
            try:
                updated(group.current(), values)
            except ParameterError as exc:
                return SetParametersResult(successful=False, reason=f"{group.prefix}{exc}" if group.prefix
                                           else str(exc))
        return SetParametersResult(successful=True)

    def after_set(params: list[Parameter]) -> None:
        for i, values in split(params).items():
            group = groups[i]
            if any(getattr(group.current(), f.name) != v for f in parameter_fields(type(group.current()))
                   for name, v in values.items() if ros_name(f) == name):
                group.apply(updated(group.current(), values))

    node.add_on_set_parameters_callback(validate)
    node.add_post_set_parameters_callback(after_set)


def fixed_parameters(node: Node, current: Callable[[], Any], live: Collection[str] = (),
                     apply: Callable[[Any], None] | None = None) -> None:
    """Refuse run-time sets of a node's parameters (its dataclass ``current()``) but ``live`` ones,
    which ``apply`` takes (default: nothing to do, the node reads them from ``current()``)."""
    serve_live_parameters(node, [LiveParameters("", current, apply or (lambda _: None), live)])


def refuse_sets(node: Node, why: str, allowed: Callable[[str], bool] = lambda name: name == "use_sim_time") -> None:
    """Refuse every run-time set of ``node``'s parameters but ``allowed`` ones, saying ``why`` (a node
    that reads its parameters once and has no dataclass of them)."""
    def validate(params: list[Parameter]) -> SetParametersResult:
        fixed = [p.name for p in params if not allowed(p.name)]
        if fixed:
            return SetParametersResult(successful=False,
                                       reason=f"'{fixed[0]}' cannot change while the node runs: {why}")
        return SetParametersResult(successful=True)

    node.add_on_set_parameters_callback(validate)


def on_valid_update(node: Node, current: Callable[[], T], apply: Callable[[T], None]) -> None:
    """Validate runtime ``ros2 param set`` updates; apply the new dataclass when valid.

    An invalid update is refused with the reason (``SetParametersResult``), and the
    running values stay as they were.
    """
    serve_live_parameters(node, [LiveParameters("", current, apply)])
