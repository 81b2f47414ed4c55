"""Navigation with Nav2's planner and controller plugins side by side: ppp_bot's choice (DWB +
NavFn), RPP + Smac 2D, and pppbot's default (RPP + pppbot's A*).

Each variant is ``config/nav2_params.yaml`` with its ``controller_server`` ``FollowPath`` and
``planner_server`` ``GridBased`` sections replaced (DWB's are ppp_bot's own values, from
``tests/data/ppp_bot/nav2_params.yaml``; RPP's pppbot's; NavFn's ppp_bot's; Smac 2D's Nav2's
defaults), and runs ``pppbot eval navigation --params-file`` in lockstep in each ``--worlds``
world: the same random goals for every variant (same seed), judged on ground truth. Prints a
line per run on stderr and, as its last line, one JSON object with every run's success rate,
collisions, mean time ratio (the time a goal took over the time its shortest path takes at the
robot's top speed: ``mean_time_ratio`` of the navigation report, docs/evaluation.md), mean path
ratio, closest clearance and wall time.

    ./pppbot env python benchmarks/nav2_plugins.py [--worlds room,maze] [--goals 10] [--out DIR]
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import yaml

from pppbot_common.dds_isolation import isolate_dds

ROOT = Path(__file__).resolve().parent.parent
PPPBOT = str(ROOT / "pppbot")
OURS = ROOT / "config" / "nav2_params.yaml"
PPP_BOT = ROOT / "tests" / "data" / "ppp_bot" / "nav2_params.yaml"
SMAC_2D = {"plugin": "nav2_smac_planner::SmacPlanner2D"}
METRICS = ("ok", "goals", "successes", "success_rate", "collisions", "mean_time_ratio", "mean_path_ratio",
           "mean_time_s", "min_clearance_m", "sim_seconds", "wall_seconds", "real_time_factor")


def variants() -> dict[str, dict[str, Any]]:
    """Each variant's ``FollowPath`` and ``GridBased`` sections."""
    ours = yaml.safe_load(OURS.read_text())
    ppp_bot = yaml.safe_load(PPP_BOT.read_text())
    rpp = ours["controller_server"]["ros__parameters"]["FollowPath"]
    dwb = ppp_bot["controller_server"]["ros__parameters"]["FollowPath"]
    navfn = ppp_bot["planner_server"]["ros__parameters"]["GridBased"]
    astar = ours["planner_server"]["ros__parameters"]["GridBased"]
    return {"dwb_navfn": {"FollowPath": dwb, "GridBased": navfn},
            "rpp_smac2d": {"FollowPath": rpp, "GridBased": SMAC_2D},
            "rpp_gridastar": {"FollowPath": rpp, "GridBased": astar}}


def write_variant(sections: dict[str, Any], path: Path) -> Path:
    params = yaml.safe_load(OURS.read_text())
    params["controller_server"]["ros__parameters"]["FollowPath"] = sections["FollowPath"]
    params["planner_server"]["ros__parameters"]["GridBased"] = sections["GridBased"]
    path.write_text(yaml.safe_dump(params, sort_keys=False))
    return path


def run(world: str, params_file: Path, goals: int, out: Path, extra: tuple[str, ...] = ()) -> dict[str, Any]:
    cmd = [PPPBOT, "eval", "navigation", "--world", world, "--goals", str(goals), "--params-file", str(params_file),
           "--out", str(out), "--no-view", "--json", "--min-success-rate", "0", *extra]
    t0 = time.monotonic()
    done = subprocess.run(cmd, capture_output=True, text=True, stdin=subprocess.DEVNULL, check=False)
    lines = done.stdout.strip().splitlines()
    try:
        report = json.loads(lines[-1])
    except (IndexError, json.JSONDecodeError):
        return {"ok": False, "failure": f"exit {done.returncode}: {done.stderr.strip()[-400:]}",
                "wall_seconds": round(time.monotonic() - t0, 1)}
    return {k: report.get(k) for k in METRICS} | {"failure": report.get("failure")}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--worlds", default="room,maze", help="comma-separated worlds (default room,maze)")
    parser.add_argument("--goals", type=int, default=10, help="goals per run (default 10)")
    parser.add_argument("--variants", default=",".join(variants()), help="which variants (default all)")
    parser.add_argument("--out", type=Path, default=None, help="where the runs' reports go (default a temp dir)")
    args = parser.parse_args()
    isolate_dds()
    out = args.out or Path(tempfile.mkdtemp(prefix="nav2_plugins_"))
    out.mkdir(parents=True, exist_ok=True)
    chosen = {name: v for name, v in variants().items() if name in args.variants.split(",")}
    results: dict[str, dict[str, Any]] = {}
    for name, sections in chosen.items():
        params = write_variant(sections, out / f"{name}.yaml")
        for world in args.worlds.split(","):
            figures = run(world, params, args.goals, out / f"{name}_{world}")
            results.setdefault(name, {})[world] = figures
            print(f"{name} {world}: {json.dumps(figures)}", file=sys.stderr, flush=True)
    print(json.dumps({"goals": args.goals, "worlds": args.worlds.split(","), "results": results, "out": str(out)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
