"""Nav2's plugins found by type name in Python entry-point groups, pluginlib's role.

A Nav2 user names a plugin in YAML (``GridBased.plugin: "nav2_navfn_planner::NavfnPlanner"``)
and pluginlib finds the library that exports that type. Here each kind of plugin is an
entry-point group, and a package exports a type by naming it there, in its ``pyproject.toml``::

    [project.entry-points."pppbot_nav.planners"]
    "my_planners::StraightLine" = "my_planners.straight:StraightLineParameters"

pppbot's own plugins are registered the same way (``pppbot_nav/setup.py``), so an installed
package's type and a built-in one are found alike. Names match in either spelling pluginlib
accepts (``pkg::Class`` or ``pkg/Class``). What an entry point must be, per kind, is the
Protocol in that kind's ``interface`` module (:data:`GROUPS`).

This module is ROS-free: the servers declare the chosen type's parameters themselves
(:mod:`pppbot_nav.ros.plugins`).
"""
from __future__ import annotations

from collections.abc import Iterator, Mapping
from importlib.metadata import EntryPoint, entry_points
from typing import Any

#: Each kind of plugin, its entry-point group and the Protocol its entries follow.
GROUPS: dict[str, tuple[str, str]] = {
    "planner": ("pppbot_nav.planners", "pppbot_nav.planner.interface.PlannerPlugin"),
    "controller": ("pppbot_nav.controllers", "pppbot_nav.controller.interface.ControllerPlugin"),
    "goal checker": ("pppbot_nav.goal_checkers", "pppbot_nav.controller.interface.GoalCheckerPlugin"),
    "progress checker": ("pppbot_nav.progress_checkers", "pppbot_nav.controller.interface.ProgressCheckerPlugin"),
    "DWB critic": ("pppbot_nav.dwb_critics", "pppbot_nav.controller.interface.CriticPlugin"),
    "costmap layer": ("pppbot_nav.costmap_layers", "pppbot_nav.costmap.interface.LayerPlugin"),
    "costmap filter": ("pppbot_nav.costmap_filters", "pppbot_nav.costmap.interface.FilterPlugin"),
    "smoother": ("pppbot_nav.smoothers", "pppbot_nav.planner.smoother_interface.SmootherPlugin"),
    "behavior": ("pppbot_nav.behaviors", "pppbot_nav.ros.behavior_interface.BehaviorPlugin"),
    "behavior tree node library": ("pppbot_nav.bt_plugins", "pppbot_nav.bt.tree.NodeLibrary"),
}


class PluginError(LookupError):
    """A type no installed package exports, or an entry point that does not load."""


def canonical(type_name: str) -> str:
    """A plugin type in one spelling: ``pkg::Class`` and ``pkg/Class`` are the same type."""
    return type_name.strip().replace("::", "/")


class PluginGroup(Mapping[str, Any]):
    """The types installed in one entry-point group, by name, each loaded on first use.

    Looking a name up accepts either spelling; iterating gives the names as registered.
    """

    def __init__(self, kind: str) -> None:
        if kind not in GROUPS:
            raise ValueError(f"unknown plugin kind {kind!r}; kinds: {', '.join(GROUPS)}")
        self.kind = kind
        self.group = GROUPS[kind][0]
        self._entries: dict[str, EntryPoint] | None = None
        self._loaded: dict[str, Any] = {}

    def entries(self) -> dict[str, EntryPoint]:
        """The group's entry points by canonical name (read from the installed packages once)."""
        if self._entries is None:
            self._entries = {canonical(ep.name): ep for ep in entry_points(group=self.group)}
        return self._entries

    def name_of(self, type_name: str) -> str | None:
        """The registered spelling of ``type_name``, or None when no package exports it."""
        entry = self.entries().get(canonical(type_name))
        return None if entry is None else entry.name

    def unknown(self, type_name: str) -> str:
        """Why ``type_name`` cannot be loaded: the group and what is installed in it."""
        installed = ", ".join(sorted(ep.name for ep in self.entries().values())) or "nothing"
        return (f"{type_name!r} is not a {self.kind} any installed package exports (entry-point group "
                f"'{self.group}'; installed: {installed})")

    def __getitem__(self, type_name: str) -> Any:
        key = canonical(type_name)
        if key not in self._loaded:
            entry = self.entries().get(key)
            if entry is None:
                raise PluginError(self.unknown(type_name))
            try:
                self._loaded[key] = entry.load()
            except Exception as exc:  # noqa: BLE001 (a plugin's import may fail any way; name it)
                raise PluginError(f"{self.kind} {entry.name!r} (entry point '{entry.value}' in group "
                                  f"'{self.group}') does not load: {type(exc).__name__}: {exc}") from exc
        return self._loaded[key]

    def __contains__(self, type_name: object) -> bool:
        return isinstance(type_name, str) and canonical(type_name) in self.entries()

    def __iter__(self) -> Iterator[str]:
        return iter(sorted(ep.name for ep in self.entries().values()))

    def __len__(self) -> int:
        return len(self.entries())


class AnyOf(Mapping[str, Any]):
    """Several groups looked up as one, the first holding a name winning (a costmap's ``filters``
    take filters and layers, as Nav2's: an inflation layer after a keepout filter)."""

    def __init__(self, *groups: PluginGroup) -> None:
        self.groups = groups

    def unknown(self, type_name: str) -> str:
        return "; ".join(group.unknown(type_name) for group in self.groups)

    def __getitem__(self, type_name: str) -> Any:
        for group in self.groups:
            if type_name in group:
                return group[type_name]
        raise PluginError(self.unknown(type_name))

    def __contains__(self, type_name: object) -> bool:
        return any(type_name in group for group in self.groups)

    def __iter__(self) -> Iterator[str]:
        return iter([name for group in self.groups for name in group])

    def __len__(self) -> int:
        return sum(len(group) for group in self.groups)


_groups: dict[str, PluginGroup] = {}


def plugins(kind: str) -> PluginGroup:
    """The installed plugins of ``kind`` (a key of :data:`GROUPS`), one shared group per kind."""
    if kind not in _groups:
        _groups[kind] = PluginGroup(kind)
    return _groups[kind]
