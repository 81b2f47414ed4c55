"""Running a batch's runs: each a ``pppbot eval`` process in a ROS domain of its own.

A worker takes one :class:`~pppbot_eval.batch.Chain` at a time (an entry's steps in one world) and
runs its steps in order (:func:`run_chain`); ``--workers`` of them share this machine
(:func:`run_local`), or Ray's tasks spread the chains over a cluster (:mod:`pppbot_eval.ros.batch_ray`).
Each run claims a ``ROS_DOMAIN_ID`` no other pppbot run on the machine holds
(:func:`~pppbot_common.dds_isolation.claimed_domain_id`) and keeps DDS on loopback, so no two
stacks see each other; lockstep makes each run's report the same whatever else runs beside it.
Each finished run leaves ``batch_run.json`` beside its report: what it ran, so that a resumed
batch reuses a report only for the same run.
"""
from __future__ import annotations

import argparse
import concurrent.futures
import fcntl
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pppbot_common.dds_isolation import claimed_domain_id
from pppbot_common.errors import PppbotError
from pppbot_eval.batch import Chain, Step, argv, filled
from pppbot_eval.batch_summary import RunResult
from pppbot_eval.generated_worlds import write_world
from pppbot_sim.worldgen.families import generate

#: Cores per run: a lockstep navigation run (simulator, nodes, the evaluation) keeps about one core busy
#: on average, its start-up included, and two at once on 2 cores run 1.5 times as many an hour as one
#: (benchmarks/batch_speed.py, RESULTS.md).
CORES_PER_RUN = 1
#: Memory per run (MB): a navigation run's process tree peaks at about 0.9 GB with the batch's own.
MB_PER_RUN = 1000
#: What a failed run's log shows in its result.
LOG_TAIL_LINES = 5
#: After the batch's SIGINT, how long an eval may take to stop its stack before SIGTERM, and after
#: SIGTERM before SIGKILL (s).
STOP_GRACE_S = (90.0, 30.0)
#: What a finished run leaves beside its report: what it ran.
FINGERPRINT = "batch_run.json"


