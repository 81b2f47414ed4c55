"""``pppbot eval batch SPEC.yaml``: many scenarios, several at once here or on a Ray cluster, one summary.

    ./pppbot eval batch SPEC.yaml [--out DIR] [--workers N] [--resume]
    ./pppbot eval batch SPEC.yaml --ray auto|local|ADDRESS [--cpus-per-run 2]

The spec (:mod:`pppbot_eval.batch`) lists runs of ``pppbot eval`` or their product over worlds,
world families and seeds, and flags. Each run writes its usual report into ``<out>/<id>/``
and its output into ``<out>/logs/<id>.log``; at the end (also after Ctrl-C, for the runs that
ended) a table per world family and scenario goes to the terminal, ``summary.csv`` (a row per
run) and ``summary.json`` into ``<out>``, and the summary as one JSON object on the last line
of stdout. ``--resume`` keeps the runs that have a report and runs the rest. Exit code 0 when
every run is ok, 1 when not, 2 for a bad spec or flag, 130 when interrupted.
"""
from __future__ import annotations

import argparse
import functools
import signal
import sys
import threading
import time
from pathlib import Path
from typing import Any, NoReturn

from pppbot_common.errors import PppbotError
from pppbot_eval.batch import Batch, Chain, load_batch
from pppbot_eval.batch_run import CORES_PER_RUN, Stop, default_workers, elapsed_text, finished_report, run_local
from pppbot_eval.batch_summary import RunResult, summarize, table, write_files
from pppbot_eval.errors import BatchSpecError
from pppbot_eval.progress import Progress
from pppbot_eval.scenarios import Scenario
from pppbot_sim.wheel_slip import MAX_SLIP_STDDEV


class _SpecFlags(argparse.ArgumentParser):
    """pppbot eval's flags for checking a spec: a refused flag raises, naming it, instead of exiting."""

    def error(self, message: str) -> NoReturn:
        raise BatchSpecError(message)


@functools.lru_cache(maxsize=1)
def eval_parser() -> argparse.ArgumentParser:
    """``pppbot eval``'s own flags: what a spec's keys may be."""
    from pppbot_eval.ros.cli import add_arguments
    parser = _SpecFlags(prog="pppbot eval")
    add_arguments(parser)
    return parser


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = ("Many scenarios, several at once on this machine or on a Ray cluster, with one summary "
                          "(the spec's format: docs/evaluation.md).")
    parser.add_argument("spec", type=Path, help="the batch spec (YAML; see docs/evaluation.md)")
    parser.add_argument("--out", type=Path, default=None,
                        help="the batch's folder (default: the spec's 'out', else eval_batch_<spec name>)")
    parser.add_argument("--workers", type=int, default=None,
                        help=f"runs at once on this machine (default: one per core, and per GB of free memory; "
                             f"here {default_workers()})")
    parser.add_argument("--resume", action="store_true",
                        help="keep the runs in --out that have a report of the same run, run the others")
    parser.add_argument("--ray", default=None, metavar="ADDRESS",
                        help="run on a Ray cluster: auto (the one `ray start` runs here), local (start one on "
                             "this machine, bound to 127.0.0.1) or the head's address (host:port)")
    parser.add_argument("--cpus-per-run", type=float, default=None,
                        help=f"with --ray: the CPUs a run reserves (default {CORES_PER_RUN}: a lockstep run keeps "
                             "about one busy)")
    parser.add_argument("--max-retries", type=int, default=None,
                        help="with --ray: how often Ray runs a task again whose worker or node died (default 3)")


def _out(args: argparse.Namespace, batch: Batch) -> Path:
    out: Path = args.out or batch.out or Path(f"eval_batch_{args.spec.stem}")
    if out.exists() and (not out.is_dir() or (any(out.iterdir()) and not args.resume)):
        raise BatchSpecError(f"--out {out}: exists and is not an empty folder; --resume goes on with it")
    return out.resolve()


def _check_flags(args: argparse.Namespace) -> int:
    """The workers to run with; the flags that go together, checked."""
    if args.ray and args.workers is not None:
        raise BatchSpecError("--workers is for this machine; with --ray, --cpus-per-run sizes the runs")
    if not args.ray and (args.cpus_per_run is not None or args.max_retries is not None):
        raise BatchSpecError("--cpus-per-run and --max-retries are for --ray")
    workers = default_workers() if args.workers is None else args.workers
    if workers < 1:
        raise BatchSpecError(f"--workers {workers}: at least 1")
    if args.cpus_per_run is not None and not args.cpus_per_run > 0:
        raise BatchSpecError(f"--cpus-per-run {args.cpus_per_run}: must be positive")
    if args.max_retries is not None and args.max_retries < 0:
        raise BatchSpecError(f"--max-retries {args.max_retries}: at least 0")
    return workers


