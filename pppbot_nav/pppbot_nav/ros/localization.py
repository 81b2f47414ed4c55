"""``localization``: map_server and amcl in one process.

Nav2's bringup composes its localization servers with its navigation servers when
``use_composition`` is on; ``launch_sim`` composes map_server and amcl here and the three
navigation servers in ``navigation`` (``use_composition:=false`` starts each node as its own
process). They stay separate nodes with their own names, parameters (their sections of
``nav2_params.yaml``; a launch gives one node a parameter as ``-p amcl:seed:=3``), topics and
services; what they share is the process: one interpreter and one DDS participant instead
of two (about 75 MB less summed RSS standing still), and one lockstep participant answering
for both. map_server is made first, so AMCL's map is on ``/map`` before AMCL subscribes.

Both are lifecycle nodes; ``lifecycle_manager_localization`` (Nav2's name and parameters: its
section of ``nav2_params.yaml``; ``autostart`` true by default here, as Nav2's bringup sets it)
configures and activates them in that order as soon as the process runs.
"""
from __future__ import annotations

import sys
from functools import partial

from pppbot_lockstep.ros.runner import run_nodes
from pppbot_nav.lifecycle import LOCALIZATION_NODES
from pppbot_nav.ros.amcl import Amcl
from pppbot_nav.ros.lifecycle_manager import LifecycleManager
from pppbot_nav.ros.map_server import MapServer


def main(args: list[str] | None = None) -> int:
    manager = partial(LifecycleManager, "lifecycle_manager_localization", LOCALIZATION_NODES, autostart=True)
    return run_nodes([MapServer, Amcl, manager], "localization", args)


if __name__ == "__main__":
    sys.exit(main())
