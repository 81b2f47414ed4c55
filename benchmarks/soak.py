"""Hours of navigation: does memory creep, CPU climb, or a process leak file descriptors?

Runs ``pppbot eval navigation`` in lockstep (random reachable goals, one after the other) on a
DDS domain of its own until ``--sim-minutes`` of sim time have passed, and samples every process
of the stack (by name: simulator, localization, navigation, the eval) every ``--sample-s`` sim
seconds: RSS, CPU time and open file descriptors, from /proc.

After the first ``--warmup-minutes`` (10) of sim time, each process's RSS is fitted with a line
against sim time: its growth per sim hour, in MB and in % of its RSS at the end of the warm-up
(target ≤ 2 %); its descriptors at the end against the end of the warm-up (target: no growth);
its CPU share over the whole run after the warm-up (% of one core against the wall clock).

    ./pppbot env python benchmarks/soak.py --sim-minutes 120       # the record (about 25 min here)
    ./pppbot env python benchmarks/soak.py --sim-minutes 15 --warmup-minutes 3
    ./pppbot env python benchmarks/soak.py --sim-minutes 40 --trace-memory /tmp/soak_trace
    ./pppbot env python benchmarks/soak.py --sim-minutes 30 --samples-csv /tmp/soak.csv   # every sample

``--trace-memory FOLDER`` finds what grows: every process of the stack traces its Python
allocations (:func:`pppbot_common.process.trace_memory_if_asked`; much slower), writes a snapshot
at the end of the warm-up and at the end of the run into FOLDER, and the growth between them is
printed per process, the biggest sources first (memory allocated by C libraries is not traced).

Prints a line per sim minute and, last, one JSON object with every figure and whether each
target is met.
"""
from __future__ import annotations

import argparse
import csv
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
import tracemalloc
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from proc_stats import TICKS, catches, children, cpu_ticks, open_files, process_name, rss_mb  # noqa: E402 (beside this script)

from pppbot_common.dds_isolation import isolate_dds  # noqa: E402
from pppbot_common.process import MEMORY_SNAPSHOT_SIGNAL, TRACE_MEMORY_ENV  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
PPPBOT = str(ROOT / "pppbot")
TARGETS = {"rss_growth_pct_per_sim_hour": 2.0, "fd_growth": 0}
SIM_TIME = re.compile(r"sim\s+(\d+(?:\.\d+)?) s")


