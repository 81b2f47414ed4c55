"""``pppbot foxglove``: the Foxglove bridge, for Foxglove or Lichtblick (``foxglove_bridge``).

    pppbot foxglove                       # ws://127.0.0.1:8765, every topic, sim time
    pppbot foxglove --port 9000 --topics '/scan|/map|/tf.*'

Open Foxglove or Lichtblick, "Open connection", Foxglove WebSocket, ``ws://127.0.0.1:8765``.
Topics are forwarded byte for byte (``cdr``, ``ros2msg`` schemas); clients may publish on
``/goal_pose``, ``/initialpose`` and ``/cmd_vel_teleop``. Also ``ros2 run pppbot_viz
foxglove_bridge`` with foxglove_bridge's parameters. Ctrl-C stops it.
"""
from __future__ import annotations

import argparse

from pppbot_viz.ros import foxglove_bridge


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--port", type=int, default=8765, help="the WebSocket port (default 8765; 0: a free one)")
    parser.add_argument("--address", default="127.0.0.1",
                        help="the address to listen on (default 127.0.0.1: this machine only)")
    parser.add_argument("--topics", metavar="REGEX", default=".*",
                        help="the topics offered (a regular expression; default: all)")
    parser.add_argument("--client-topics", metavar="REGEX", default="",
                        help="the topics clients may publish on (default: /goal_pose, /initialpose, /cmd_vel_teleop)")
    parser.add_argument("--wall-time", action="store_true",
                        help="stamp forwarded messages with wall time instead of sim time (/clock)")


def main(args: argparse.Namespace) -> int:
    ros_args = ["--ros-args", "-p", f"port:={args.port}", "-p", f"address:={args.address}",
                "-p", f"topic_whitelist:=['{args.topics}']", "-p", f"use_sim_time:={str(not args.wall_time).lower()}"]
    if args.client_topics:
        ros_args += ["-p", f"client_topic_whitelist:=['{args.client_topics}']"]
    return foxglove_bridge.main(["pppbot foxglove", *ros_args])
