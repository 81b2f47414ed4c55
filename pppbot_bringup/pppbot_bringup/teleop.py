"""``pppbot teleop``: the keyboard teleop in this terminal (teleop_twist_keyboard's keys).

Extra arguments go to the node, e.g. ``pppbot teleop --ros-args -p speed:=0.3``.
"""
from __future__ import annotations

import argparse

from pppbot_bringup.run import exec_node


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("argv", nargs=argparse.REMAINDER, help="passed on, e.g. --ros-args -p speed:=0.3")


def main(args: argparse.Namespace) -> int:
    return exec_node("pppbot_control", "teleop_keyboard", args.argv, "teleop")
