"""Generate worlds for the autonomy suite: seeded layouts of several families, written as SDF with their routes.

Each world is ``<out>/<name>.sdf`` (:mod:`pppbot_sim.worldgen.families`: maze, looped_maze,
office, corridor, hall, symmetric, cones, clutter, self_similar) and ``<out>/<name>.routes.yaml``
holding its ``coverage`` route (:mod:`pppbot_eval.coverage`), so ``launch_sim world:=<out>/<name>.sdf``
and ``./pppbot eval slam --world <out>/<name>.sdf`` take it like a shipped world. A
``clutter`` world (BARN's kind: an obstacle field to cross) has its ``crossing`` route first,
the shortest passable path to its goal, which a map-less ``eval navigation --no-map`` takes as
the goal. A family and a seed give the same world on every machine.

Sets (``--set``): ``tune`` (seeds 0–2 of every family but clutter and self_similar, 21 worlds:
tune parameters on these), ``held_out`` (seeds 100–102, 21 worlds, never tuned on: report them
separately), ``clutter_tune`` (clutter seeds 0–9), ``clutter_held_out`` (clutter seeds
100–199, 100 worlds, never tuned on), ``self_similar_tune`` (self_similar seeds 0–4),
``self_similar_held_out`` (self_similar seeds 100–104, never tuned on) and ``ci`` (two small
worlds, for the test suite).

    ./pppbot env python benchmarks/worldgen.py --family maze --seed 3 [--small] [--out DIR]
    ./pppbot env python benchmarks/worldgen.py --set tune [--out DIR]

prints each world's path and properties, and a JSON list of them on its last line.
"""
from __future__ import annotations

import argparse
import json
import sys
from dataclasses import dataclass
from pathlib import Path

from pppbot_eval.generated_worlds import write_world
from pppbot_sim.worldgen.families import Family, WorldGenError, family_of, generate

DEFAULT_OUT = Path(__file__).resolve().parent / ".cache" / "worlds"


@dataclass(frozen=True)
class WorldSpec:
    family: Family
    seed: int
    small: bool = False


TUNE_SEEDS = (0, 1, 2)
HELD_OUT_SEEDS = (100, 101, 102)
#: clutter worlds come in sets of their own, as BARN's many fields do
CLUTTER_TUNE_SEEDS = range(10)
CLUTTER_HELD_OUT_SEEDS = range(100, 200)
#: self-similar worlds too: a few, to count false loop closures on
SELF_SIMILAR_TUNE_SEEDS = range(5)
SELF_SIMILAR_HELD_OUT_SEEDS = range(100, 105)
_MIXED = [f for f in Family if f not in (Family.CLUTTER, Family.SELF_SIMILAR)]
SETS: dict[str, list[WorldSpec]] = {
    "tune": [WorldSpec(f, s) for f in _MIXED for s in TUNE_SEEDS],
    "held_out": [WorldSpec(f, s) for f in _MIXED for s in HELD_OUT_SEEDS],
    "clutter_tune": [WorldSpec(Family.CLUTTER, s) for s in CLUTTER_TUNE_SEEDS],
    "clutter_held_out": [WorldSpec(Family.CLUTTER, s) for s in CLUTTER_HELD_OUT_SEEDS],
    "self_similar_tune": [WorldSpec(Family.SELF_SIMILAR, s) for s in SELF_SIMILAR_TUNE_SEEDS],
    "self_similar_held_out": [WorldSpec(Family.SELF_SIMILAR, s) for s in SELF_SIMILAR_HELD_OUT_SEEDS],
    "ci": [WorldSpec(Family.LOOPED_MAZE, 0, small=True), WorldSpec(Family.OFFICE, 1, small=True)],
}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--family", help=f"one of {', '.join(f.value for f in Family)}")
    group.add_argument("--set", choices=sorted(SETS), help="a whole set of worlds")
    parser.add_argument("--seed", type=int, default=0, help="with --family: the layout's seed (default 0)")
    parser.add_argument("--small", action="store_true", help="with --family: about half the size")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help=f"output folder (default {DEFAULT_OUT})")
    args = parser.parse_args(argv)
    try:
        specs = SETS[args.set] if args.set else [WorldSpec(family_of(args.family), args.seed, args.small)]
        summaries = []
        for spec in specs:
            world_file, summary = write_world(generate(spec.family, spec.seed, small=spec.small), args.out)
            print(f"{world_file}: {summary}")
            summaries.append(summary)
    except WorldGenError as exc:
        print(f"worldgen: {exc}", file=sys.stderr)
        return 2
    print(json.dumps(summaries))
    return 0


if __name__ == "__main__":
    sys.exit(main())
