"""Nav2's plugins by type name: a name's ``<name>.plugin`` picks the implementation, and its
parameters are declared under ``<name>.``, as pluginlib and Nav2's servers do.

Type names are matched in either spelling pluginlib accepts (``nav2_navfn_planner/NavfnPlanner``
or ``nav2_navfn_planner::NavfnPlanner``). A type pppbot does not implement stops the node with a
message listing the ones it does.
"""
from __future__ import annotations

from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass
from functools import partial
from typing import Any

from rclpy.node import Node

from pppbot_common.params import ParameterError
from pppbot_common.ros.params import LiveParameters, declare_parameters


def canonical(type_name: str) -> str:
    """A plugin type in one spelling: ``pkg::Class`` and ``pkg/Class`` are the same type."""
    return type_name.strip().replace("::", "/")


@dataclass(frozen=True)
class Plugin:
    """One loaded plugin: its name (the parameter prefix), its type as given and its parameters."""

    name: str
    type_name: str
    params: Any


def plugin_type(node: Node, name: str, types: Mapping[str, Any], default_type: str | None) -> str:
    """Declare ``<name>.plugin`` and return the known type it names (as spelled in ``types``).

    Raises:
        ParameterError: no type given and no default, or a type pppbot does not implement.
    """
    given = node.declare_parameter(f"{name}.plugin", default_type or "").value
    known = {canonical(t): t for t in types}
    if not isinstance(given, str) or not given:
        raise ParameterError(f"{name}.plugin", given, "must name the plugin's type, one of: " + ", ".join(types))
    found = known.get(canonical(given))
    if found is None:
        raise ParameterError(f"{name}.plugin", given, "is not a plugin pppbot implements; known: " + ", ".join(types))
    return found


def load_plugin(node: Node, name: str, types: Mapping[str, type], default_type: str | None = None) -> Plugin:
    """``<name>.plugin`` and the parameters of that type under ``<name>.``, validated.

    Raises:
        ParameterError: an unknown type or a bad parameter (named with its prefix).
    """
    type_name = plugin_type(node, name, types, default_type)
    return Plugin(name, type_name, declare_parameters(node, types[type_name], prefix=f"{name}."))


def _params_of(plugins: Mapping[str, Plugin], name: str) -> Any:
    return plugins[name].params


def live_plugin_parameters(plugins: Mapping[str, Plugin], apply: Callable[[str, Any], None],
                           live: Mapping[str, Collection[str] | None]) -> list[LiveParameters]:
    """Each plugin's parameters as a live group under ``<name>.``: ``apply(name, new)`` takes a valid
    set; ``live`` says by type what may change (None: everything; a type it lacks: nothing)."""
    return [LiveParameters(f"{name}.", partial(_params_of, plugins, name), partial(apply, name),
                           live.get(plugin.type_name, ()))
            for name, plugin in plugins.items()]
