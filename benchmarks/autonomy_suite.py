"""The autonomy suite: SLAM, then AMCL on the SLAM map, then navigation, across generated worlds.

For each world of a set (:mod:`benchmarks.worldgen`: ``tune``, ``held_out``, ``ci``) it

1. writes the world and its coverage route (the generator is seeded: the same world on
   every machine);
2. ``pppbot eval slam``: maps the world along the coverage route; the report holds the
   trajectory error (ATE) and the map's quality against the world (F1), and the map is
   saved as Nav2 YAML + PGM;
3. ``pppbot eval localization --map <that map>``: AMCL on the SLAM map along the same
   route, from an initial pose 0.5 m and 0.3 rad off;
4. ``pppbot eval navigation --map <that map>``: ``--goals`` random reachable goals sent
   to ``navigate_to_pose``, judged on ground truth.

Every run is in lockstep with wheel slip 0.01 and the default parameters, so the figures
are the same on any machine; only the wall time differs. It prints one line per world
and stage on stderr, and the per-world and aggregate figures (per set, per family, and
against the issue's targets) as one JSON object on the last line of stdout. Each stage's
own report stays in ``--out/<world>/<stage>/``; ``--resume`` reuses the reports already
there, so an interrupted suite picks up where it stopped.

    ./pppbot env python benchmarks/autonomy_suite.py --set tune [--set held_out] [--goals 10]
                                                     [--worlds maze_000,hall_001] [--out DIR] [--resume]

The worlds of ``held_out`` are never tuned on: report them separately (the aggregate is
per set).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, NoReturn

sys.path.insert(0, str(Path(__file__).resolve().parent))

from worldgen import SETS, WorldSpec, write_world  # noqa: E402  (a sibling script)

from pppbot_common.dds_isolation import isolate_dds  # noqa: E402
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
WHEEL_SLIP = 0.01


def run_stage(stage: str, world_file: Path, out: Path, arguments: list[str], resume: bool) -> dict[str, Any]:
    """One ``pppbot eval`` run and its report (from ``out/report.json``; reused with ``resume``).

    A run that wrote no report (it could not start) gives ``{"ok": False, "failure": ...}``.
    """
    report_file = out / "report.json"
    if resume and report_file.is_file():
        report = dict(json.loads(report_file.read_text()))
        if report.get("failure") != "interrupted":
            return report
    shutil.rmtree(out, ignore_errors=True)  # an earlier, unfinished or replaced run
    command = [PPPBOT, "eval", stage, "--world", str(world_file), "--lockstep", "--wheel-slip", str(WHEEL_SLIP),
               "--out", str(out), "--json", "--no-view", *arguments]
    proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        _, stderr = proc.communicate()
    except KeyboardInterrupt:
        # Ctrl-C: the eval (in the same process group) stops its stack and writes its report;
        # killing it instead would leave the stack's nodes running. Signalled alone, the
        # suite passes the interrupt on.
        proc.send_signal(signal.SIGINT)
        proc.wait()
        _stop_interrupted(stage, world_file, out)
    if not report_file.is_file():
        tail = stderr.strip().splitlines()[-5:]
        return {"ok": False, "failure": f"eval {stage} exited {proc.returncode} without a report: "
                                        + " | ".join(tail)}
    report = dict(json.loads(report_file.read_text()))
    if report.get("failure") == "interrupted":  # the eval alone was signalled: the suite stops too
        _stop_interrupted(stage, world_file, out)
    return report


def _stop_interrupted(stage: str, world_file: Path, out: Path) -> NoReturn:
    """End the suite after an interrupted stage, whose output is no result: --resume runs it again."""
    shutil.rmtree(out, ignore_errors=True)
    raise SystemExit(f"autonomy_suite: eval {stage} in {world_file.stem} was interrupted; --resume goes on from there")


def _round(value: Any, digits: int = 4) -> Any:
    return round(value, digits) if isinstance(value, float) else value


def run_world(spec: WorldSpec, out: Path, goals: int, resume: bool) -> dict[str, Any]:
    """SLAM, AMCL on its map, navigation on its map in one world: the figures of each stage."""
    layout = generate(spec.family, spec.seed, small=spec.small)
    world_file, summary = write_world(layout, out / "worlds")
    route = load_routes(routes_file(world_file))[0]
    start = [f"{v:.6f}" for v in route.start]  # the spawn pose: where the SLAM map's frame is
    figures: dict[str, Any] = {"world": layout.name, "family": spec.family.value, "seed": spec.seed,
                               "route_length_m": summary["route_length_m"], "loops": summary["loops"]}
    here = out / layout.name
    slam = run_stage("slam", world_file, here / "slam", ["--seed", str(spec.seed)], resume)
    figures["slam"] = {k: _round(slam.get(k)) for k in
                       ("ok", "failure", "map_f1", "map_precision", "map_recall", "ate_rms_m", "ate_max_m",
                        "ate_yaw_rms_rad", "collisions", "sim_seconds", "wall_seconds", "real_time_factor")}
    health = slam.get("slam_health") or {}
    figures["slam"]["health"] = {k: health.get(k) for k in ("keyframes", "loop_closures", "rejected_closures",
                                                            "undone_closures", "degenerate_matches", "recoveries",
                                                            "lost", "keyframes_left_out", "largest_correction_m")}
    _say(layout.name, "slam", figures["slam"], ("map_f1", "ate_rms_m", "ate_max_m"))
    map_file = slam.get("map")
    if not map_file or not Path(map_file).is_file():
        figures["localization"] = figures["navigation"] = {"ok": False, "failure": "no SLAM map"}
        return figures
    localization = run_stage("localization", world_file, here / "localization",
                             ["--seed", str(spec.seed), "--map", map_file, "--map-pose", *start], resume)
    figures["localization"] = {k: _round(localization.get(k)) for k in
                               ("ok", "failure", "converged", "converged_after_m", "amcl_rms_m", "amcl_max_m",
                                "amcl_yaw_rms_rad", "collisions", "sim_seconds", "wall_seconds")}
    _say(layout.name, "localization", figures["localization"], ("amcl_rms_m", "amcl_max_m"))
    navigation = run_stage("navigation", world_file, here / "navigation",
                           ["--seed", str(spec.seed), "--map", map_file, "--map-pose", *start, "--start", *start,
                            "--goals", str(goals)], resume)
    results = navigation.get("goal_results") or []
    figures["navigation"] = {**{k: _round(navigation.get(k)) for k in
                                ("ok", "failure", "success_rate", "collisions", "ate_rms_m", "sim_seconds",
                                 "wall_seconds")},
                             "goals": len(results), "reached": sum(bool(r["reached"]) for r in results)}
    _say(layout.name, "navigation", figures["navigation"], ("reached", "goals", "collisions"))
    return figures


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
        "collisions": collisions,
        "wall_seconds": round(sum((_get(w, s, "wall_seconds") or 0.0) for w in worlds for s in STAGES), 1),
    }
    figures["targets"] = {
        "map_f1_and_ate_rms": _target(figures["map_good_fraction"], WORLDS_FRACTION, lambda v, t: v >= t),
        "no_ate_max_over_0.5_m": {"value": len(over), "target": 0, "met": not over},
        "amcl_rms": _target(figures["amcl_good_fraction"], WORLDS_FRACTION, lambda v, t: v >= t),
        "goal_rate": _target(figures["goal_rate"], GOAL_RATE_MIN, lambda v, t: v >= t),
        "collisions": {"value": collisions, "target": 0, "met": collisions == 0},
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
    parser.add_argument("--set", dest="sets", action="append", choices=sorted(SETS),
                        help="a set of worlds (repeatable; default tune and held_out)")
    parser.add_argument("--worlds", default=None, help="only these worlds of the sets (comma-separated names)")
    parser.add_argument("--goals", type=int, default=10, help="navigation goals per world (default 10)")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help=f"output folder (default {DEFAULT_OUT})")
    parser.add_argument("--resume", action="store_true", help="reuse the stage reports already in --out")
    args = parser.parse_args(argv)
    if args.goals < 1:
        parser.error(f"--goals {args.goals}: must be at least 1")
    sets = args.sets or ["tune", "held_out"]
    wanted = None if args.worlds is None else set(args.worlds.split(","))
    # Each world's name, generated once (only to filter by --worlds: run_world generates it again).
    names = {} if wanted is None else {s: generate(s.family, s.seed, small=s.small).name
                                       for name in sets for s in SETS[name]}
    if wanted is not None:
        known = set(names.values())
        if wanted - known:
            parser.error(f"--worlds: {', '.join(sorted(wanted - known))} not in the sets {', '.join(sets)} "
                         f"(they have {', '.join(sorted(known))})")
    isolate_dds()
    os.environ.setdefault("MUJOCO_GL", "egl")
    started = time.monotonic()
    result: dict[str, Any] = {"wheel_slip": WHEEL_SLIP, "goals_per_world": args.goals, "lockstep": True, "sets": {}}
    for name in sets:
        worlds = []
        for spec in SETS[name]:
            if wanted is not None and names[spec] not in wanted:
                continue
            worlds.append(run_world(spec, args.out, args.goals, args.resume))
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
