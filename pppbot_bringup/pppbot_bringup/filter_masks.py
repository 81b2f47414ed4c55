"""``launch_sim keepout_mask:=… speed_mask:=…``: Nav2's costmap filters for a run (Nav2's bringup
``use_keepout_zones`` / ``use_speed_zones``, its masks ``keepout_mask`` / ``speed_mask``).

A mask given, the navigation parameters get its filter where they lack one: a
``nav2_costmap_2d::KeepoutFilter`` named ``keepout_filter`` in both costmaps, followed by an
inflation layer (``keepout_inflation``, the costmap's own inflation settings) so that paths keep
the robot's radius from a zone, as Nav2's documentation advises (filters are not inflated), a
``nav2_costmap_2d::SpeedFilter`` named ``speed_filter`` in the global costmap (one speed limit for
the controller), each reading the info topic Nav2's bringup uses. A filter the file already has
is enabled and its ``filter_info_topic`` kept: the info server publishes there. The
``costmap_filters`` process (:mod:`pppbot_nav.ros.costmap_filters`) serves the masks.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Any

KEEPOUT_TYPE = "nav2_costmap_2d::KeepoutFilter"
SPEED_TYPE = "nav2_costmap_2d::SpeedFilter"
#: Each kind: its plugin type, the name and info topic a filter gets when the file has none, the costmaps it goes in.
KINDS = {"keepout": (KEEPOUT_TYPE, "keepout_filter", "keepout_costmap_filter_info",
                     ("global_costmap", "local_costmap")),
         "speed": (SPEED_TYPE, "speed_filter", "speed_costmap_filter_info", ("global_costmap",))}


KEEPOUT_INFLATION = "keepout_inflation"
INFLATION_TYPE = "nav2_costmap_2d::InflationLayer"


def _inflation_like(params: dict[str, Any]) -> dict[str, Any]:
    """An inflation layer's section with the settings of the costmap's own inflation layer, if any."""
    own: dict[str, Any] = next((params[name] for name in params.get("plugins") or []
                if isinstance(params.get(name), dict) and _plugin_of(params, name) == INFLATION_TYPE), {})
    kept = {k: v for k, v in own.items() if k in ("inflation_radius", "cost_scaling_factor", "inflate_unknown",
                                                 "inflate_around_unknown")}
    return {"plugin": INFLATION_TYPE, "enabled": True, **kept}


def _own_topic(document: dict[str, Any], costmap: str, plugin: str) -> str | None:
    """The info topic of a ``plugin`` filter ``costmap`` has already, if it names one."""
    section = document.get(costmap)
    if not isinstance(section, dict):
        return None
    params = _costmap_parameters(copy.deepcopy(document), costmap)
    for name in params.get("filters") or []:
        if _plugin_of(params, name) == plugin:
            own = params.get(name)
            topic = own.get("filter_info_topic") if isinstance(own, dict) else params.get(f"{name}.filter_info_topic")
            if topic:
                return str(topic)
    return None


@dataclass(frozen=True)
class FilterSetup:
    """What the launch does for the masks: the adapted document, each kind's info topic, and notes."""

    document: dict[str, Any]
    info_topics: dict[str, str]
    changes: list[str]


def _costmap_parameters(document: dict[str, Any], costmap: str) -> dict[str, Any]:
    section = document.setdefault(costmap, {})
    inner = section.setdefault(costmap, {}) if "ros__parameters" not in section else section
    return inner.setdefault("ros__parameters", {})


def _plugin_of(params: dict[str, Any], name: str) -> str:
    """A filter's ``plugin`` (nested, or a dotted key), in the ``pkg::Class`` spelling."""
    section = params.get(name)
    given = section.get("plugin") if isinstance(section, dict) else params.get(f"{name}.plugin")
    return str(given or "").strip().replace("/", "::")


def with_filters(document: dict[str, Any], kinds: list[str]) -> FilterSetup:
    """``document`` (Nav2's parameters, not changed) with the filters of ``kinds`` in its costmaps."""
    out = copy.deepcopy(document)
    info_topics: dict[str, str] = {}
    changes: list[str] = []
    for kind in kinds:
        plugin, default_name, default_topic, costmaps = KINDS[kind]
        # A filter the file has gives the topic the added ones read too.
        default_topic = next((topic for costmap in costmaps if (topic := _own_topic(out, costmap, plugin))),
                             default_topic)
        for costmap in costmaps:
            params = _costmap_parameters(out, costmap)
            filters = list(params.get("filters") or [])
            name = next((f for f in filters if _plugin_of(params, f) == plugin), None)
            if name is None:
                name = default_name
                params["filters"] = [*filters, name]
                params[name] = {"plugin": plugin, "enabled": True, "filter_info_topic": default_topic}
                changes.append(f"{costmap} gets {name} ({plugin.split('::')[-1]})")
                if kind == "keepout":
                    params["filters"].append(KEEPOUT_INFLATION)
                    params[KEEPOUT_INFLATION] = _inflation_like(params)
                topic = default_topic
            else:
                section = params.get(name)
                if isinstance(section, dict):
                    section["enabled"] = True
                    topic = str(section.get("filter_info_topic") or default_topic)
                    section["filter_info_topic"] = topic
                else:
                    params[f"{name}.enabled"] = True
                    topic = str(params.get(f"{name}.filter_info_topic") or default_topic)
                    params[f"{name}.filter_info_topic"] = topic
            info_topics.setdefault(kind, topic)
            if info_topics[kind] != topic:
                raise ValueError(f"the costmaps' {plugin} filters read different info topics "
                                 f"('{info_topics[kind]}', '{topic}'): one {kind} mask serves one topic")
    return FilterSetup(out, info_topics, changes)
