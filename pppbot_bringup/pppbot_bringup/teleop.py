"""``pppbot teleop``: the keyboard teleop in this terminal (teleop_twist_keyboard's keys).

Extra arguments go to the node, e.g. ``pppbot teleop --ros-args -p speed:=0.3``.
"""
from __future__ import annotations

import argparse
import os
import sys

from pppbot_bringup.run import RunError, find_executable


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("argv", nargs=argparse.REMAINDER, help="passed on, e.g. --ros-args -p speed:=0.3")


def main(args: argparse.Namespace) -> int:
    try:
        path = find_executable("pppbot_control", "teleop_keyboard")
    except RunError as exc:
        print(f"pppbot teleop: {exc}", file=sys.stderr)
        return 1
    os.execv(str(path), [str(path), *args.argv])
    return 0  # not reached
