"""How many scenarios an hour ``pppbot eval batch`` runs here, and what one run costs.

Runs one batch (``--runs`` navigations in ``--world`` with ``--goals`` goals each, seeds 0, 1, ...;
or ``--scenario slam`` with ``--timeout`` sim seconds) once per worker count in ``--workers``
(default 1 and 2), each into a folder of its own, and measures per batch: the wall time, the
scenarios per hour, the CPU all its processes used (cores busy on average, from the batch's
children's rusage), and the peak memory of its process tree (summed RSS, sampled twice a second).
With one worker the CPU and memory are one run's: what to reserve per run on a cluster. The
batches' reports must agree (lockstep): a disagreement is printed and fails the run. One JSON
object with every figure is the last line of stdout.

    ./pppbot env python benchmarks/batch_speed.py [--runs 4] [--workers 1 2] [--world maze] [--goals 3]
"""
from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from stack_speed import _children, _rss_mb  # noqa: E402  (a sibling script)

from pppbot_common.dds_isolation import isolate_dds  # noqa: E402
from pppbot_eval.batch_summary import comparable_reports  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
PPPBOT = str(ROOT / "pppbot")


def spec_text(args: argparse.Namespace) -> str:
    flags = {"navigation": f"goals: {args.goals}", "slam": f"timeout: {args.timeout}"}[args.scenario]
    return (f"runs:\n  - scenario: {args.scenario}\n    world: {args.world}\n    seed: {list(range(args.runs))}\n"
            f"    {flags}\n")


def _children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run_batch(spec: Path, out: Path, workers: int) -> dict[str, Any]:
    """One batch with ``workers``: its summary and what it cost."""
    cpu0, wall0 = _children_cpu_s(), time.monotonic()
    proc = subprocess.Popen([PPPBOT, "eval", "batch", str(spec), "--out", str(out), "--workers", str(workers)],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    peak = [0.0]
    done = threading.Event()

    def sample() -> None:
        while not done.wait(0.5):
            peak[0] = max(peak[0], sum(_rss_mb(p) for p in [proc.pid, *_children(proc.pid)]))
    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    stdout, _ = proc.communicate()
    done.set()
    sampler.join()
    wall, cpu = time.monotonic() - wall0, _children_cpu_s() - cpu0
    summary = json.loads(stdout.strip().splitlines()[-1])
    return {"workers": workers, "runs": summary["runs"], "ok": summary["ok"], "exit_code": proc.returncode,
            "wall_seconds": round(wall, 1), "runs_per_hour": round(summary["runs"] * 3600 / wall, 1),
            "cores_busy": round(cpu / wall, 2), "cpu_seconds_per_run": round(cpu / max(summary["runs"], 1), 1),
            "peak_rss_mb": round(peak[0]), "sim_seconds": summary["overall"]["sim_seconds"]}




def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=4, help="scenarios in the batch (default 4)")
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2], help="worker counts (default 1 2)")
    parser.add_argument("--scenario", choices=("navigation", "slam"), default="navigation")
    parser.add_argument("--world", default="maze")
    parser.add_argument("--goals", type=int, default=3, help="navigation: goals per run (default 3)")
    parser.add_argument("--timeout", type=float, default=60.0, help="slam: sim seconds per run (default 60)")
    args = parser.parse_args(argv)
    isolate_dds()
    folder = Path(tempfile.mkdtemp(prefix="batch_speed_"))
    spec = folder / "spec.yaml"
    spec.write_text(spec_text(args))
    results, first = [], None
    for workers in args.workers:
        out = folder / f"workers_{workers}"
        result = run_batch(spec, out, workers)
        these = comparable_reports(out)
        result["same_reports_as_first"] = first is None or these == first
        first = first or these
        print(f"{workers} worker(s): {result}", file=sys.stderr)
        results.append(result)
    print(json.dumps({"scenario": args.scenario, "world": args.world, "goals": args.goals, "batches": results,
                      "out": str(folder)}))
    return 0 if all(r["same_reports_as_first"] and r["exit_code"] in (0, 1) for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
