"""Nav2's plugins by type name: a name's ``<name>.plugin`` picks the implementation, and its
parameters are declared under ``<name>.``, as pluginlib and Nav2's servers do.

The types are the installed entry points of the kind's group (:mod:`pppbot_nav.plugins`), matched
in either spelling pluginlib accepts (``nav2_navfn_planner/NavfnPlanner`` or
``nav2_navfn_planner::NavfnPlanner``). A type no installed package exports stops the node with a
message naming the group and what is installed in it.
"""
from __future__ import annotations

from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass
from functools import partial
from typing import Any

from rclpy.node import Node

from pppbot_common.params import ParameterError
from pppbot_common.ros.params import LiveParameters, declare_parameters
from pppbot_nav.plugins import AnyOf, PluginError, PluginGroup, canonical


@dataclass(frozen=True)
class Plugin:
    """One loaded plugin: its name (the parameter prefix), its type as given and its parameters."""

    name: str
    type_name: str
    params: Any


def plugin_type(node: Node, name: str, types: Mapping[str, Any], default_type: str | None) -> str:
    """Declare ``<name>.plugin`` and return the known type it names (as spelled in ``types``).

    Raises:
        ParameterError: no type given and no default, or a type no installed package exports.
    """
    given = node.declare_parameter(f"{name}.plugin", default_type or "").value
    known = {canonical(t): t for t in types}
    if not isinstance(given, str) or not given:
        raise ParameterError(f"{name}.plugin", given, "must name the plugin's type, one of: " + ", ".join(types))
    found = known.get(canonical(given))
    if found is None:
        if isinstance(types, (PluginGroup, AnyOf)):
            raise ParameterError(f"{name}.plugin", given, "names no installed plugin: " + types.unknown(given))
        raise ParameterError(f"{name}.plugin", given, "is not a plugin pppbot implements; known: " + ", ".join(types))
    return found


def plugin_class(name: str, types: Mapping[str, type], type_name: str) -> type:
    """The parameters class of ``type_name``.

    Raises:
        ParameterError: the entry point does not load (its import failed), named with ``<name>.plugin``.
    """
    try:
        return types[type_name]
    except PluginError as exc:
        raise ParameterError(f"{name}.plugin", type_name, str(exc)) from exc


def load_plugin(node: Node, name: str, types: Mapping[str, type], default_type: str | None = None) -> Plugin:
    """``<name>.plugin`` and the parameters of that type under ``<name>.``, validated.

    Raises:
        ParameterError: an unknown type or a bad parameter (named with its prefix).
    """
    type_name = plugin_type(node, name, types, default_type)
    return Plugin(name, type_name, declare_parameters(node, plugin_class(name, types, type_name), prefix=f"{name}."))


def live_fields(params: Any) -> Collection[str] | None:
    """What of a plugin's parameters may change while it runs: its class's ``LIVE_PARAMETERS``
    (None: everything; absent: nothing)."""
    return getattr(type(params), "LIVE_PARAMETERS", ())


def _params_of(plugins: Mapping[str, Plugin], name: str) -> Any:
    return plugins[name].params


def live_plugin_parameters(plugins: Mapping[str, Plugin], apply: Callable[[str, Any], None]) -> list[LiveParameters]:
    """Each plugin's parameters as a live group under ``<name>.``: ``apply(name, new)`` takes a valid
    set; what may change is :func:`live_fields`."""
    return [LiveParameters(f"{name}.", partial(_params_of, plugins, name), partial(apply, name),
                           live_fields(plugin.params))
            for name, plugin in plugins.items()]
