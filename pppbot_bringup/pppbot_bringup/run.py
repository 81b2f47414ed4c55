"""``pppbot run <package> <executable> [args]``: run one node, as ``ros2 run`` does.

Executables are found where ament_python installs them,
``<prefix>/lib/<package>/<executable>`` for the prefixes in the ament index.
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from ament_index_python.packages import PackageNotFoundError, get_package_prefix

from pppbot_bringup.errors import RunError


def executables_of(package: str) -> dict[str, Path]:
    """Executable files of ``package`` by name.

    Raises:
        RunError: the package is not in the ament index.
    """
    try:
        prefix = Path(get_package_prefix(package))
    except PackageNotFoundError as exc:
        raise RunError(f"package '{package}' not found in AMENT_PREFIX_PATH") from exc
    folder = prefix / "lib" / package
    if not folder.is_dir():
        return {}
    return {p.name: p for p in sorted(folder.iterdir())
            if p.is_file() and os.access(p, os.X_OK)}


def find_executable(package: str, executable: str) -> Path:
    """The path of ``executable`` in ``package``.

    Raises:
        RunError: no such package or executable; lists the ones that exist.
    """
    found = executables_of(package)
    if executable not in found:
        known = ", ".join(found) or "none"
        raise RunError(f"no executable '{executable}' in package '{package}' (it has: {known})")
    return found[executable]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("package", help="package name, e.g. pppbot_sim")
    parser.add_argument("executable", help="executable in the package, e.g. simulator")
    parser.add_argument("argv", nargs=argparse.REMAINDER,
                        help="arguments passed on, including --ros-args ...")


def exec_node(package: str, executable: str, argv: list[str], verb: str) -> int:
    """Replace this process with the executable (as ``ros2 run`` does); 1 with a message if missing."""
    try:
        path = find_executable(package, executable)
    except RunError as exc:
        print(f"pppbot {verb}: {exc}", file=sys.stderr)
        return 1
    sys.stdout.flush()
    os.execv(str(path), [str(path), *argv])
    return 0  # not reached


def main(args: argparse.Namespace) -> int:
    return exec_node(args.package, args.executable, args.argv, "run")


__all__ = ["RunError", "executables_of", "exec_node", "find_executable", "add_arguments", "main"]