def parse_arguments(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--world", default="room")
    parser.add_argument("--sim-minutes", type=float, default=120.0, help="sim time to run (default 120)")
    parser.add_argument("--warmup-minutes", type=float, default=10.0,
                        help="sim time left out of the growth fits (default 10)")
    parser.add_argument("--sample-s", type=float, default=30.0, help="sim seconds between samples (default 30)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--samples-csv", type=Path, metavar="FILE",
                        help="write every sample (sim s, process, RSS MB, CPU ticks, descriptors) to FILE")
    parser.add_argument("--trace-memory", type=Path, metavar="FOLDER",
                        help="trace Python allocations; print what grew after the warm-up, per process")
    args = parser.parse_args(argv)
    if not 0 < args.warmup_minutes < args.sim_minutes:
        parser.error("--warmup-minutes must be above 0 and below --sim-minutes")
    return args


def sample(root: int) -> dict[str, dict[str, float]]:
    """Per process name (summed over processes of one name): RSS MB, CPU ticks, open descriptors."""
    by_name: dict[str, dict[str, float]] = {}
    for pid in [root, *children(root)]:
        name = process_name(pid)
        if name in ("bash", "sh", "?"):
            continue
        row = by_name.setdefault(name, {"rss_mb": 0.0, "cpu_ticks": 0.0, "fds": 0.0})
        row["rss_mb"] += rss_mb(pid)
        row["cpu_ticks"] += cpu_ticks(pid)
        row["fds"] += open_files(pid)
    return by_name


def kept_tail(tail: list[str], line: str, keep: int = 40) -> list[str]:
    """The last ``keep`` lines with ``line`` added, a bar redrawn unchanged kept once (a run that
    hangs redraws it until it ends, and its last words came before)."""
    if tail and tail[-1] == line:
        return tail
    return (tail + [line])[-keep:]


def terminal_lines(fd: int) -> Iterator[str]:
    """The lines (and progress-bar redraws) a child writes to the terminal ``fd``, until it closes."""
    pending = b""
    while True:
        try:
            chunk = os.read(fd, 65536)
        except OSError:  # EIO: every writer has closed it
            chunk = b""
        if not chunk:
            break
        *whole, pending = re.split(rb"[\r\n]+", pending + chunk)
        yield from (line.decode(errors="replace") for line in whole if line)
    os.close(fd)
    if pending:
        yield pending.decode(errors="replace")


def growth(samples: list[tuple[float, float, dict[str, dict[str, float]]]], warmup_s: float) -> dict[str, Any]:
    """Per process: RSS growth per sim hour after the warm-up (a least-squares line), descriptor growth, CPU."""
    after = [s for s in samples if s[0] >= warmup_s]
    if len(after) < 3:
        raise SystemExit(f"soak: only {len(after)} samples after the warm-up; run longer")
    first, last = after[0], after[-1]
    results: dict[str, Any] = {}
    for name in sorted(set(first[2]) & set(last[2])):
        series = [(s[0], s[2][name]) for s in after if name in s[2]]
        t_h = np.array([t for t, _ in series]) / 3600.0
        rss = np.array([row["rss_mb"] for _, row in series])
        slope_mb_h = float(np.polyfit(t_h, rss, 1)[0])
        wall = last[1] - first[1]
        cpu = 100.0 * (last[2][name]["cpu_ticks"] - first[2][name]["cpu_ticks"]) / TICKS / max(wall, 1e-6)
        results[name] = {
            "rss_mb_at_warmup": round(float(rss[0]), 1), "rss_mb_at_end": round(float(rss[-1]), 1),
            "rss_growth_mb_per_sim_hour": round(slope_mb_h, 2),
            "rss_growth_pct_per_sim_hour": round(100.0 * slope_mb_h / max(float(rss[0]), 1e-6), 2),
            "fds_at_warmup": int(first[2][name]["fds"]), "fds_at_end": int(last[2][name]["fds"]),
            "fd_growth": int(last[2][name]["fds"] - first[2][name]["fds"]),
            "cpu_pct": round(cpu, 1)}
    return results


def write_samples(samples: list[tuple[float, float, dict[str, dict[str, float]]]], path: Path) -> None:
    """The samples as CSV: a row per sample and process."""
    with path.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["sim_s", "wall_s", "process", "rss_mb", "cpu_ticks", "fds"])
        for sim_s, wall_s, by_name in samples:
            for name, row in sorted(by_name.items()):
                writer.writerow([f"{sim_s:.1f}", f"{wall_s - samples[0][1]:.1f}", name, f"{row['rss_mb']:.2f}",
                                 int(row["cpu_ticks"]), int(row["fds"])])


def snapshot_memory(root: int, folder: Path, timeout_s: float = 120.0) -> None:
    """Ask every traced process of the stack for a snapshot of its allocations, and wait until each
    has begun writing it (a process finishes writing before it acts on a later stop signal)."""
    before = len(list(folder.glob("*.tracemalloc")))
    traced = [pid for pid in children(root) if catches(pid, MEMORY_SNAPSHOT_SIGNAL)]
    for pid in traced:
        os.kill(pid, MEMORY_SNAPSHOT_SIGNAL)
    deadline = time.monotonic() + timeout_s
    while len(list(folder.glob("*.tracemalloc"))) < before + len(traced) and time.monotonic() < deadline:
        time.sleep(0.5)


def memory_growth(folder: Path, top: int = 12) -> dict[str, list[str]]:
    """Per traced process: the source lines whose allocations grew most from its first snapshot
    to its last (KB, count)."""
    grown: dict[str, list[str]] = {}
    for first in sorted(folder.glob("*-000.tracemalloc")):
        name_pid = first.name.rsplit("-", 1)[0]
        last = sorted(folder.glob(f"{name_pid}-*.tracemalloc"))[-1]
        if last == first:
            continue
        stats = tracemalloc.Snapshot.load(str(last)).compare_to(tracemalloc.Snapshot.load(str(first)), "traceback")
        grown[name_pid] = [f"{s.size_diff / 1024:+.0f} KB in {s.count_diff:+d} blocks: "
                           + " < ".join(f"{Path(f.filename).name}:{f.lineno}" for f in s.traceback)
                           for s in stats[:top]]
    return grown


