"""pytest harness for pppbot.

- The whole session gets its own ROS_DOMAIN_ID (held with a lock file, so parallel
  test runs on one machine never share one) and ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST;
  both are set before any test, so in-process rclpy and child processes inherit them; a module
  starts in a new domain when this process holds many participants in the last one, and after
  each test the contexts rclpy kept are collected.
- ``spawn`` starts children in their own process groups and stops every one of them
  after the test (SIGINT → SIGTERM → SIGKILL); ``module_spawn`` does the same for a
  module's shared fixture; the session fails if one survives. Fast DDS's shared memory that
  killed processes left is removed before the first test and after a child dies by a signal.
- ``ros_node`` gives a test an rclpy node in a context of its own.
- ``load_benchmark`` imports a ``benchmarks/`` script for tests of its pieces.
"""
from __future__ import annotations

import fcntl
import gc
import importlib.util
import os
import sys
import time
from collections.abc import Callable, Generator, Iterator
from contextlib import contextmanager
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

from pppbot_common.dds_isolation import fresh_domain_if_crowded, isolate_dds
from pppbot_common.dds_participants import own_participants
from pppbot_common.dds_shm import clean_stale
from pppbot_common.process import ChildProcess, StopTimeouts

REPO_ROOT = Path(__file__).resolve().parent.parent
SCRIPTS = Path(__file__).resolve().parent / "scripts"

def pytest_configure(config: pytest.Config) -> None:
    isolate_dds()
    clean_stale()  # DDS shared memory a killed run left can hang participants (pppbot_common.dds_shm)
    os.environ["PYTHONUNBUFFERED"] = "1"


def _own_participants() -> int:
    return own_participants(int(os.environ.get("ROS_DOMAIN_ID", "0") or 0))


@pytest.fixture(autouse=True, scope="module")
def _domain_with_room() -> Iterator[int]:
    """Before each module: what earlier modules left of DDS participants is collected (rclpy keeps
    some contexts' participants after rclpy.shutdown(): a lifecycle node's, until the garbage
    collector runs); if this process still holds many in the session's domain, the module and its
    children move to a new domain: with LOCALHOST discovery, new participants past ID 31 never
    find each other (the suite's late lockstep tests failed so). Gives how many the process holds
    as the module starts (:func:`_participants_let_go` collects what a test leaves beyond it)."""
    if _own_participants():
        gc.collect()
    moved = fresh_domain_if_crowded()
    if moved is not None:
        print(f"\n[conftest] ROS_DOMAIN_ID -> {moved} (this process held many participants in the last one)")
    before = _own_participants()
    yield before
    if _own_participants() > before:
        gc.collect()


@pytest.fixture(autouse=True)
def _participants_let_go(_domain_with_room: int) -> Iterator[None]:
    """After each test: contexts that rclpy keeps after ``rclpy.shutdown()`` (a lifecycle node's sits
    in a reference cycle until the garbage collector runs) are collected, so their DDS participants
    go with the test instead of piling up within a module (a module of lifecycle tests reached
    past participant ID 31, where nothing is discovered on localhost) or lingering in the graph
    (the Foxglove test saw a kept /scan publisher vanish; a node of a fault test, still in the
    graph, was taken for one of the stack's by the hostile-message test). Only when the process
    holds more than it did as the module started: a participant kept for the whole session made
    every later test run a full collection (0.25 s each on a worker's grown heap, 400 s of a
    suite), the import-rule tests' included."""
    yield
    if _own_participants() > _domain_with_room:
        gc.collect()


def _idle_cores(window_s: float = 1.0) -> int:
    """How many of this machine's cores were idle over the last ``window_s`` (/proc/stat), at least 1."""
    def times() -> tuple[int, int]:
        fields = [int(v) for v in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]]
        return sum(fields), fields[3] + fields[4]  # all, idle + iowait

    try:
        total0, idle0 = times()
        time.sleep(window_s)
        total1, idle1 = times()
    except (OSError, ValueError, IndexError):
        return os.cpu_count() or 1
    cores = os.cpu_count() or 1
    return max(1, min(cores, round(cores * (idle1 - idle0) / max(total1 - total0, 1))))


