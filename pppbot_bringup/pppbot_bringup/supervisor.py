"""Start, watch and stop a set of node processes, as ``ros2 launch`` does, without orphans.

No ROS here: readiness is a callable the caller provides (``launch_sim`` asks the
ROS graph: a first message, a node's endpoints, a lockstep participant's joining).

* Order: a node starts once every node in its ``after`` is ready; a node is ready
  when its check passes (or at once without a check); a check that does not pass
  within its timeout ends the launch with an error naming it.
* Output: each line prefixed ``[name-N]`` (N counts the processes of that name),
  decoded with replacement; ros2 launch's ``process started with pid``, ``process
  has finished cleanly`` and ``process has died`` lines. With a log directory,
  each node's output goes to ``<dir>/<name-N>.log`` and only warnings and errors
  are echoed (so a keyboard teleop can own the terminal). A node's output is read to
  its end even when it cannot be written (a full disk): a node never blocks on it.
* Respawn: ``respawn`` with ``respawn_delay_s`` and at most ``max_respawns``
  restarts. A ``required`` node that dies ends the launch with a non-zero code.
* Shutdown (Ctrl-C, SIGTERM, SIGHUP, a required node's death): SIGINT to every
  node, SIGTERM to the ones left after ``sigint_timeout_s`` (pppbot's nodes first
  print their threads' stacks, on SIGUSR1, so a hang shows where), SIGKILL after
  ``sigterm_timeout_s`` more; a second Ctrl-C does not cut this short. Every
  node runs in its own process group (killed whole) and gets SIGTERM from the
  kernel if the supervisor itself is killed (PR_SET_PDEATHSIG).
"""
from __future__ import annotations

import contextlib
import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Protocol

from pppbot_common.dds_shm import clean_stale
from pppbot_common.process import STACK_DUMP_SIGNAL, StopTimeouts, block_stop_signals, die_with_parent

POLL_S = 0.05
#: Wall seconds a hung node has to print its stacks before SIGTERM.
STACK_DUMP_WAIT_S = 1.0
_LEVEL = re.compile(r"\[(WARN|WARNING|ERROR|FATAL)\]|Traceback|error:", re.IGNORECASE)


@dataclass(frozen=True)
class ReadyCheck:
    """How to know a node is up: ``probe()`` returns True (asked from the ROS graph or the
    node's lifecycle state, never from its log text, which log levels and wording change)."""

    description: str
    probe: Callable[[], bool]
    timeout_s: float = 60.0


@dataclass(frozen=True)
class NodeSpec:
    name: str
    cmd: Sequence[str]
    after: tuple[str, ...] = ()
    ready: ReadyCheck | None = None
    required: bool = False
    respawn: bool = False
    respawn_delay_s: float = 0.0
    max_respawns: int = 3
    #: the node reads and writes this terminal (a keyboard teleop); it stays in our process group
    terminal: bool = False
    env: Mapping[str, str] | None = None
    #: one of pppbot's nodes (pppbot_lockstep.ros.runner): it is started with SIGINT and SIGTERM
    #: blocked and takes a stop sent while it was starting once it can end cleanly
    pppbot_node: bool = False


def _pppbot_node_preexec() -> None:
    die_with_parent()
    block_stop_signals()


class TextSink(Protocol):
    def write(self, text: str, /) -> int: ...
    def flush(self) -> None: ...


class Output:
    """Where the launch's and the nodes' lines go.

    A terminal node's output (a keyboard teleop's: its key help and its prompt) goes to the
    terminal as it is, and its newest line stays the terminal's last: a line from the launch or
    another node is written above it and the prompt drawn again below, so warnings never split
    or bury the teleop's prompt line (as a shell keeps its prompt under a background job's
    output).
    """

    def __init__(self, stream: TextSink = sys.stdout, log_dir: Path | None = None) -> None:
        self.stream = stream
        self.log_dir = log_dir
        self._lock = threading.RLock()
        self._files: dict[str, IO[str]] = {}
        #: the terminal node's newest line, drawn last on the terminal without its newline
        self._prompt: str | None = None
        if log_dir is not None:
            log_dir.mkdir(parents=True, exist_ok=True)

    def _emit(self, text: str) -> None:
        try:
            self.stream.write(text)
            self.stream.flush()
        except (OSError, ValueError):
            pass

    def _write(self, text: str) -> None:
        with self._lock:
            if self._prompt is None:
                self._emit(text + "\n")
            else:  # over the prompt's line (carriage return, erase the line), then the prompt again
                self._emit(f"\r\x1b[K{text}\n{self._prompt}")

    def terminal_line(self, text: str) -> None:
        """A line of the terminal node's own output: the terminal's last line from now on."""
        with self._lock:
            self._emit(("\n" if self._prompt is not None else "") + text)
            self._prompt = text

    def end_terminal(self) -> None:
        """The terminal node is gone: its last line ends, and lines go below it."""
        with self._lock:
            if self._prompt is not None:
                self._emit("\n")
                self._prompt = None

    def event(self, level: str, label: str, text: str) -> None:
        self._write(f"[{level}] [{label}]: {text}")

    def node_line(self, label: str, text: str) -> None:
        if self.log_dir is None:
            self._write(f"[{label}] {text}")
            return
        with self._lock:
            log = self._files.get(label)
            if log is None:
                # open until close(): one log file a node, written line by line as it prints
                log = self._files[label] = open(self.log_dir / f"{label}.log", "a", buffering=1)  # noqa: SIM115
            log.write(text + "\n")
        if _LEVEL.search(text):
            self._write(f"[{label}] {text}")

    def close(self) -> None:
        with self._lock:
            self.end_terminal()
            for log in self._files.values():
                with contextlib.suppress(OSError):  # a full disk: the lines it could not take are lost
                    log.close()
            self._files.clear()