def main(argv: list[str] | None = None) -> int:
    args = parse_arguments(argv)
    isolate_dds()
    out = Path(tempfile.mkdtemp(prefix="soak_"))
    goals = int(args.sim_minutes * 6) + 10  # more than the time allows: the run is stopped by sim time
    cmd = [PPPBOT, "eval", "navigation", "--world", args.world, "--goals", str(goals), "--seed", str(args.seed),
           "--timeout", str(args.sim_minutes * 60 * 2), "--min-success-rate", "0", "--no-view", "--out", str(out)]
    env = dict(os.environ)
    if args.trace_memory:
        args.trace_memory.mkdir(parents=True, exist_ok=True)
        env[TRACE_MEMORY_ENV] = str(args.trace_memory.resolve())
    # Its progress goes to a terminal of ours, so it redraws its bar (and the sim time) every
    # 0.2 s: without one it prints a line every 10 % of its goals, too seldom to sample by.
    terminal, their_end = os.openpty()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=their_end, env=env)
    os.close(their_end)
    output = terminal_lines(terminal)
    samples: list[tuple[float, float, dict[str, dict[str, float]]]] = []
    next_sample, next_line, sim_s, started = 0.0, 60.0, 0.0, time.monotonic()
    snapshot_at = [args.warmup_minutes * 60] if args.trace_memory else []
    tail: list[str] = []
    for line in output:
        tail = kept_tail(tail, line)
        found = SIM_TIME.findall(line)
        if not found:
            continue
        sim_s = float(found[-1])
        if sim_s >= next_sample:
            samples.append((sim_s, time.monotonic(), sample(proc.pid)))
            next_sample = sim_s + args.sample_s
        if sim_s >= next_line:
            total = sum(row["rss_mb"] for row in samples[-1][2].values())
            print(f"sim {sim_s / 60:5.1f} min, {sim_s / (time.monotonic() - started):4.1f}x, RSS {total:6.0f} MB",
                  flush=True)
            next_line += 60.0
        if snapshot_at and sim_s >= snapshot_at[0]:
            snapshot_memory(proc.pid, args.trace_memory)
            snapshot_at.pop(0)
        if sim_s >= args.sim_minutes * 60:
            if args.trace_memory:
                snapshot_memory(proc.pid, args.trace_memory)
            proc.send_signal(signal.SIGINT)  # the eval stops its stack cleanly
            break
    for line in output:  # read on while it stops: a terminal nobody reads would block its last writes
        tail = kept_tail(tail, line)
    code = proc.wait()
    if sim_s < args.sim_minutes * 60:
        raise SystemExit(f"soak: the run ended at sim {sim_s:.0f} s (exit {code}):\n" + "\n".join(tail))
    if args.samples_csv:
        write_samples(samples, args.samples_csv)
    processes = growth(samples, args.warmup_minutes * 60)
    stack = {n: r for n, r in processes.items() if n != "eval"}
    worst_rss = max(r["rss_growth_pct_per_sim_hour"] for r in stack.values())
    worst_fd = max(r["fd_growth"] for r in stack.values())
    if args.trace_memory:
        for name_pid, lines in memory_growth(args.trace_memory).items():
            print(f"{name_pid}: Python allocations grown after the warm-up", *lines, sep="\n  ")
    print(json.dumps({
        "world": args.world, "sim_minutes": args.sim_minutes, "warmup_minutes": args.warmup_minutes,
        "wall_minutes": round((time.monotonic() - started) / 60, 1), "samples": len(samples),
        "processes": processes, "worst_rss_growth_pct_per_sim_hour": worst_rss, "worst_fd_growth": worst_fd,
        "targets": TARGETS, "targets_met": {"rss_growth_pct_per_sim_hour": worst_rss <= TARGETS[
            "rss_growth_pct_per_sim_hour"], "fd_growth": worst_fd <= TARGETS["fd_growth"]}}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