def _check_worlds(batch: Batch) -> None:
    """Every named world exists, before anything runs."""
    from pppbot_sim.errors import WorldError
    from pppbot_sim.worlds import find_world
    for name in sorted({s.world.source for s in batch.steps if not s.world.generated}):
        try:
            find_world(name)
        except WorldError as exc:
            raise BatchSpecError(f"{batch.file}: {exc}") from exc


class Tally:
    """The runs that ended, and the progress line over them."""

    def __init__(self, batch: Batch, progress: Progress) -> None:
        self.order = {s.id: i for i, s in enumerate(batch.steps)}
        self.total = len(self.order)
        self.progress = progress
        self.results: list[RunResult] = []
        self.executed = 0  # runs that ran now (not kept from before: they take no time)
        self.started = time.monotonic()
        self.lock = threading.Lock()

    def done(self, run: RunResult) -> None:
        with self.lock:
            self.results.append(run)
            self.executed += not run.resumed
        if not run.ok:
            self.progress.message(f"{run.id}: FAILED: {run.failure}")
        self.tick()

    def tick(self) -> None:
        with self.lock:
            n, failed = len(self.results), sum(not r.ok for r in self.results)
            elapsed = time.monotonic() - self.started
            left = self.total - n
            eta = ("ETA " + elapsed_text(elapsed / self.executed * left)) if self.executed and left else "ETA --"
        self.progress.update(n / self.total, f"{n}/{self.total} runs, {failed} failed, "
                                             f"{elapsed_text(elapsed)}, {eta if left else 'done'}")

    def ordered(self) -> list[RunResult]:
        return sorted(self.results, key=lambda r: self.order[r.id])


def main(args: argparse.Namespace) -> int:
    try:
        batch = load_batch(args.spec, eval_parser(), [s.value for s in Scenario], MAX_SLIP_STDDEV)
        _check_worlds(batch)
        workers = _check_flags(args)
        out = _out(args, batch)
        out.mkdir(parents=True, exist_ok=True)
        started_ray = False
        if args.ray:
            from pppbot_eval.ros.batch_ray import connect
            started_ray = connect(args.ray)
    except PppbotError as exc:
        print(f"pppbot eval batch: {exc}", file=sys.stderr)
        return 2
    progress = Progress(sys.stderr, f"batch {args.spec.stem}")
    tally = Tally(batch, progress)
    where = f"Ray ({args.ray})" if args.ray else f"{workers} worker(s)"
    progress.message(f"{tally.total} runs in {len(batch.chains)} chain(s) on {where}; reports in {out}")
    stop = Stop()
    try:
        _run(batch, args, out, workers, stop, tally)
    finally:
        if started_ray:
            import ray
            ray.shutdown()
    progress.finish()
    results = tally.ordered()
    summary = summarize(results, time.monotonic() - tally.started)
    summary.update({"spec": str(args.spec), "out": str(out), "interrupted": stop.event.is_set(),
                    "not_run": tally.total - len(results)})
    line = write_files(out, results, summary)
    print(table(summary))
    print(line)
    if stop.event.is_set():
        return 130
    return 0 if len(results) == tally.total and all(r.ok for r in results) else 1


def _run(batch: Batch, args: argparse.Namespace, out: Path, workers: int, stop: Stop, tally: Tally) -> None:
    """Run the batch; Ctrl-C, SIGTERM and SIGHUP stop it (the handler only sets the stop: the runner
    notices it, stops every running eval, and returns once all have)."""
    def interrupt(signum: int, frame: Any) -> None:
        if not stop.event.is_set():
            tally.progress.message("stopping: every running stack stops, then the summary of the runs that ended")
        stop.event.set()
    previous = {s: signal.signal(s, interrupt) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
    try:
        if not args.ray:
            run_local(batch.chains, out, eval_parser(), workers, args.resume, stop, tally.done, tally.tick)
            return
        from pppbot_eval.ros.batch_ray import run_on_ray
        chains = [c for c in batch.chains if not (args.resume and _finished(c, out))]
        kept = [c for c in batch.chains if c not in chains]  # resumed: their reports are taken as they are
        run_local(kept, out, eval_parser(), 1, True, stop, tally.done, tally.tick)
        run_on_ray(chains, out, args.cpus_per_run or CORES_PER_RUN,
                   3 if args.max_retries is None else args.max_retries, stop, tally.done, tally.tick)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def _finished(chain: Chain, out: Path) -> bool:
    return all(finished_report(out, step) is not None for step in chain.steps)
