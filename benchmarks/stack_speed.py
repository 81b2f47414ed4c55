"""How fast the whole stack runs, and what each node costs: issue 20's figures.

Runs, one after the other in ``--world`` (default maze), on a DDS domain of its own:

* ``mapping``: ``pppbot eval slam`` in lockstep (simulator with the controller,
  robot_state_publisher and twist_mux, slam, the eval driver) — achieved real-time factor;
* ``navigation``: ``pppbot eval navigation`` in lockstep (simulator with robot_state_publisher
  and twist_mux, map_server and amcl composed in one process (``localization``), planner_server,
  controller_server and navigator in another (``navigation``), the eval) — achieved
  real-time factor and the peak RSS of all of them;
* ``navigation_1x``: the same without lockstep at 1× real time — the navigation nodes'
  CPU while they drive;
* ``idle_1x`` and ``idle_lockstep_1x``: ``launch_sim localization:=true`` at 1× with no goal,
  free running and in lockstep paced at 1× (``localization`` and ``navigation`` composed in
  both, launch_sim's default) — every node's CPU, and
  the bringup's memory: the sum of its processes' RSS (the issue's measure, which counts the
  libraries they share once per process) and of their PSS (each shared page counted once).

Each node's CPU share (% of one core, from /proc) and, in lockstep, the rounds per sync time
(from the simulator's log) are printed per run; one JSON object with every figure, its target
and whether it is met is the last line.

    ./pppbot env python benchmarks/stack_speed.py [--world maze] [--mapping-seconds 120] [--goals 3]
"""
from __future__ import annotations

import argparse
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

from pppbot_common.dds_isolation import isolate_dds
from pppbot_nav.lifecycle import NAVIGATION_NODES

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))
from proc_stats import TICKS, children, cpu_ticks, process_name, pss_mb, rss_mb  # noqa: E402 (beside this script)

PPPBOT = str(ROOT / "pppbot")
#: The navigation nodes' processes: composed (launch_sim's default) or each its own.
NAV_NODES = ("navigation", *NAVIGATION_NODES, "lifecycle_manager_navigation")
#: Issue 52's targets (the driving share is issue 20's).
TARGETS = {"mapping_rtf": 10.0, "navigation_rtf": 7.0, "nav_nodes_driving_1x_pct": 25.0,
           "nav_nodes_idle_1x_pct": 5.0, "bringup_idle_1x_pct": 15.0, "navigation_rss_mb": 550.0,
           "navigation_pss_mb": 550.0, "nav_nodes_idle_lockstep_1x_pct": 5.0, "bringup_idle_lockstep_1x_pct": 15.0,
           "navigation_lockstep_rss_mb": 550.0, "navigation_lockstep_pss_mb": 550.0}


class Sampler:
    """CPU per process name over a window, and the peak total RSS, of ``root``'s process tree."""

    def __init__(self, root: int) -> None:
        self.root = root
        self.peak_rss_mb = 0.0
        self._start: dict[int, tuple[str, int]] = {}
        self._last: dict[int, int] = {}
        self._t0 = 0.0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._watch_memory, daemon=True)
        self._thread.start()

    def _watch_memory(self) -> None:
        while not self._stop.wait(0.5):
            pids = [self.root, *children(self.root)]
            self.peak_rss_mb = max(self.peak_rss_mb, sum(rss_mb(p) for p in pids))
            for pid in pids:  # the last CPU seen: a process may be gone when the window ends
                self._last[pid] = max(self._last.get(pid, 0), cpu_ticks(pid))

    def begin(self) -> None:
        self._start = {p: (process_name(p), cpu_ticks(p)) for p in [self.root, *children(self.root)]}
        self._t0 = time.monotonic()

    def end(self) -> dict[str, float]:
        """% of one core per process name since :meth:`begin`."""
        wall = time.monotonic() - self._t0
        shares: dict[str, float] = {}
        for pid, (name, ticks) in self._start.items():
            used = max(cpu_ticks(pid), self._last.get(pid, 0)) - ticks
            if used >= 0:
                shares[name] = shares.get(name, 0.0) + round(100.0 * used / TICKS / wall, 1)
        return dict(sorted(shares.items(), key=lambda kv: -kv[1]))

    def close(self) -> None:
        self._stop.set()


