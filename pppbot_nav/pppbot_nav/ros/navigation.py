"""``navigation``: planner_server, controller_server and navigator in one process.

Nav2's bringup composes its servers into one container by default (``use_composition``);
``launch_sim`` does the same with these three (``use_composition:=false`` starts each as its
own process). They stay separate nodes, with their own
names, parameters (their sections of ``nav2_params.yaml``), topics, services and actions;
what they share is the process: one interpreter and one DDS participant instead of three
(about 180 MB less summed RSS, measured standing still), one executor, one ``/clock``
subscription, and one lockstep participant answering for all three.
"""
from __future__ import annotations

import sys

from pppbot_common.ros.node_main import run_nodes
from pppbot_nav.ros.controller_server import ControllerServer
from pppbot_nav.ros.navigator import Navigator
from pppbot_nav.ros.planner_server import PlannerServer


def main(args: list[str] | None = None) -> int:
    return run_nodes([PlannerServer, ControllerServer, Navigator], "navigation", args)


if __name__ == "__main__":
    sys.exit(main())
