"""``navigation``: planner_server, controller_server, behavior_server and bt_navigator in one
process, with ``lifecycle_manager_navigation`` bringing them up in that order.

Nav2's bringup composes its servers into one container by default (``use_composition``);
``launch_sim`` does the same with these (``use_composition:=false`` starts each as its
own process). They stay separate nodes, with their own
names, parameters (their sections of ``nav2_params.yaml``), topics, services and actions;
what they share is the process: one interpreter and one DDS participant instead of one each
(about 180 MB less summed RSS, measured standing still), one executor, one ``/clock``
subscription, and one lockstep participant answering for all three.
"""
from __future__ import annotations

import sys
from functools import partial

from pppbot_common.ros.node_main import run_nodes
from pppbot_nav.lifecycle import NAVIGATION_NODES
from pppbot_nav.ros.behavior_server import BehaviorServer
from pppbot_nav.ros.controller_server import ControllerServer
from pppbot_nav.ros.lifecycle_manager import LifecycleManager
from pppbot_nav.ros.navigator import Navigator
from pppbot_nav.ros.planner_server import PlannerServer


def main(args: list[str] | None = None) -> int:
    manager = partial(LifecycleManager, "lifecycle_manager_navigation", NAVIGATION_NODES, autostart=True)
    return run_nodes([PlannerServer, ControllerServer, BehaviorServer, Navigator, manager], "navigation", args)


if __name__ == "__main__":
    sys.exit(main())
