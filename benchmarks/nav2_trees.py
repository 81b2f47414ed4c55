"""Navigation with Nav2's ``navigate_*`` behaviour trees against pppbot's default trees.

Each variant is ``config/nav2_params.yaml`` with ``bt_navigator``'s ``default_nav_to_pose_bt_xml``
set: ``pppbot`` leaves the file as it is (pppbot's own trees, ``pppbot_nav/behavior_trees/``), and
each ``navigate_*.xml`` of ``--trees`` (Nav2's ``nav2_bt_navigator/behavior_trees`` folder, from an
installed Nav2 or its sources: the project holds none of Nav2's files) names that file. Every
variant runs ``pppbot eval navigation --params-file`` in lockstep in each ``--worlds`` world, with
the same random goals (same seed), judged on ground truth, as ``nav2_plugins.py`` does.

A tree that navigates through poses (one reading ``{goals}``, or using ``ComputePathThroughPoses`` or
``RemovePassedGoals``) is set as ``default_nav_through_poses_bt_xml`` instead and its runs send
each goal as a one-pose ``navigate_through_poses`` goal (``eval navigation --through-poses``);
``pppbot_through_poses`` is pppbot's own through-poses tree run so.

Prints a line per run on stderr and, as its last line, one JSON object with every run's success
rate, collisions, mean time ratio (a goal's time over its shortest path's time at the robot's top
speed, docs/evaluation.md), mean path ratio, closest clearance, real-time factor and wall time. A
run that failed carries ``failure``; its logs are under ``--out``.

    ./pppbot env python benchmarks/nav2_trees.py [--trees DIR] [--worlds room,maze] [--goals 10]
        [--only pppbot,navigate_to_pose_w_replanning_and_recovery] [--out DIR]
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
from nav2_plugins import OURS, run  # noqa: E402 (the benchmarks folder is not a package)

from pppbot_common.dds_isolation import isolate_dds  # noqa: E402

#: The variants that keep ``config/nav2_params.yaml`` as it is (pppbot's default trees), to a pose
#: and through poses.
PPPBOT = "pppbot"
PPPBOT_THROUGH = "pppbot_through_poses"
#: Nodes and blackboard entries only a navigate_through_poses goal gives a tree.
THROUGH_POSES_NODES = frozenset({"ComputePathThroughPoses", "RemovePassedGoals"})
THROUGH_POSES_ENTRY = "{goals}"


@dataclass(frozen=True)
class Options:
    """The command line, parsed once."""

    trees: Path | None
    worlds: tuple[str, ...]
    goals: int
    out: Path | None
    only: frozenset[str] | None


def parse_options(argv: list[str] | None = None) -> Options:
    """The command line's options.

    Raises:
        SystemExit: a bad argument (argparse's message names it), or ``--trees`` is not a folder.
    """
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument("--trees", type=Path, default=None,
                        help="Nav2's behavior_trees folder (default none: pppbot's trees only)")
    parser.add_argument("--worlds", default="room,maze", help="comma-separated worlds (default room,maze)")
    parser.add_argument("--goals", type=int, default=10, help="goals per run (default 10)")
    parser.add_argument("--only", default=None, help="comma-separated variants to run (pppbot, or a tree's stem)")
    parser.add_argument("--out", type=Path, default=None, help="where the runs' reports go (default a temp dir)")
    args = parser.parse_args(argv)
    if args.trees is not None and not args.trees.is_dir():
        parser.error(f"--trees {args.trees}: not a folder")
    only = frozenset(n for n in args.only.split(",") if n) if args.only else None
    return Options(trees=args.trees.resolve() if args.trees else None, worlds=tuple(args.worlds.split(",")),
                   goals=args.goals, out=args.out, only=only)


def through_poses(tree: Path) -> bool:
    """Whether ``tree`` navigates through poses (it needs a navigate_through_poses goal).

    Raises:
        ET.ParseError: the file is not well-formed XML.
    """
    return any(element.tag in THROUGH_POSES_NODES or THROUGH_POSES_ENTRY in element.attrib.values()
               for element in ET.parse(tree).iter())


@dataclass(frozen=True)
class Variant:
    tree: Path | None  # None: pppbot's own
    through: bool  # run with navigate_through_poses goals


def variants(trees: Path | None) -> tuple[dict[str, Variant], dict[str, str]]:
    """Each variant's tree and goal kind, and the trees skipped, with why."""
    chosen = {PPPBOT: Variant(None, False), PPPBOT_THROUGH: Variant(None, True)}
    skipped: dict[str, str] = {}
    for tree in sorted(trees.glob("navigate_*.xml")) if trees else []:
        try:
            chosen[tree.stem] = Variant(tree, through_poses(tree))
        except ET.ParseError as exc:
            skipped[tree.stem] = f"{tree}: not well-formed XML: {exc}"
    return chosen, skipped


def write_params(variant: Variant, path: Path) -> Path:
    """``config/nav2_params.yaml`` with the variant's tree as the default of its goal kind."""
    params = yaml.safe_load(OURS.read_text())
    if variant.tree is not None:
        key = "default_nav_through_poses_bt_xml" if variant.through else "default_nav_to_pose_bt_xml"
        params["bt_navigator"]["ros__parameters"][key] = str(variant.tree.resolve())
    path.write_text(yaml.safe_dump(params, sort_keys=False))
    return path


def main() -> int:
    options = parse_options()
    isolate_dds()
    out = options.out or Path(tempfile.mkdtemp(prefix="nav2_trees_"))
    out.mkdir(parents=True, exist_ok=True)
    chosen, skipped = variants(options.trees)
    if options.only is not None:
        chosen = {name: tree for name, tree in chosen.items() if name in options.only}
        skipped = {name: why for name, why in skipped.items() if name in options.only}
    for name, why in skipped.items():
        print(f"{name}: skipped: {why}", file=sys.stderr, flush=True)
    results: dict[str, dict[str, Any]] = {}
    for name, variant in chosen.items():
        params = write_params(variant, out / f"{name}.yaml")
        extra = ("--through-poses",) if variant.through else ()
        for world in options.worlds:
            figures = run(world, params, options.goals, out / f"{name}_{world}", extra)
            results.setdefault(name, {})[world] = figures
            print(f"{name} {world}: {json.dumps(figures)}", file=sys.stderr, flush=True)
    files = {name: str(v.tree) if v.tree else "config/nav2_params.yaml" for name, v in chosen.items()}
    print(json.dumps({"goals": options.goals, "worlds": list(options.worlds),
                      "trees": str(options.trees) if options.trees else None, "files": files,
                      "results": results, "skipped": skipped, "out": str(out)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