def default_workers() -> int:
    """As many runs at once as this machine's cores and free memory allow (at least one)."""
    cores = len(os.sched_getaffinity(0)) // CORES_PER_RUN
    try:
        with open("/proc/meminfo") as f:
            available_mb = next(int(line.split()[1]) // 1024 for line in f if line.startswith("MemAvailable:"))
    except (OSError, StopIteration, ValueError):
        available_mb = cores * MB_PER_RUN
    return max(1, min(cores, available_mb // MB_PER_RUN))


@dataclass
class Stop:
    """Stopping a batch: :attr:`event` is set once (by a signal handler, or when the batch's Ray key
    says so); :meth:`request` then sends every running eval SIGINT, and each stops its stack and
    writes its report."""

    event: threading.Event = field(default_factory=threading.Event)
    running: set[subprocess.Popen[bytes]] = field(default_factory=set)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def request(self) -> None:
        with self.lock:
            self.event.set()
            for proc in self.running:
                if proc.poll() is None:
                    proc.send_signal(signal.SIGINT)

    def started(self, proc: subprocess.Popen[bytes]) -> None:
        """Track ``proc`` (SIGINT at once when the batch is already stopping)."""
        with self.lock:
            self.running.add(proc)
            if self.event.is_set():
                proc.send_signal(signal.SIGINT)

    def ended(self, proc: subprocess.Popen[bytes]) -> None:
        with self.lock:
            self.running.discard(proc)


def world_file(step: Step, worlds: Path) -> str:
    """What ``--world`` gets: a shipped name or file as given, or a generated world written to ``worlds``
    (once: runs in the same world wait for the first; written whole or not at all)."""
    world = step.world
    if not world.generated:
        return world.source
    path = worlds / f"{world.name}.sdf"
    worlds.mkdir(parents=True, exist_ok=True)
    with open(worlds / f".{world.name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not path.is_file():
            assert world.seed is not None
            with tempfile.TemporaryDirectory(dir=worlds, prefix=f".{world.name}-") as tmp:
                written, _ = write_world(generate(world.family, world.seed, small=world.small), Path(tmp),
                                         tool="pppbot eval batch")
                for part in sorted(Path(tmp).iterdir(), key=lambda p: p.suffix == ".sdf"):  # the world last
                    os.replace(part, worlds / part.name)
            assert (worlds / written.name) == path, (written, path)
    return str(path)


def fingerprint(step: Step) -> dict[str, Any]:
    """What a run is: scenario, world and flags (placeholders as written)."""
    w = step.world
    return {"scenario": step.scenario, "world": [w.source, w.family, w.seed, w.small], "flags": dict(step.flags)}


def _read_json(path: Path) -> dict[str, Any] | None:
    try:
        return dict(json.loads(path.read_text()))
    except (OSError, ValueError, TypeError):
        return None


def finished_report(out: Path, step: Step) -> dict[str, Any] | None:
    """The report a finished run of this very step left in ``out`` (None: none, it was interrupted,
    or it ran other flags)."""
    report = _read_json(out / step.id / "report.json")
    if report is None or report.get("failure") == "interrupted":
        return None
    return report if _read_json(out / step.id / FINGERPRINT) == json.loads(json.dumps(fingerprint(step))) else None


def run_step(step: Step, out: Path, parser: argparse.ArgumentParser, reports: Mapping[str, Mapping[str, Any]],
             stop: Stop) -> dict[str, Any] | None:
    """Run ``step``: its report (None: the batch stopped it, which is no result). A run that wrote none
    gets one saying why (not saved: a resumed batch runs it again)."""
    here = out / step.id
    shutil.rmtree(here, ignore_errors=True)  # an earlier, unfinished or replaced run
    try:
        flags = filled(step, reports)
    except KeyError as exc:
        return {"ok": False, "failure": f"not run: {exc.args[0]}"}
    world = world_file(step, out / "worlds")
    log = out / "logs" / f"{step.id}.log"
    log.parent.mkdir(parents=True, exist_ok=True)
    command = [sys.executable, "-m", "pppbot_eval.batch_child", str(os.getpid()), "eval",
               *argv(step, flags, parser), "--world", world, "--out", str(here), "--json"]
    with claimed_domain_id() as domain, open(log, "wb") as stderr:
        env = {**os.environ, "ROS_DOMAIN_ID": str(domain), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
        env.pop("ROS_STATIC_PEERS", None)
        env.pop("ROS_LOCALHOST_ONLY", None)
        stderr.write((f"ROS_DOMAIN_ID={domain} " + " ".join(command) + "\n").encode())
        stderr.flush()
        # A session of its own: a terminal's Ctrl-C reaches the batch, which passes it on once.
        proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=stderr, env=env, start_new_session=True)
        stop.started(proc)
        try:
            code = _wait(proc, stop)
        finally:
            stop.ended(proc)
    report = _read_json(here / "report.json")
    if report is None:
        if stop.event.is_set():
            return None
        tail = log.read_text(errors="replace").strip().splitlines()[-LOG_TAIL_LINES:]
        return {"ok": False, "failure": f"eval exited {code} without a report (see {log}): " + " | ".join(tail)}
    if report.get("failure") == "interrupted" and stop.event.is_set():
        shutil.rmtree(here, ignore_errors=True)  # no result: a resumed batch runs it again
        return None
    (here / FINGERPRINT).write_text(json.dumps(fingerprint(step)) + "\n")
    return report


def _wait(proc: subprocess.Popen[bytes], stop: Stop) -> int:
    """Wait for ``proc``; once the batch stops, SIGTERM and then SIGKILL if it outlasts :data:`STOP_GRACE_S`."""
    stopping_since: float | None = None
    escalated = 0
    while True:
        try:
            return proc.wait(timeout=1.0)
        except subprocess.TimeoutExpired:
            pass
        if not stop.event.is_set():
            continue
        stopping_since = stopping_since or time.monotonic()
        if escalated < len(STOP_GRACE_S) and time.monotonic() - stopping_since > sum(STOP_GRACE_S[:escalated + 1]):
            proc.send_signal((signal.SIGTERM, signal.SIGKILL)[escalated])
            escalated += 1


def result(step: Step, report: Mapping[str, Any], resumed: bool = False) -> RunResult:
    return RunResult(step.id, step.scenario, step.world.name, step.world.value("family"), dict(step.axes), report,
                     resumed)


def run_chain(chain: Chain, out: Path, parser: argparse.ArgumentParser, stop: Stop, resume: bool,
              done: Callable[[RunResult], None]) -> None:
    """Run ``chain``'s steps in order, each report handed to ``done``; stops early when told. A run
    that cannot start (no domain free, a world that cannot be written) is a failed result."""
    reports: dict[str, Mapping[str, Any]] = {}
    for step in chain.steps:
        if stop.event.is_set():
            return
        kept = finished_report(out, step) if resume else None
        try:
            report = kept or run_step(step, out, parser, reports, stop)
        except (PppbotError, OSError, RuntimeError) as exc:
            report = {"ok": False, "failure": f"not run: {exc}"}
        if report is None:
            return
        reports[step.name] = report
        done(result(step, report, resumed=kept is not None))


def run_local(chains: Sequence[Chain], out: Path, parser: argparse.ArgumentParser, workers: int, resume: bool,
              stop: Stop, done: Callable[[RunResult], None], tick: Callable[[], None]) -> None:
    """Run ``chains`` on this machine, ``workers`` at a time; ``tick`` is called about every second
    from this thread (progress). Once ``stop.event`` is set (a signal handler sets it) no chain
    starts, every running eval stops its stack, and the call returns when all have."""
    with concurrent.futures.ThreadPoolExecutor(max_workers=workers, thread_name_prefix="batch") as pool:
        futures = [pool.submit(run_chain, chain, out, parser, stop, resume, done) for chain in chains]
        pending = set(futures)
        stopping = False
        while pending:
            finished, pending = concurrent.futures.wait(pending, timeout=1.0)
            for future in finished:
                if not future.cancelled():
                    future.result()  # a bug in the runner is not swallowed
            if stop.event.is_set() and not stopping:
                stopping = True
                stop.request()
                for future in pending:
                    future.cancel()
            tick()


def elapsed_text(seconds: float) -> str:
    seconds = max(0, int(round(seconds)))
    hours, rest = divmod(seconds, 3600)
    return f"{hours} h {rest // 60:02d} min" if hours else f"{rest // 60} min {rest % 60:02d} s"
