"""The autonomy suite: SLAM, then AMCL on the SLAM map, then navigation, across generated worlds.

The suite is a batch (``pppbot eval batch``, :mod:`pppbot_eval.batch`): for each world of a set
(:mod:`benchmarks.worldgen`: ``tune``, ``held_out``, ``ci``, ``self_similar_tune``,
``self_similar_held_out``) the batch

1. writes the world and its coverage route (the generator is seeded: the same world on
   every machine);
2. ``pppbot eval slam``: maps the world along the coverage route; the report holds the
   trajectory error (ATE) and the map's quality against the world (F1), and the map is
   saved as Nav2 YAML + PGM;
3. ``pppbot eval localization --map <that map>``: AMCL on the SLAM map along the same
   route, from an initial pose 0.5 m and 0.3 rad off;
4. ``pppbot eval navigation --map <that map>``: ``--goals`` random reachable goals sent
   to ``navigate_to_pose``, judged on ground truth.

The spec is written to ``--out/suite.batch.yaml`` (``benchmarks/batches/autonomy_held_out.yaml``
is the held-out set's, for ``pppbot eval batch`` itself); worlds run ``--workers`` at once, or
on a Ray cluster (``--ray``). Every run is in lockstep with wheel slip 0.01 and the default
parameters, so the figures are the same on any machine and any number of workers; only the
wall time differs. The batch's table and summary go to stderr with one line per world and
stage, and the per-world and aggregate figures (per set, per family, and against the issue's
targets) as one JSON object on the last line of stdout. Each stage's own report stays in
``--out/<world>/<stage>/``; ``--resume`` keeps the reports already there, so an interrupted
suite picks up where it stopped.

    ./pppbot env python benchmarks/autonomy_suite.py --set tune [--set held_out] [--goals 10]
                                                     [--worlds maze_000,hall_001] [--out DIR] [--resume]
                                                     [--workers N | --ray auto]

The worlds of ``held_out`` are never tuned on: report them separately (the aggregate is
per set).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))

from worldgen import SETS, WorldSpec  # noqa: E402  (a sibling script)

from pppbot_eval.routes import load_routes, routes_file  # noqa: E402
from pppbot_sim.worldgen.families import generate  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
PPPBOT = str(ROOT / "pppbot")
DEFAULT_OUT = Path(__file__).resolve().parent / ".cache" / "autonomy"
STAGES = ("slam", "localization", "navigation")
#: The issue's targets (Deliver 3), over every world of a set.
MAP_F1_MIN = 0.95
ATE_RMS_MAX_M = 0.05
ATE_MAX_LIMIT_M = 0.5
AMCL_RMS_MAX_M = 0.05
WORLDS_FRACTION = 0.95
GOAL_RATE_MIN = 0.98
#: The sets mapped, localized on and navigated (not the clutter sets: BARN's task has no map).
SUITE_SETS = sorted(name for name in SETS if not name.startswith("clutter"))
WHEEL_SLIP = 0.01


def suite_spec(sets: list[str], goals: int, wanted: set[str] | None = None) -> dict[str, Any]:
    """The suite as a batch spec (:mod:`pppbot_eval.batch`): per world, SLAM, then AMCL and navigation
    on the map SLAM saved, whose frame is the spawn pose (the coverage route's start)."""
    runs: list[dict[str, Any]] = []
    for name in sets:
        specs = [s for s in SETS[name] if wanted is None or generate(s.family, s.seed, small=s.small).name in wanted]
        families = list(dict.fromkeys(s.family for s in specs))
        whole = wanted is None and len({s.small for s in specs}) == 1 and len(specs) == len(families) * len(
            {s.seed for s in specs})
        worlds = ([{"family": [f.value for f in families], "seed": sorted({s.seed for s in specs}),
                    **({"small": True} if specs[0].small else {})}] if whole
                  else [{"family": s.family.value, "seed": s.seed, **({"small": True} if s.small else {})}
                        for s in specs])
        runs += [{"world": world, "seed": "${world.seed}", "steps": suite_steps(goals)} for world in worlds]
    return {"defaults": {"lockstep": True, "wheel_slip": WHEEL_SLIP, "view": False}, "runs": runs}


def suite_steps(goals: int) -> list[dict[str, Any]]:
    on_map = {"map": "${slam.map}", "map_pose": "${slam.start}"}
    return [{"scenario": "slam"}, {"scenario": "localization", **on_map},
            {"scenario": "navigation", **on_map, "start": "${slam.start}", "goals": goals}]


def _report(out: Path, world: str, stage: str, failures: dict[str, str]) -> dict[str, Any]:
    """A stage's report, or why there is none (the batch's summary says: e.g. no SLAM map)."""
    try:
        return dict(json.loads((out / world / stage / "report.json").read_text()))
    except (OSError, ValueError):
        return {"ok": False, "failure": failures.get(f"{world}/{stage}", "no report")}


def world_figures(spec: WorldSpec, out: Path, failures: dict[str, str]) -> dict[str, Any]:
    """SLAM, AMCL on its map, navigation on its map in one world: the figures of each stage."""
    layout = generate(spec.family, spec.seed, small=spec.small)
    route = load_routes(routes_file(out / "worlds" / f"{layout.name}.sdf"))[0] if (
        out / "worlds" / f"{layout.name}.sdf").is_file() else None
    figures: dict[str, Any] = {"world": layout.name, "family": spec.family.value, "seed": spec.seed,
                               "route_length_m": round(route.length_m, 1) if route else None, "loops": layout.loops}
    slam = _report(out, layout.name, "slam", failures)
    figures["slam"] = {k: _round(slam.get(k)) for k in
                       ("ok", "failure", "map_f1", "map_precision", "map_recall", "ate_rms_m", "ate_max_m",
                        "ate_yaw_rms_rad", "collisions", "closures", "false_closures", "false_claims",
                        "closure_max_error_m",
                        "sim_seconds", "wall_seconds", "real_time_factor")}
    health = slam.get("slam_health") or {}
    figures["slam"]["health"] = {k: health.get(k) for k in ("keyframes", "loop_closures", "rejected_closures",
                                                            "undone_closures", "degenerate_matches", "recoveries",
                                                            "lost", "keyframes_left_out", "largest_correction_m")}
    _say(layout.name, "slam", figures["slam"], ("map_f1", "ate_rms_m", "ate_max_m"))
    localization = _report(out, layout.name, "localization", failures)
    figures["localization"] = {k: _round(localization.get(k)) for k in
                               ("ok", "failure", "converged", "converged_after_m", "amcl_rms_m", "amcl_max_m",
                                "amcl_yaw_rms_rad", "collisions", "sim_seconds", "wall_seconds")}
    _say(layout.name, "localization", figures["localization"], ("amcl_rms_m", "amcl_max_m"))
    navigation = _report(out, layout.name, "navigation", failures)
    results = navigation.get("goal_results") or []
    figures["navigation"] = {**{k: _round(navigation.get(k)) for k in
                                ("ok", "failure", "success_rate", "collisions", "ate_rms_m", "sim_seconds",
                                 "wall_seconds")},
                             "goals": len(results), "reached": sum(bool(r["reached"]) for r in results)}
    _say(layout.name, "navigation", figures["navigation"], ("reached", "goals", "collisions"))
    return figures


def _round(value: Any, digits: int = 4) -> Any:
    return round(value, digits) if isinstance(value, float) else value


def _say(world: str, stage: str, figures: dict[str, Any], keys: tuple[str, ...]) -> None:
    shown = ", ".join(f"{k} {figures.get(k)}" for k in keys)
    status = "ok" if figures.get("ok") else f"FAILED: {figures.get('failure')}"
    print(f"{world:>24} {stage:<12} {shown}; {figures.get('wall_seconds')} s wall; {status}", file=sys.stderr,
          flush=True)


def _get(world: dict[str, Any], stage: str, key: str) -> Any:
    value = world.get(stage, {}).get(key)
    return None if isinstance(value, float) and not math.isfinite(value) else value


def map_good(world: dict[str, Any]) -> bool:
    """The world's SLAM met the map and trajectory targets (F1 and ATE RMS)."""
    f1, ate = _get(world, "slam", "map_f1"), _get(world, "slam", "ate_rms_m")
    return f1 is not None and ate is not None and f1 >= MAP_F1_MIN and ate <= ATE_RMS_MAX_M


def amcl_good(world: dict[str, Any]) -> bool:
    rms = _get(world, "localization", "amcl_rms_m")
    return bool(_get(world, "localization", "converged")) and rms is not None and rms <= AMCL_RMS_MAX_M


def aggregate(worlds: list[dict[str, Any]]) -> dict[str, Any]:
    """The set's figures: how many worlds met each target, the goals, and the targets met or not."""
    n = len(worlds)
    goals = sum(_get(w, "navigation", "goals") or 0 for w in worlds)
    reached = sum(_get(w, "navigation", "reached") or 0 for w in worlds)
    collisions = sum((_get(w, s, "collisions") or 0) for w in worlds for s in STAGES)
    false_closures = sum(_get(w, "slam", "false_closures") or 0 for w in worlds)
    ate_max = [_get(w, "slam", "ate_max_m") for w in worlds]
    over = [w["world"] for w, a in zip(worlds, ate_max, strict=True) if a is None or a > ATE_MAX_LIMIT_M]
    figures: dict[str, Any] = {
        "worlds": n,
        "map_good_fraction": _fraction(sum(map(map_good, worlds)), n),
        "map_f1_min": _min(_get(w, "slam", "map_f1") for w in worlds),
        "map_f1_median": _median(_get(w, "slam", "map_f1") for w in worlds),
        "ate_rms_m_median": _median(_get(w, "slam", "ate_rms_m") for w in worlds),
        "ate_max_m_max": _max(ate_max),
        "worlds_ate_max_over_limit": over,
        "amcl_good_fraction": _fraction(sum(map(amcl_good, worlds)), n),
        "amcl_rms_m_median": _median(_get(w, "localization", "amcl_rms_m") for w in worlds),
        "goals": goals, "goals_reached": reached, "goal_rate": _fraction(reached, goals),
        "collisions": collisions, "false_closures": false_closures,
        "wall_seconds": round(sum((_get(w, s, "wall_seconds") or 0.0) for w in worlds for s in STAGES), 1),
    }
    figures["targets"] = {
        "map_f1_and_ate_rms": _target(figures["map_good_fraction"], WORLDS_FRACTION, lambda v, t: v >= t),
        "no_ate_max_over_0.5_m": {"value": len(over), "target": 0, "met": not over},
        "amcl_rms": _target(figures["amcl_good_fraction"], WORLDS_FRACTION, lambda v, t: v >= t),
        "goal_rate": _target(figures["goal_rate"], GOAL_RATE_MIN, lambda v, t: v >= t),
        "collisions": {"value": collisions, "target": 0, "met": collisions == 0},
        "no_false_closures": {"value": false_closures, "target": 0, "met": false_closures == 0},
    }
    return figures


def _target(value: float | None, target: float, ok: Callable[[float, float], bool]) -> dict[str, Any]:
    return {"value": value, "target": target, "met": value is not None and ok(value, target)}


def _fraction(count: int, total: int) -> float | None:
    return round(count / total, 4) if total else None


def _values(values: Any) -> list[float]:
    return sorted(float(v) for v in values if v is not None)


def _min(values: Any) -> float | None:
    v = _values(values)
    return round(v[0], 4) if v else None


def _max(values: Any) -> float | None:
    v = _values(values)
    return round(v[-1], 4) if v else None


def _median(values: Any) -> float | None:
    v = _values(values)
    return round(v[len(v) // 2] if len(v) % 2 else (v[len(v) // 2 - 1] + v[len(v) // 2]) / 2, 4) if v else None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--set", dest="sets", action="append", choices=SUITE_SETS,
                        help="a set of worlds (repeatable; default tune and held_out; the clutter worlds are "
                             "crossed without a map: benchmarks/batches/clutter_*.yaml)")
    parser.add_argument("--worlds", default=None, help="only these worlds of the sets (comma-separated names)")
    parser.add_argument("--goals", type=int, default=10, help="navigation goals per world (default 10)")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help=f"output folder (default {DEFAULT_OUT})")
    parser.add_argument("--resume", action="store_true", help="keep the runs in --out that have a report")
    parser.add_argument("--workers", type=int, default=None,
                        help="worlds at once on this machine (default: the batch's, one per 2 cores)")
    parser.add_argument("--ray", default=None, metavar="ADDRESS", help="run on a Ray cluster (pppbot eval batch --ray)")
    args = parser.parse_args(argv)
    if args.goals < 1:
        parser.error(f"--goals {args.goals}: must be at least 1")
    sets = args.sets or ["tune", "held_out"]
    wanted = None if args.worlds is None else set(args.worlds.split(","))
    if wanted is not None:
        known = {generate(s.family, s.seed, small=s.small).name for name in sets for s in SETS[name]}
        if wanted - known:
            parser.error(f"--worlds: {', '.join(sorted(wanted - known))} not in the sets {', '.join(sets)} "
                         f"(they have {', '.join(sorted(known))})")
    if args.out.exists() and any(args.out.iterdir()) and not args.resume:
        parser.error(f"--out {args.out}: exists and is not empty; --resume goes on with it")
    os.environ.setdefault("MUJOCO_GL", "egl")
    args.out.mkdir(parents=True, exist_ok=True)
    spec_file = args.out / "suite.batch.yaml"
    spec_file.write_text(yaml.safe_dump(suite_spec(sets, args.goals, wanted), sort_keys=False))
    started = time.monotonic()
    batch = [PPPBOT, "eval", "batch", str(spec_file), "--out", str(args.out), "--resume",
             *(["--workers", str(args.workers)] if args.workers else []), *(["--ray", args.ray] if args.ray else [])]
    proc = subprocess.Popen(batch, stdout=sys.stderr)  # its table and summary: stderr; ours: stdout
    try:
        code = proc.wait()
    except KeyboardInterrupt:  # Ctrl-C: the batch stops every stack and writes its summary
        proc.send_signal(signal.SIGINT)
        code = proc.wait()
    if code not in (0, 1):
        return code  # interrupted (130; --resume goes on), or a bad spec or flag (2)
    failures = json.loads((args.out / "summary.json").read_text()).get("failures", {})
    result: dict[str, Any] = {"wheel_slip": WHEEL_SLIP, "goals_per_world": args.goals, "lockstep": True, "sets": {}}
    for name in sets:
        worlds = [world_figures(spec, args.out, failures) for spec in SETS[name]
                  if wanted is None or generate(spec.family, spec.seed, small=spec.small).name in wanted]
        families: dict[str, list[dict[str, Any]]] = {}
        for world in worlds:
            families.setdefault(world["family"], []).append(world)
        result["sets"][name] = {"aggregate": aggregate(worlds),
                                "families": {f: aggregate(ws) for f, ws in families.items()},
                                "worlds": worlds}
        print(f"{name}: {json.dumps(result['sets'][name]['aggregate'])}", file=sys.stderr)
    result["wall_seconds"] = round(time.monotonic() - started, 1)
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
