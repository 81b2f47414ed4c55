"""The ``pppbot`` command line: one entry point, a verb per tool.

``./pppbot`` at the repository root sets the environment up and calls this; with
an installed ROS 2 Jazzy, ``ros2 run pppbot_bringup pppbot <verb>`` does the same.
Verbs are found as ``ros2`` finds ``ros2 bag``: each package declares its own in its
``setup.py`` as entry points of the group ``pppbot.verbs`` (``bag = pppbot_bag.cli``).
A verb is a module with ``add_arguments(parser)`` and ``main(args) -> int`` (or
``main_argv(argv) -> int``), imported only when named; its help line is the first line
of its docstring, read without importing it, so ``pppbot --help`` stays quick.
"""
from __future__ import annotations

import argparse
import ast
import importlib
import importlib.util
import os
import sys
from importlib.metadata import entry_points
from pathlib import Path

from pppbot_bringup.errors import VerbConflict
from pppbot_common.dds_isolation import domain_id_problem

#: The entry point group of ``pppbot`` verbs.
VERB_GROUP = "pppbot.verbs"


def find_verbs() -> dict[str, str]:
    """Verb → module, from the installed packages' ``pppbot.verbs`` entry points.

    Raises:
        VerbConflict: one verb declared by two packages with different modules.
    """
    verbs: dict[str, str] = {}
    for point in entry_points(group=VERB_GROUP):
        if verbs.get(point.name, point.module) != point.module:
            raise VerbConflict(f"verb {point.name!r} is declared twice: by {verbs[point.name]} and by "
                               f"{point.module} (entry points '{VERB_GROUP}'); uninstall one of them")
        verbs[point.name] = point.module
    return dict(sorted(verbs.items()))


def verb_help(module: str) -> str:
    """The first paragraph of ``module``'s docstring after its usage (``pppbot bag ...``: …), unimported."""
    try:
        spec = importlib.util.find_spec(module)
    except ModuleNotFoundError:  # its package is missing
        spec = None
    if spec is None or spec.origin is None:
        return f"({module} is not installed)"
    doc = ast.get_docstring(ast.parse(Path(spec.origin).read_text(encoding="utf-8"))) or ""
    first = " ".join(doc.strip().split("\n\n")[0].split()) if doc.strip() else module
    usage, colon, rest = first.partition("``: ")
    return (rest if colon else first).replace("``", "`")


# Verbs of DESIGN.md that this checkout does not have yet: named, never faked.
NOT_YET: dict[str, str] = {}

# Handled by ./pppbot itself before Python starts; listed for --help.
SHELL_VERBS: dict[str, str] = {
    "setup": "create or update the environment (.venv/, install/); ./pppbot only",
    "env": "run a command inside the environment, e.g. `./pppbot env bash`; ./pppbot only",
}


def _top_parser(verbs: dict[str, str]) -> argparse.ArgumentParser:
    width = max(map(len, [*verbs, *SHELL_VERBS]))
    rows = [*(f"  {n:<{width}}  {verb_help(m)}" for n, m in verbs.items()),
            *(f"  {n:<{width}}  {h}" for n, h in SHELL_VERBS.items())]
    parser = argparse.ArgumentParser(
        prog="pppbot",
        usage="pppbot <verb> [arguments ...]",
        description="pppbot: a MuJoCo-simulated ppp_bot on ROS 2 Jazzy, and the tools around it.",
        epilog="verbs:\n" + "\n".join(rows) + "\n\n`pppbot <verb> --help` describes a verb.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("verb", choices=sorted(verbs), metavar="<verb>", help=argparse.SUPPRESS)
    parser.add_argument("arguments", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv and argv[0] in NOT_YET:
        print(f"pppbot {argv[0]}: {NOT_YET[argv[0]]} is not built yet in this checkout "
              "(README.md, 'Status', says what is)", file=sys.stderr)
        return 2
    try:
        verbs = find_verbs()
    except VerbConflict as exc:
        print(f"pppbot: {exc}", file=sys.stderr)
        return 2
    top = _top_parser(verbs).parse_args(argv)
    problem = domain_id_problem(os.environ.get("ROS_DOMAIN_ID"))
    if problem is not None:  # DDS would fail later with a port error on stdout
        print(f"pppbot {top.verb}: {problem}", file=sys.stderr)
        return 2
    module_name = verbs[top.verb]
    module = importlib.import_module(module_name)
    if hasattr(module, "main_argv"):  # verbs that parse their own: name:=value arguments, sub-verbs
        return int(module.main_argv(list(top.arguments)))
    parser = argparse.ArgumentParser(prog=f"pppbot {top.verb}", description=verb_help(module_name))
    module.add_arguments(parser)
    args = parser.parse_args(top.arguments)
    try:
        return int(module.main(args))
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
