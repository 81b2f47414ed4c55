"""``navigation``: Nav2's navigation servers in one process, with ``lifecycle_manager_navigation``
bringing them up in the order of :data:`pppbot_nav.lifecycle.NAVIGATION_NODES`:
controller_server, smoother_server, planner_server, behavior_server, velocity_smoother,
collision_monitor, bt_navigator, waypoint_follower. ``--without velocity_smoother`` and
``--without collision_monitor`` (before ``--ros-args``) leave those out.

Nav2's bringup composes its servers into one container by default (``use_composition``);
``launch_sim`` does the same with these (``use_composition:=false`` starts each as its
own process). They stay separate nodes, with their own names, parameters (their sections of
``nav2_params.yaml``), topics, services and actions; what they share is the process: one
interpreter and one DDS participant instead of one each (about 180 MB less summed RSS for
three of them, measured standing still), one executor, one ``/clock`` subscription, and one
lockstep participant answering for all. The velocity commands are chained by node-scoped
remappings (:func:`pppbot_nav.lifecycle.command_remaps`, given by the launch).
"""
from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from functools import partial

from rclpy.node import Node
from rclpy.utilities import remove_ros_args

from pppbot_lockstep.ros.runner import run_nodes
from pppbot_nav.errors import LifecycleError
from pppbot_nav.lifecycle import VELOCITY_CHAIN, navigation_nodes
from pppbot_nav.ros.behavior_server import BehaviorServer
from pppbot_nav.ros.collision_monitor import CollisionMonitor
from pppbot_nav.ros.controller_server import ControllerServer
from pppbot_nav.ros.lifecycle_manager import LifecycleManager
from pppbot_nav.ros.navigator import Navigator
from pppbot_nav.ros.planner_server import PlannerServer
from pppbot_nav.ros.smoother_server import SmootherServer
from pppbot_nav.ros.velocity_smoother import VelocitySmoother
from pppbot_nav.ros.waypoint_follower import WaypointFollower

#: Each navigation node's class, by its name.
NODES: dict[str, Callable[[], Node]] = {
    "controller_server": ControllerServer, "smoother_server": SmootherServer, "planner_server": PlannerServer,
    "behavior_server": BehaviorServer, "velocity_smoother": VelocitySmoother, "collision_monitor": CollisionMonitor,
    "bt_navigator": Navigator, "waypoint_follower": WaypointFollower}


def main(args: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="navigation", description=__doc__.split("\n\n")[0])
    parser.add_argument("--without", action="append", default=[], choices=VELOCITY_CHAIN,
                        help="leave this node of the velocity chain out (repeatable)")
    options = parser.parse_args(remove_ros_args(args if args is not None else sys.argv)[1:])
    try:
        names = navigation_nodes(options.without)
    except LifecycleError as exc:
        parser.error(str(exc))
    manager = partial(LifecycleManager, "lifecycle_manager_navigation", names, autostart=True)
    return run_nodes([*(NODES[name] for name in names), manager], "navigation", args)


if __name__ == "__main__":
    sys.exit(main())