@dataclass
class _Running:
    spec: NodeSpec
    label: str
    proc: subprocess.Popen[bytes]
    started_s: float
    ready: bool = False
    reader: threading.Thread | None = None
    log_reader: threading.Thread | None = None


class Supervisor:
    def __init__(self, specs: Sequence[NodeSpec], output: Output | None = None,
                 sigint_timeout_s: float = 5.0, sigterm_timeout_s: float = 5.0,
                 clock: Callable[[], float] = time.monotonic) -> None:
        names = [s.name for s in specs]
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise ValueError(f"node names must be unique: {', '.join(duplicates)}")
        for spec in specs:
            unknown = [d for d in spec.after if d not in names]
            if unknown:
                raise ValueError(f"node '{spec.name}' waits for unknown node(s) {', '.join(unknown)}")
        self.specs = list(specs)
        self.output = output or Output()
        self.sigint_timeout_s = sigint_timeout_s
        self.sigterm_timeout_s = sigterm_timeout_s
        self.clock = clock
        self._counts: dict[str, int] = {}
        self._running: dict[str, _Running] = {}
        self._ready: set[str] = set()
        self._respawns: dict[str, int] = {}
        self._respawn_at: dict[str, float] = {}
        self._pending = list(self.specs)
        self._shutdown = threading.Event()
        self._shutdown_reason = ""
        self._terminal_interrupted = False
        self._repeated_requests: list[str] = []
        self.exit_code = 0
        self.pids: list[int] = []  # every process ever started (tests check none survives)

    # ------------------------------------------------------------ public API
    def request_shutdown(self, reason: str, exit_code: int = 0) -> None:
        """Start the orderly shutdown (idempotent: a second request changes nothing).

        Safe in a signal handler: it only sets flags; the loop does the talking.
        """
        if self._shutdown.is_set():
            self._repeated_requests.append(reason)
            return
        self._shutdown_reason = reason
        self.exit_code = max(self.exit_code, exit_code)
        self._shutdown.set()

    def _report_repeats(self) -> None:
        while self._repeated_requests:
            reason = self._repeated_requests.pop(0)
            self.output.event("WARNING", "launch", f"{reason}: already shutting down, please wait")

    def install_signal_handlers(self) -> None:
        """Ctrl-C, SIGTERM and SIGHUP shut down the same orderly way."""
        def handler(signum: int, frame: object) -> None:
            if signum == signal.SIGINT and not self._shutdown.is_set():
                # Ctrl-C in the terminal reached the terminal's node (same process group) too.
                self._terminal_interrupted = True
            self.request_shutdown(f"signal {signal.Signals(signum).name}", 0 if signum == signal.SIGINT else 1)

        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
            signal.signal(sig, handler)

    def is_ready(self, name: str) -> bool:
        return name in self._ready

    def run(self, until: Callable[[], bool] | None = None) -> int:
        """Start everything, watch until shutdown (or ``until()``); return the exit code."""
        self._clean_shared_memory("launch")  # what a run killed before left could hang the first node
        try:
            while not self._shutdown.is_set():
                if until is not None and until():
                    break
                self._start_due()
                self._check_readiness()
                self._reap()
                if not self._running and not self._pending and not self._respawn_at:
                    self.output.event("INFO", "launch", "all processes have finished")
                    break
                self._shutdown.wait(POLL_S)
        finally:
            self._stop_all()
            self.output.close()
        return self.exit_code

    # --------------------------------------------------------------- startup
    def _start_due(self) -> None:
        now = self.clock()
        for name, at in list(self._respawn_at.items()):
            if now >= at:
                del self._respawn_at[name]
                self._start(next(s for s in self.specs if s.name == name))
        for spec in list(self._pending):
            if all(d in self._ready for d in spec.after):
                self._pending.remove(spec)
                self._start(spec)

    def _start(self, spec: NodeSpec) -> None:
        self._counts[spec.name] = self._counts.get(spec.name, 0) + 1
        label = f"{spec.name}-{self._counts[spec.name]}"
        env = None if spec.env is None else {**os.environ, **spec.env}
        preexec = _pppbot_node_preexec if spec.pppbot_node else die_with_parent
        try:
            if spec.terminal:
                # Keys from the terminal, its lines through the launch (which keeps its prompt
                # last); in the launch's process group, so Ctrl-C reaches it as it reaches us.
                proc = subprocess.Popen(list(spec.cmd), env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                        preexec_fn=preexec)
            else:
                proc = subprocess.Popen(list(spec.cmd), env=env, stdin=subprocess.DEVNULL,
                                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                        start_new_session=True, preexec_fn=preexec)
        except OSError as exc:
            self.output.event("ERROR", label, f"cannot start {' '.join(spec.cmd)}: {exc.strerror}")
            self.request_shutdown(f"'{spec.name}' could not start", 1)
            return
        running = _Running(spec, label, proc, self.clock())
        self._running[spec.name] = running
        self.pids.append(proc.pid)
        self.output.event("INFO", label, f"process started with pid [{proc.pid}]")
        if proc.stdout is not None:
            running.reader = threading.Thread(target=self._read, args=(running,), daemon=True)
            running.reader.start()
        if proc.stderr is not None:  # a terminal node's log lines: as any node's
            running.log_reader = threading.Thread(target=self._read, args=(running, proc.stderr), daemon=True)
            running.log_reader.start()
        if spec.ready is None:
            self._mark_ready(running)

    def _read(self, running: _Running, stream: IO[bytes] | None = None) -> None:
        """A node's output, line by line; a terminal node's standard output is its terminal lines.

        The pipe is read to its end whatever happens: a node whose pipe nobody reads blocks once
        the pipe is full (64 KiB), in its next print or log line, and then neither works nor stops
        on SIGINT. A line that cannot be passed on (its log file on a full disk) is dropped, said
        once. Should reading itself fail, the pipe is closed: the node's writes fail, they do not
        block.
        """
        to_terminal = stream is None and running.spec.terminal
        stream = stream if stream is not None else running.proc.stdout
        if stream is None:
            return
        failed = False
        try:
            for raw in iter(stream.readline, b""):
                text = raw.decode(errors="replace").rstrip("\r\n")
                try:
                    if to_terminal:
                        self.output.terminal_line(text)
                    else:
                        self.output.node_line(running.label, text)
                except Exception as exc:  # the output failed, not the node: read on
                    if not failed:
                        failed = True
                        self._say(running, f"cannot write its output ({type(exc).__name__}: {exc}); its lines "
                                           "are dropped, and read on so that it never blocks")
        except (OSError, ValueError) as exc:
            self._say(running, f"cannot read its output ({type(exc).__name__}: {exc}); closing its pipe")
            with contextlib.suppress(OSError):
                stream.close()
        finally:
            if to_terminal:
                with contextlib.suppress(Exception):
                    self.output.end_terminal()

    def _say(self, running: _Running, text: str) -> None:
        """An error about a node's output, from its reader thread (which must not die of saying it)."""
        with contextlib.suppress(Exception):
            self.output.event("ERROR", running.label, text)

    def _mark_ready(self, running: _Running) -> None:
        running.ready = True
        self._ready.add(running.spec.name)
        elapsed = self.clock() - running.started_s
        what = f" ({running.spec.ready.description})" if running.spec.ready else ""
        self.output.event("INFO", running.label, f"ready after {elapsed:.1f} s{what}")

    def _check_readiness(self) -> None:
        for running in list(self._running.values()):
            check = running.spec.ready
            if running.ready or check is None:
                continue
            if check.probe():
                self._mark_ready(running)
            elif self.clock() - running.started_s > check.timeout_s:
                self.output.event("ERROR", running.label,
                                  f"not ready after {check.timeout_s:g} s (waited for {check.description})")
                self.request_shutdown(f"'{running.spec.name}' did not become ready", 1)

    # --------------------------------------------------------------- watching
    def _reap(self) -> None:
        for name, running in list(self._running.items()):
            code = running.proc.poll()
            if code is None:
                continue
            del self._running[name]
            for reader in (running.reader, running.log_reader):
                if reader is not None:
                    reader.join(timeout=2.0)
            self._report_exit(running, code)
            if code < 0:
                self._clean_shared_memory(running.label)
            spec = running.spec
            if spec.respawn and not self._shutdown.is_set():
                done = self._respawns.get(name, 0)
                if spec.max_respawns < 0 or done < spec.max_respawns:
                    self._respawns[name] = done + 1
                    self._ready.discard(name)
                    self._respawn_at[name] = self.clock() + spec.respawn_delay_s
                    limit = "no limit" if spec.max_respawns < 0 else f"{done + 1} of {spec.max_respawns}"
                    self.output.event("INFO", running.label,
                                      f"respawning in {spec.respawn_delay_s:g} s ({limit})")
                    continue
                self.output.event("ERROR", running.label, f"not respawning: {spec.max_respawns} respawns used")
            if spec.required:
                self.request_shutdown(f"required node '{name}' exited", 1)
            waiting = [s.name for s in self._pending if name in s.after]
            if not running.ready and waiting:
                self.output.event("ERROR", running.label,
                                  f"exited before it was ready; {', '.join(waiting)} cannot start")
                self.request_shutdown(f"'{name}' exited before it was ready", 1)

    def _clean_shared_memory(self, label: str) -> None:
        """Remove the DDS shared memory a process killed by a signal could not (as ``fastdds shm
        clean`` would): files of segments no living process holds, and segments never sized."""
        removed = clean_stale()
        if removed:
            self.output.event("INFO", label, f"removed {len(removed)} shared-memory file(s) of DDS segments that "
                                             "killed processes left (/dev/shm/fastrtps_*)")

    def _report_exit(self, running: _Running, code: int) -> None:
        # A program other than pppbot's nodes that keeps SIGINT's default action (rerun) ends
        # by the signal the launch sent it to stop: that is its clean end. pppbot's nodes
        # handle SIGINT; one that dies of it did not end cleanly.
        stopped = code == -signal.SIGINT and self._shutdown.is_set() and not running.spec.pppbot_node
        if code == 0 or stopped:
            self.output.event("INFO", running.label, f"process has finished cleanly [pid {running.proc.pid}]")
        else:
            self.output.event("ERROR", running.label,
                              f"process has died [pid {running.proc.pid}, exit code {code}, "
                              f"cmd '{' '.join(running.spec.cmd)}']")

    # --------------------------------------------------------------- shutdown
    def _signal(self, running: _Running, sig: int) -> None:
        try:
            if running.spec.terminal:
                os.kill(running.proc.pid, sig)
            else:
                os.killpg(running.proc.pid, sig)
        except ProcessLookupError:
            pass

    def _dump_stacks(self, hung: list[_Running]) -> None:
        """Ask pppbot nodes still running after SIGINT for their threads' stacks (SIGUSR1: see
        pppbot_lockstep.ros.runner), so that the log shows where they hang."""
        if not hung:
            return
        self.output.event("WARNING", "launch", f"{', '.join(r.label for r in hung)} still running "
                                               f"{self.sigint_timeout_s:g} s after SIGINT; their stacks follow")
        for running in hung:
            with contextlib.suppress(ProcessLookupError):
                os.kill(running.proc.pid, STACK_DUMP_SIGNAL)
        deadline = time.monotonic() + STACK_DUMP_WAIT_S
        while time.monotonic() < deadline:
            self._report_repeats()
            time.sleep(POLL_S)

    def _stop_all(self) -> None:
        if self._shutdown_reason:
            self.output.event("INFO", "launch", f"shutting down ({self._shutdown_reason})")
        self._respawn_at.clear()
        self._pending.clear()
        for sig, wait_s in StopTimeouts(self.sigint_timeout_s, self.sigterm_timeout_s).ladder():
            alive = [r for r in self._running.values() if r.proc.poll() is None]
            if not alive:
                break
            if sig == signal.SIGTERM:
                self._dump_stacks([r for r in alive if r.spec.pppbot_node])
            if sig != signal.SIGINT:
                names = ", ".join(r.label for r in alive)
                self.output.event("WARNING", "launch", f"sending {signal.Signals(sig).name} to {names}")
            for running in alive:
                if not (sig == signal.SIGINT and running.spec.terminal and self._terminal_interrupted):
                    self._signal(running, sig)
            deadline = time.monotonic() + wait_s
            while time.monotonic() < deadline and any(r.proc.poll() is None for r in alive):
                self._report_repeats()
                time.sleep(POLL_S)
        for running in list(self._running.values()):
            if running.proc.poll() is None:
                running.proc.wait()
            if not running.spec.terminal:
                with contextlib.suppress(ProcessLookupError, PermissionError):  # whatever the node left in its group
                    os.killpg(running.proc.pid, signal.SIGKILL)
            for reader in (running.reader, running.log_reader):
                if reader is not None:
                    reader.join(timeout=2.0)
            self._report_exit(running, running.proc.returncode)
        if any(r.proc.returncode < 0 for r in self._running.values()):
            self._clean_shared_memory("launch")
        self._running.clear()
        self._report_repeats()