def run_eval(scenario: str, args: list[str], domain: int) -> dict[str, Any]:
    """One ``pppbot eval`` run: its report, the CPU shares from its first progress line (the stack's
    start-up left out) to its end, and the peak memory of its process tree."""
    out = Path(tempfile.mkdtemp(prefix=f"stack_speed_{scenario}_"))
    env = {**os.environ, "ROS_DOMAIN_ID": str(domain)}
    proc = subprocess.Popen([PPPBOT, "eval", scenario, *args, "--no-view", "--out", str(out)], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    sampler = Sampler(proc.pid)
    lines: list[str] = []
    assert proc.stderr is not None
    for line in proc.stderr:  # the stack starts (its CPU is not the run's) until progress shows
        lines.append(line)
        if "%" in line:
            break
    sampler.begin()
    lines += proc.stderr.readlines()
    proc.wait()
    err = "".join(lines)
    shares = sampler.end()
    sampler.close()
    report_file = out / "report.json"
    if not report_file.is_file():
        raise SystemExit(f"stack_speed: eval {scenario} wrote no report:\n{err[-2000:]}")
    report = json.loads(report_file.read_text())
    return {"real_time_factor": round(float(report["real_time_factor"]), 2), "ok": bool(report.get("ok")),
            "sim_seconds": round(float(report["sim_seconds"]), 1), "cpu_pct": shares,
            "peak_rss_mb": round(sampler.peak_rss_mb), "rounds_per_sync_time": rounds_per_sync_time(out),
            "out": str(out)}


def rounds_per_sync_time(out: Path) -> float | None:
    """Lockstep rounds (a step and everyone's answer) per sync time, from the simulator's last speed
    line in the run's logs ("lockstep: N steps, M rounds", or a participant's leaving "so far: N steps,
    M rounds"); None when it logged none."""
    found = None
    for log in sorted((out / "logs").glob("simulator*.log")):
        for match in re.finditer(r"(\d+) steps, (\d+) rounds", log.read_text(errors="replace")):
            found = match
    return round(int(found.group(2)) / int(found.group(1)), 2) if found and int(found.group(1)) else None


def run_idle(world: str, seconds: float, domain: int, lockstep: bool = False) -> dict[str, Any]:
    """launch_sim with localization and navigation at 1× (free running, or lockstep paced at 1×;
    the navigation nodes one composed process), no goal: CPU per node over ``seconds``."""
    env = {**os.environ, "ROS_DOMAIN_ID": str(domain)}
    proc = subprocess.Popen([PPPBOT, "launch_sim", f"world:={world}", "localization:=true", "use_teleop:=false",
                             "use_rviz:=false", "use_viz:=false", "real_time_factor:=1.0",
                             f"lockstep:={str(lockstep).lower()}"],
                            env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    assert proc.stdout is not None
    deadline = time.monotonic() + 120
    for line in proc.stdout:
        if "is up in" in line or time.monotonic() > deadline:
            break
    threading.Thread(target=lambda: [None for _ in proc.stdout], daemon=True).start()  # type: ignore[union-attr]
    sampler = Sampler(proc.pid)
    time.sleep(5.0)
    sampler.begin()
    time.sleep(seconds)
    shares = sampler.end()
    pids = [proc.pid, *children(proc.pid)]
    rss, pss = sum(rss_mb(p) for p in pids), sum(pss_mb(p) for p in pids)
    sampler.close()
    proc.send_signal(signal.SIGINT)
    proc.wait(60)
    return {"cpu_pct": shares, "rss_mb": round(rss), "pss_mb": round(pss)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--world", default="maze")
    parser.add_argument("--mapping-seconds", type=float, default=120.0, help="sim seconds of mapping (timeout)")
    parser.add_argument("--goals", type=int, default=3)
    parser.add_argument("--idle-seconds", type=float, default=20.0)
    args = parser.parse_args()
    base = isolate_dds()
    figures: dict[str, Any] = {"world": args.world, "cores": os.cpu_count()}
    mapping = run_eval("slam", ["--world", args.world, "--timeout", str(args.mapping_seconds)], base)
    print(f"mapping (lockstep): {mapping}", file=sys.stderr)
    navigation = run_eval("navigation", ["--world", args.world, "--goals", str(args.goals)], base)
    print(f"navigation (lockstep): {navigation}", file=sys.stderr)
    driving = run_eval("navigation", ["--world", args.world, "--goals", str(args.goals), "--no-lockstep",
                                      "--real-time-factor", "1"], base)
    print(f"navigation at 1x: {driving}", file=sys.stderr)
    idle = run_idle(args.world, args.idle_seconds, base)
    print(f"idle at 1x: {idle}", file=sys.stderr)
    idle_lockstep = run_idle(args.world, args.idle_seconds, base, lockstep=True)
    print(f"idle in lockstep paced at 1x: {idle_lockstep}", file=sys.stderr)
    figures.update(
        mapping_rtf=mapping["real_time_factor"], navigation_rtf=navigation["real_time_factor"],
        nav_nodes_driving_1x_pct=round(sum(driving["cpu_pct"].get(n, 0.0) for n in NAV_NODES), 1),
        nav_nodes_idle_1x_pct=round(sum(idle["cpu_pct"].get(n, 0.0) for n in NAV_NODES), 1),
        bringup_idle_1x_pct=round(sum(v for k, v in idle["cpu_pct"].items() if k != "launch_sim"), 1),
        navigation_rss_mb=idle["rss_mb"], navigation_pss_mb=idle["pss_mb"],
        nav_nodes_idle_lockstep_1x_pct=round(sum(idle_lockstep["cpu_pct"].get(n, 0.0) for n in NAV_NODES), 1),
        bringup_idle_lockstep_1x_pct=round(sum(v for k, v in idle_lockstep["cpu_pct"].items() if k != "launch_sim"), 1),
        navigation_lockstep_rss_mb=idle_lockstep["rss_mb"], navigation_lockstep_pss_mb=idle_lockstep["pss_mb"],
        navigation_with_eval_peak_rss_mb=navigation["peak_rss_mb"],
        rounds_per_sync_time={"mapping": mapping["rounds_per_sync_time"],
                              "navigation": navigation["rounds_per_sync_time"]},
        cpu_pct={"mapping": mapping["cpu_pct"], "navigation": navigation["cpu_pct"],
                 "navigation_1x": driving["cpu_pct"], "idle_1x": idle["cpu_pct"],
                 "idle_lockstep_1x": idle_lockstep["cpu_pct"]})
    # A figure from a run that failed (a goal unanswered, the robot stuck) is no figure: say so.
    # (Mapping stops at --mapping-seconds, before its route's end: it counts when it got there.)
    figures["runs_ok"] = {"mapping": mapping["ok"] or mapping["sim_seconds"] >= 0.95 * args.mapping_seconds,
                          "navigation": navigation["ok"], "navigation_1x": driving["ok"]}
    figures["targets"] = TARGETS
    figures["met"] = {k: (figures[k] >= t if k.endswith("_rtf") else figures[k] <= t) for k, t in TARGETS.items()}
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
