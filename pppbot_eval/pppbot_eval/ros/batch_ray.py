"""A batch on a Ray cluster: each chain of runs a Ray task, its folder streamed back as it ends.

Ray does the scheduling, the retries of a task whose worker or node died (``max_retries``) and
the cluster; this module only turns a chain into a task and a finished task back into files.
A task reserves the CPUs one lockstep stack needs (``--cpus-per-run``), runs the chain as
:func:`~pppbot_eval.batch_run.run_chain` does on this machine, in a temporary folder of the
node it lands on (generated worlds are written there: a family and a seed give the same world
on every machine), and returns the folder as a tar archive; here it is unpacked into ``--out``
and the paths in its reports are rewritten to where they now are. Resuming is per chain: a
chain whose runs all have reports is not sent again.
"""
from __future__ import annotations

import io
import json
import os
import shutil
import tarfile
import tempfile
import threading
import time
import uuid
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from pppbot_eval.batch import Chain
from pppbot_eval.batch_run import Stop, result, run_chain
from pppbot_eval.batch_summary import RunResult
from pppbot_eval.errors import RayError

#: Where Ray comes from: an optional extra (``./pppbot setup --ray``), pinned in requirements-ray.txt.
INSTALL_HINT = "./pppbot setup --ray (installs the Ray pinned in requirements-ray.txt)"


def connect(address: str) -> bool:
    """Join the cluster at ``address`` (``auto``: the one ``ray start`` runs on this machine), or start
    one on this machine (``local``) whose every server binds 127.0.0.1.

    Returns:
        Whether this process started the instance (and shuts it down at the end).

    Raises:
        RayError: Ray is not installed, or there is no cluster at ``address``.
    """
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")  # Ray reports nothing home
    if address == "local":
        # Ray's single-machine mode, read when Ray is imported: its node address is 127.0.0.1 and every
        # server binds there (on Linux it would take the machine's address and bind every interface).
        os.environ.setdefault("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "0")
    try:
        import ray
    except ImportError:
        raise RayError(f"--ray needs Ray, which is not installed: {INSTALL_HINT}") from None
    try:
        if address == "local":
            ray.init(address="local", include_dashboard=False, log_to_driver=False, configure_logging=False)
            return True
        ray.init(address=address, log_to_driver=False, configure_logging=False)
    except (ConnectionError, RuntimeError, ValueError) as exc:
        raise RayError(f"--ray {address}: {exc}") from exc
    return False


#: How often a task asks whether the batch is stopping (s).
STOP_POLL_S = 1.0
#: How long a stopping batch waits for its tasks to stop their stacks and send what they have (s).
STOP_WAIT_S = 180.0


def _stopping(key: bytes) -> bool:
    """Whether the batch of ``key`` is stopping, read from the cluster's key-value store (the GCS).

    Not a task or actor call: a task blocked on one gives its CPUs back to Ray, which would start
    another stack beside it. Ray has no public key-value API; this one is pinned with Ray.
    """
    from ray.experimental import internal_kv
    return internal_kv._internal_kv_get(key) is not None


def _watch(key: bytes, stop: Stop, finished: threading.Event) -> None:
    """On a Ray worker: until the chain is ``finished``, stop it when the batch is stopping."""
    while True:
        if _stopping(key):
            stop.request()
            return
        if finished.wait(STOP_POLL_S):
            return


def _chain_task(chain: Chain, key: bytes) -> tuple[str, list[tuple[str, dict[str, Any]]], bytes]:
    """On a Ray worker: run ``chain`` in a temporary folder; its out folder's path, the reports (of the
    runs that ended: all, unless the batch stopped), the folder as a gzipped tar."""
    from pppbot_eval.ros.batch_cli import eval_parser
    if _stopping(key):  # a task Ray starts after the batch stopped runs nothing
        return "", [], b""
    reports: list[RunResult] = []
    stop, finished = Stop(), threading.Event()
    threading.Thread(target=_watch, args=(key, stop, finished), daemon=True).start()
    with tempfile.TemporaryDirectory(prefix="pppbot-batch-") as tmp:
        out = Path(tmp).resolve() / "out"
        out.mkdir()
        try:
            run_chain(chain, out, eval_parser(), stop, False, reports.append)
        finally:
            finished.set()
        archive = io.BytesIO()
        with tarfile.open(fileobj=archive, mode="w:gz") as tar:
            tar.add(out, arcname=".")
        return str(out), [(r.id, dict(r.report)) for r in reports], archive.getvalue()


def _unpack(remote_out: str, archive: bytes, out: Path, chain: Chain) -> None:
    """Unpack a task's folder into ``out`` (the chain's runs' folders replaced), its reports' paths
    pointing into ``out``."""
    for step in chain.steps:
        shutil.rmtree(out / step.id, ignore_errors=True)
    with tarfile.open(fileobj=io.BytesIO(archive), mode="r:gz") as tar:
        tar.extractall(out, filter="data")
        names = [m.name for m in tar.getmembers() if m.name.endswith("/report.json")]
    for name in names:
        path = out / name
        path.write_text(_moved(path.read_text(), remote_out, out))


def _moved(text: str, remote_out: str, out: Path) -> str:
    """JSON ``text`` with the task's folder replaced by ``out``."""
    return text.replace(json.dumps(remote_out)[1:-1], json.dumps(str(out))[1:-1])


def run_on_ray(chains: Sequence[Chain], out: Path, cpus_per_run: float, max_retries: int, stop: Stop,
               done: Callable[[RunResult], None], tick: Callable[[], None]) -> None:
    """Run ``chains`` as Ray tasks on the cluster :func:`connect` joined, each result into ``out`` as it
    ends. Once ``stop.event`` is set (a signal handler sets it), the tasks stop their evals, which stop
    their stacks, and send the runs that ended; a task Ray gives up on (its worker or node died more
    than ``max_retries`` times) is a failed result for each of its runs."""
    import ray
    from ray.experimental import internal_kv
    key = f"pppbot-batch-stop-{uuid.uuid4().hex}".encode()  # this batch's own: others may share the cluster
    task = ray.remote(num_cpus=cpus_per_run, max_retries=max_retries)(_chain_task)
    pending = {task.remote(chain, key): chain for chain in chains}
    deadline: float | None = None
    try:
        while pending and (deadline is None or time.monotonic() < deadline):
            finished, _ = ray.wait(list(pending), num_returns=1, timeout=1.0)
            for ref in finished:
                chain = pending.pop(ref)
                try:
                    remote_out, reports, archive = ray.get(ref)
                except ray.exceptions.RayError as exc:
                    for step in chain.steps:
                        done(result(step, {"ok": False, "failure": f"not run: Ray: {exc}".splitlines()[0]}))
                    continue
                if archive:
                    _unpack(remote_out, archive, out, chain)
                steps = {s.id: s for s in chain.steps}
                for run_id, report in reports:
                    done(result(steps[run_id], json.loads(_moved(json.dumps(report), remote_out, out))))
            if stop.event.is_set() and deadline is None:
                internal_kv._internal_kv_put(key, b"stop")
                deadline = time.monotonic() + STOP_WAIT_S
            tick()
        for ref in pending:  # stuck after the stop: Ray ends its worker (its eval gets SIGINT then)
            ray.cancel(ref, force=True)
    finally:
        internal_kv._internal_kv_del(key)
