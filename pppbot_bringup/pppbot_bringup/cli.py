"""The ``pppbot`` command line: one entry point, a verb per tool.

``./pppbot`` at the repository root sets the environment up and calls this; with
an installed ROS 2 Jazzy, ``ros2 run pppbot_bringup pppbot <verb>`` does the same.
Each verb is a module with ``add_arguments(parser)`` and ``main(args) -> int``,
imported only when named, so ``pppbot --help`` stays quick.
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys

from pppbot_common.dds_isolation import domain_id_problem

# verb → (module, one-line help)
VERBS: dict[str, tuple[str, str]] = {
    "run": ("pppbot_bringup.run", "run one node, like `ros2 run <package> <executable>`"),
    "topic": ("pppbot_bringup.ros.topic", "inspect topics: list, info, echo, hz (like `ros2 topic`)"),
    "teleop": ("pppbot_bringup.teleop", "drive with the keyboard in this terminal (teleop_twist_keyboard's keys)"),
    "launch_sim": ("pppbot_bringup.ros.launch_sim", "the simulation bringup (name:=value arguments; --show-args)"),
    "bag": ("pppbot_bag.cli", "record, play, inspect and reindex rosbag2 (MCAP) bags (like `ros2 bag`)"),
    "eval": ("pppbot_bringup.ros.eval", "run a headless scenario and measure it against ground truth"),
    "nav": ("pppbot_nav.ros.nav_cli", "send a navigation goal and print its feedback: nav goto X Y [YAW]"),
    "map_saver": ("pppbot_nav.ros.map_saver_cli",
                  "save /map as a Nav2 map, YAML + PGM (like nav2_map_server's map_saver_cli)"),
}

# Verbs of DESIGN.md that this checkout does not have yet: named, never faked.
NOT_YET: dict[str, str] = {}

# Handled by ./pppbot itself before Python starts; listed for --help.
SHELL_VERBS: dict[str, str] = {
    "setup": "create or update the environment (.venv/, install/); ./pppbot only",
    "env": "run a command inside the environment, e.g. `./pppbot env bash`; ./pppbot only",
}


def _top_parser() -> argparse.ArgumentParser:
    width = max(map(len, [*VERBS, *SHELL_VERBS]))
    rows = [*(f"  {n:<{width}}  {h}" for n, (_, h) in VERBS.items()),
            *(f"  {n:<{width}}  {h}" for n, h in SHELL_VERBS.items())]
    parser = argparse.ArgumentParser(
        prog="pppbot",
        usage="pppbot <verb> [arguments ...]",
        description="pppbot: a MuJoCo-simulated ppp_bot on ROS 2 Jazzy, and the tools around it.",
        epilog="verbs:\n" + "\n".join(rows) + "\n\n`pppbot <verb> --help` describes a verb.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("verb", choices=sorted(VERBS), metavar="<verb>", help=argparse.SUPPRESS)
    parser.add_argument("arguments", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv and argv[0] in NOT_YET:
        print(f"pppbot {argv[0]}: {NOT_YET[argv[0]]} is not built yet in this checkout "
              "(README.md, 'Status', says what is)", file=sys.stderr)
        return 2
    top = _top_parser().parse_args(argv)
    problem = domain_id_problem(os.environ.get("ROS_DOMAIN_ID"))
    if problem is not None:  # DDS would fail later with a port error on stdout
        print(f"pppbot {top.verb}: {problem}", file=sys.stderr)
        return 2
    module_name, help_text = VERBS[top.verb]
    module = importlib.import_module(module_name)
    if hasattr(module, "main_argv"):  # verbs with ros2-launch-style name:=value arguments
        return int(module.main_argv(list(top.arguments)))
    parser = argparse.ArgumentParser(prog=f"pppbot {top.verb}", description=help_text)
    module.add_arguments(parser)
    args = parser.parse_args(top.arguments)
    try:
        return int(module.main(args))
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