@pytest.hookimpl(optionalhook=True)  # pytest-xdist's: without it, pytest has no such hook
def pytest_xdist_auto_num_workers(config: pytest.Config) -> int:
    """``-n auto`` (``make test``): a worker per idle core. On a machine already busy (a test run
    beside another, CI with a core taken) the suite runs as it would alone on what is left, rather
    than its stacks and browsers each getting a share too small for their waits."""
    return _idle_cores()


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Files with a test marked ``heavy`` (whole stacks, a browser: minutes each) come first, each
    file's tests in their order, and files with a test that takes the machine whole part way
    (``whole_machine``: the busy-machine tests) last. ``make test`` runs files in parallel, one
    worker per core and in this order (``--dist loadfile --no-loadscope-reorder``): the long files
    start at once and the many short ones fill the cores at the end, instead of one long file
    running alone last; the busy run waits for the other worker's short test to end, or for none
    once that worker has run out of files (handed out among the rest, it waited up to three
    minutes for the other worker's autonomy suite). Files with an ``exclusive`` test stay among
    the rest: handed out last too (4b341bd), two of their tests failed (docs/development.md)."""
    heavy = {item.path for item in items if item.get_closest_marker("heavy")}
    whole = {item.path for item in items if "whole_machine" in getattr(item, "fixturenames", ())}
    items.sort(key=lambda item: 0 if item.path in heavy else 2 if item.path in whole else 1)


class MachineLock:
    """The run's lock as one test holds it (shared, or whole: see :func:`_machine_shared_or_whole`)."""

    def __init__(self, file: Any = None) -> None:
        self._file = file

    def take_whole(self) -> None:
        """From now until the test ends, no other test runs beside this one (it waits for those
        running to end): for the part of a test that loads every core."""
        if self._file is not None:
            fcntl.flock(self._file, fcntl.LOCK_EX)  # the shared hold is let go while it waits: no deadlock


@pytest.fixture(autouse=True)
def _machine_shared_or_whole(request: pytest.FixtureRequest,
                             tmp_path_factory: pytest.TempPathFactory) -> Iterator[MachineLock]:
    """In a parallel run (pytest-xdist), a test marked ``exclusive`` runs while no other worker runs a
    test, and waits for them: one that loads every core on purpose would leave another worker's
    stack a third of the machine, and one that times the machine by the wall clock would measure
    the other worker too. Every other test holds the run's lock shared; one that loads the machine
    only in part of it takes it whole from there (:func:`whole_machine`)."""
    run = os.environ.get("PYTEST_XDIST_TESTRUNUID")
    if not run:
        yield MachineLock()
        return
    # The run's folder, shared by its workers (pytest removes old ones), not the machine's /tmp.
    with open(tmp_path_factory.getbasetemp().parent / f"pppbot-{run}.lock", "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX if request.node.get_closest_marker("exclusive") else fcntl.LOCK_SH)
        try:
            yield MachineLock(lock)
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


@pytest.fixture
def whole_machine(_machine_shared_or_whole: MachineLock) -> Callable[[], None]:
    """Call it to have the machine to this test from then on (see :meth:`MachineLock.take_whole`)."""
    return _machine_shared_or_whole.take_whole


def pytest_report_header(config: pytest.Config) -> str:
    return (f"ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID')} "
            f"ROS_AUTOMATIC_DISCOVERY_RANGE={os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE')}")


_started: list[ChildProcess] = []


#: Lines of each spawned child's output a failed test shows (a launch's include its nodes').
FAILED_OUTPUT_LINES = 80


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Generator[None, Any, None]:
    """Keep each phase's report on the test item, for fixtures that act on a failure."""
    outcome = yield
    report = outcome.get_result()
    setattr(item, f"report_{report.when}", report)


@contextmanager
def _children(failed: Callable[[], bool]) -> Iterator[Callable[..., ChildProcess]]:
    """``start(cmd, name=..., timeouts=...)`` for the block; its children stopped at the end,
    and the end of each one's output printed when ``failed()`` says so."""
    mine: list[ChildProcess] = []

    def start(cmd: list[str], name: str | None = None, timeouts: StopTimeouts = StopTimeouts(3.0, 3.0),
              **kwargs: object) -> ChildProcess:
        child = ChildProcess(cmd, name=name, timeouts=timeouts, **kwargs)  # type: ignore[arg-type]
        mine.append(child)
        _started.append(child)
        return child

    try:
        yield start
    finally:
        for child in reversed(mine):
            child.stop()
        if any((child.proc.returncode or 0) < 0 for child in mine):
            clean_stale()  # what the killed one's participants left in /dev/shm (pppbot_common.dds_shm)
        if failed():
            for child in mine:
                lines = child.output.splitlines()[-FAILED_OUTPUT_LINES:]
                print(f"---- the last {len(lines)} lines of {child.name}'s output:\n" + "\n".join(lines))


@pytest.fixture
def spawn(request: pytest.FixtureRequest) -> Iterator[Callable[..., ChildProcess]]:
    """Start a child: ``spawn(cmd, name=..., timeouts=...)``; stopped after the test. When the
    test fails, the end of each child's output is printed (pytest shows it with the failure):
    a wait that timed out says little of why."""
    def failed() -> bool:
        report = getattr(request.node, "report_call", None)
        return report is not None and report.failed

    with _children(failed) as start:
        yield start


@pytest.fixture(scope="module")
def module_spawn(request: pytest.FixtureRequest) -> Iterator[Callable[..., ChildProcess]]:
    """``spawn`` for a module's shared fixture: children run until the module's last test; the
    end of their output is printed when a test of the module failed."""
    failures_before = request.session.testsfailed
    with _children(lambda: request.session.testsfailed > failures_before) as start:
        yield start


@pytest.fixture(scope="session")
def load_benchmark() -> Callable[[str], ModuleType]:
    """``load_benchmark("name")``: ``benchmarks/<name>.py`` as a module (the benchmarks are
    scripts, not a package)."""
    def load(name: str) -> ModuleType:
        if name in sys.modules:
            return sys.modules[name]
        spec = importlib.util.spec_from_file_location(name, REPO_ROOT / "benchmarks" / f"{name}.py")
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module  # before running it: its dataclasses look their module up
        spec.loader.exec_module(module)
        return module
    return load


@pytest.fixture
def rerun_cli(tmp_path: Path) -> Callable[..., str]:
    """``rerun_cli("rrd", "stats", file)``: rerun's command line (the reader of its own files),
    with its settings out of the home directory; its stdout."""
    import subprocess

    from pppbot_viz.viewer import rerun_binary, viewer_environment

    def run(*args: str) -> str:
        env = {**os.environ, **viewer_environment(tmp_path / "rerun"), "RUST_LOG": "warn"}
        result = subprocess.run([str(rerun_binary()), *args], capture_output=True, text=True, timeout=120, env=env)
        assert result.returncode == 0, result.stderr
        return result.stdout
    return run


@pytest.fixture
def rrd_chunks(rerun_cli: Callable[..., str]) -> Callable[[Path], dict[str, int]]:
    """``rrd_chunks(file)``: chunks per entity path of a rerun recording (``rerun rrd stats``)."""
    import re

    def chunks(rrd: Path) -> dict[str, int]:
        section = rerun_cli("rrd", "stats", str(rrd)).split("Num chunks per entity", 1)[1].split("\n\n", 1)[0]
        rows = (line.rsplit(": ", 1) for line in section.splitlines() if line.startswith("/"))
        return {entity: int(re.sub(r"\D", "", count)) for entity, count in rows}
    return chunks


@pytest.fixture
def python_script() -> Callable[[str], list[str]]:
    """The command line that runs ``tests/scripts/<name>`` with this interpreter."""
    def command(name: str, *args: str) -> list[str]:
        return [sys.executable, str(SCRIPTS / name), *args]
    return command


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    survivors = [c for c in _started if c.running()]
    for child in survivors:
        child.stop()
    if survivors:
        names = ", ".join(f"{c.name} (pid {c.pid})" for c in survivors)
        print(f"\nERROR: test children still running at the end of the session were killed: {names}",
              file=sys.stderr)
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


@pytest.fixture
def ros_node(request: pytest.FixtureRequest) -> Iterator[Any]:
    """An rclpy node (default context, initialised for this test only)."""
    import rclpy

    rclpy.init()
    name = "pytest_" + "".join(ch if ch.isalnum() else "_" for ch in request.node.name)[:50]
    node = rclpy.create_node(name)
    try:
        yield node
    finally:
        node.destroy_node()
        rclpy.shutdown()


@pytest.fixture
def spin_in_background(ros_node: Any) -> Iterator[Callable[..., Any]]:
    """``spin_in_background(*nodes)``: spin ``nodes`` (the code under test, as one process of
    ``run_nodes`` would) on an EventsExecutor in a thread until the test ends; then the executor
    stops and the nodes are destroyed, before ``ros_node``'s context ends. Returns the executor
    (more nodes may be added to it)."""
    import threading

    from rclpy.experimental import EventsExecutor

    executor = EventsExecutor()
    stop = threading.Event()
    spun: list[Any] = []

    def spin() -> None:
        while not stop.is_set():
            executor.spin_once(timeout_sec=0.05)

    thread = threading.Thread(target=spin, daemon=True)

    def start(*nodes: Any) -> Any:
        for node in nodes:
            executor.add_node(node)
            spun.append(node)
        if not thread.is_alive():
            thread.start()
        return executor
    try:
        yield start
    finally:
        stop.set()
        if thread.is_alive():
            thread.join(5)
        executor.shutdown()
        for node in spun:
            node.destroy_node()
