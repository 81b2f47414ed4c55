r"""``costmap_filters``: the servers of Nav2's costmap filter masks in one process.

For each filter asked for (``--keepout``, ``--speed``) a ``map_server`` serves its mask and a
``costmap_filter_info_server`` says what the mask means, under the names Nav2's bringup gives
them (``keepout_filter_mask_server`` on ``keepout_filter_mask``, ``keepout_costmap_filter_info_server``
on ``keepout_costmap_filter_info``; ``speed_…`` likewise, its info a limit in % of
``100 − mask value``), each with its section of the parameters file;
``lifecycle_manager_costmap_filters`` brings them up. ``launch_sim keepout_mask:=… speed_mask:=…``
starts it; the costmaps' ``KeepoutFilter`` and ``SpeedFilter`` read what it serves.

    ./pppbot run pppbot_nav costmap_filters --keepout --ros-args --params-file config/nav2_params.yaml \\
        -p keepout_filter_mask_server:yaml_filename:=my_keepout_mask.yaml
"""
from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

import yaml
from rclpy.parameter import Parameter
from rclpy.utilities import remove_ros_args

from pppbot_lockstep.ros.runner import run_nodes
from pppbot_nav.costmap.filters import KEEPOUT, SPEED_PERCENT
from pppbot_nav.ros.costmap_filter_info_server import CostmapFilterInfoServer
from pppbot_nav.ros.lifecycle_manager import LifecycleManager
from pppbot_nav.ros.map_server import MapServer

#: Each filter's mask server and info server, with Nav2's bringup defaults.
FILTERS: dict[str, tuple[dict[str, Any], dict[str, Any]]] = {
    "keepout": ({"topic_name": "keepout_filter_mask"},
                {"type": KEEPOUT, "filter_info_topic": "keepout_costmap_filter_info",
                 "mask_topic": "keepout_filter_mask", "base": 0.0, "multiplier": 1.0}),
    "speed": ({"topic_name": "speed_filter_mask"},
              {"type": SPEED_PERCENT, "filter_info_topic": "speed_costmap_filter_info",
               "mask_topic": "speed_filter_mask", "base": 100.0, "multiplier": -1.0}),
}


def node_names(kinds: list[str]) -> list[str]:
    """The managed nodes, mask server before info server, in ``kinds``' order."""
    return [name for kind in kinds for name in (f"{kind}_filter_mask_server", f"{kind}_costmap_filter_info_server")]


def given_parameters(args: list[str], node: str) -> set[str]:
    """The parameters of ``node`` the command line gives: in a ``--params-file`` (its section, or
    ``/**``'s) or as ``-p node:name:=value`` / ``-p name:=value``."""
    names: set[str] = set()
    for i, arg in enumerate(args):
        if arg == "--params-file" and i + 1 < len(args):
            try:
                document = yaml.safe_load(Path(args[i + 1]).read_text()) or {}
            except (OSError, yaml.YAMLError):
                continue  # rclpy names what is wrong with the file
            for key in (node, f"/{node}", "/**"):
                section = document.get(key) if isinstance(document, dict) else None
                if isinstance(section, dict) and isinstance(section.get("ros__parameters"), dict):
                    names |= set(section["ros__parameters"])
        elif arg in ("-p", "--param") and i + 1 < len(args):
            name = args[i + 1].split(":=", 1)[0]
            scope, _, param_name = name.rpartition(":")
            if scope in ("", node):
                names.add(param_name)
    return names


def _with_defaults(factory: Callable[..., Any], name: str, defaults: dict[str, Any], args: list[str],
                   **kwargs: Any) -> Any:
    """The node, with ``defaults`` for the parameters the command line leaves out (rclpy's
    overrides would win over the parameters file)."""
    given = given_parameters(args, name)
    overrides = [Parameter(k, value=v) for k, v in defaults.items() if k not in given]
    return factory(name=name, parameter_overrides=overrides, **kwargs)


def main(args: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="costmap_filters", description=__doc__.split("\n\n")[0])
    for kind in FILTERS:
        parser.add_argument(f"--{kind}", action="store_true", help=f"serve the {kind} filter's mask and info")
    argv = list(args if args is not None else sys.argv)
    options = parser.parse_args(remove_ros_args(argv)[1:])
    kinds = [kind for kind in FILTERS if getattr(options, kind)]
    if not kinds:
        parser.error("name at least one filter: " + ", ".join(f"--{kind}" for kind in FILTERS))
    factories: list[Callable[..., Any]] = []
    for kind in kinds:
        mask, info = FILTERS[kind]
        factories.append(partial(_with_defaults, MapServer, f"{kind}_filter_mask_server", mask, argv))
        factories.append(partial(_with_defaults, CostmapFilterInfoServer, f"{kind}_costmap_filter_info_server",
                                 info, argv))
    manager = partial(LifecycleManager, "lifecycle_manager_costmap_filters", node_names(kinds), autostart=True)
    return run_nodes([*factories, manager], "costmap_filters", args)


if __name__ == "__main__":
    sys.exit(main())
