"""Start and stop child processes so that none is ever left behind.

Children run in their own session (process group), so a signal reaches the node
and anything it started. Stopping escalates as ``ros2 launch`` does: SIGINT,
then SIGTERM after a timeout, then SIGKILL.
"""
from __future__ import annotations

import contextlib
import faulthandler
import ipaddress
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
import tracemalloc
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from pppbot_common.errors import TimeoutExpired


@dataclass(frozen=True)
class StopTimeouts:
    """Seconds to wait after SIGINT and after SIGTERM before escalating."""

    sigint_s: float = 5.0
    sigterm_s: float = 5.0

    def ladder(self) -> tuple[tuple[signal.Signals, float], ...]:
        """The stop ladder, as ``ros2 launch`` climbs it: each signal and how long to wait after
        it for the process to end before the next (after SIGKILL: :data:`KILL_WAIT_S`)."""
        return ((signal.SIGINT, self.sigint_s), (signal.SIGTERM, self.sigterm_s), (signal.SIGKILL, KILL_WAIT_S))


#: Seconds to wait for a process after SIGKILL (it cannot refuse; this is only the kernel's time).
KILL_WAIT_S = 5.0


def die_with_parent(sig: int = signal.SIGTERM) -> None:
    """In a child (``preexec_fn``): get ``sig`` when the parent dies, even by SIGKILL.

    Linux only (prctl PR_SET_PDEATHSIG); elsewhere it does nothing. The setting
    survives ``exec``. Spawn from the main thread: it fires when the spawning thread ends.
    """
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        pr_set_pdeathsig = 1
        libc.prctl(pr_set_pdeathsig, sig, 0, 0, 0)
    except (OSError, AttributeError):
        pass


#: The signals that ask a process to stop.
STOP_SIGNALS = frozenset({signal.SIGINT, signal.SIGTERM})
#: Makes one of pppbot's nodes print every thread's stack (pppbot_lockstep.ros.runner).
STACK_DUMP_SIGNAL = signal.SIGUSR1


def dump_stacks_on_signal() -> None:
    """From now on :data:`STACK_DUMP_SIGNAL` prints every thread's stack to stderr (from C: it
    works while the main thread is stuck in a binding call)."""
    for stream in (sys.stderr, sys.__stderr__):
        if stream is None:
            continue
        try:
            faulthandler.register(STACK_DUMP_SIGNAL, file=stream, all_threads=True)
            return
        except (AttributeError, ValueError, OSError):  # no file descriptor (captured, closed)
            continue


#: With a folder in this variable, a process of pppbot's traces Python's allocations (for soaks).
TRACE_MEMORY_ENV = "PPPBOT_TRACE_MEMORY"
#: Makes a process that traces its allocations write a snapshot of them.
MEMORY_SNAPSHOT_SIGNAL = signal.SIGUSR2
#: Frames kept per traced allocation.
TRACE_MEMORY_FRAMES = 8


def trace_memory_if_asked(name: str) -> None:
    """With ``PPPBOT_TRACE_MEMORY=FOLDER`` in the environment: trace Python's allocations
    (:mod:`tracemalloc`) and, on each :data:`MEMORY_SNAPSHOT_SIGNAL`, write a snapshot of them to
    ``FOLDER/NAME-PID-N.tracemalloc`` (``benchmarks/soak.py --trace-memory`` compares the first
    and the last). Without the variable it does nothing. Call it from the main thread."""
    folder = os.environ.get(TRACE_MEMORY_ENV)
    if not folder:
        return
    tracemalloc.start(TRACE_MEMORY_FRAMES)
    taken = iter(range(1 << 30))

    def snapshot(signum: int, frame: object) -> None:
        tracemalloc.take_snapshot().dump(str(Path(folder) / f"{name}-{os.getpid()}-{next(taken):03d}.tracemalloc"))

    signal.signal(MEMORY_SNAPSHOT_SIGNAL, snapshot)


@contextlib.contextmanager
def exit_if_stuck(timeout_s: float) -> Iterator[None]:
    """Within the block, a process stuck for ``timeout_s`` prints every thread's stack to stderr and
    exits with status 1 (from C: it works while the main thread is stuck in a binding call that
    holds the GIL, where no Python signal handler can run). Where stderr has no file descriptor
    (a test's captured output) it does nothing."""
    armed = False
    for stream in (sys.stderr, sys.__stderr__):
        if stream is None:
            continue
        try:
            faulthandler.dump_traceback_later(timeout_s, exit=True, file=stream)
            armed = True
            break
        except (AttributeError, ValueError, OSError):
            continue
    try:
        yield
    finally:
        if armed:
            faulthandler.cancel_dump_traceback_later()


def group_stacks(pgid: int, timeout_s: float = 15.0, max_processes: int = 4, max_chars: int = 6000) -> str:
    """Where the Python processes in process group ``pgid`` are now (``py-spy dump``), as text to
    append to a report about a child that stopped making progress: a hang before the child's own
    stack dump is installed (imports, ``rclpy.init``, DDS discovery) shows too. At most
    ``max_processes`` dumps, ``timeout_s`` in all, each cut to ``max_chars``. Native frames when
    py-spy can unwind them, the Python stack alone when not. Empty when py-spy is not installed
    or the group is gone. A launch starts its nodes in groups of their own: for a launch, this
    shows the launch, not its nodes (their output is in the launch's log directory)."""
    py_spy = shutil.which("py-spy") or os.path.join(os.path.dirname(sys.executable), "py-spy")
    if not os.access(py_spy, os.X_OK):
        return ""
    deadline = time.monotonic() + timeout_s
    parts: list[str] = []
    for pid in group_members(pgid):
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as f:
                cmdline = f.read().replace(b"\0", b" ").decode(errors="replace").strip()
        except OSError:
            continue
        if "python" not in cmdline:
            continue
        if len(parts) == max_processes or time.monotonic() >= deadline:
            parts.append(f"\n--- (more processes in the group not dumped: {timeout_s:g} s or {max_processes} dumps)")
            break
        text = ""
        for native in (["--native"], []):
            try:
                dump = subprocess.run([py_spy, "dump", *native, "--pid", str(pid)], capture_output=True, text=True,
                                      errors="replace", timeout=max(deadline - time.monotonic(), 0.1))
            except (OSError, subprocess.TimeoutExpired) as exc:
                text = f"py-spy failed: {exc}"
                break
            text = dump.stdout + dump.stderr
            if dump.returncode == 0:
                break
        parts.append(f"\n--- stacks of {pid} ({cmdline[:200]}):\n{text[:max_chars]}")
    return "".join(parts)


def listening_addresses(pids: Iterable[int]) -> list[tuple[str, int]]:
    """The TCP addresses (ip, port) the processes ``pids`` listen on, from ``/proc``; an IPv4
    address mapped into IPv6 is given as IPv4."""
    inodes = {target[8:-1] for pid in pids for target in open_file_targets(pid) if target.startswith("socket:[")}
    found = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        with contextlib.suppress(OSError), open(table) as f:
            for line in f.read().splitlines()[1:]:
                fields = line.split()
                if fields[3] == "0A" and fields[9] in inodes:  # LISTEN
                    address, port = fields[1].split(":")
                    # /proc writes the address as 32-bit words in the machine's (little-endian) order
                    raw = b"".join(bytes.fromhex(address[i:i + 8])[::-1] for i in range(0, len(address), 8))
                    ip = ipaddress.ip_address(raw)
                    if isinstance(ip, ipaddress.IPv6Address) and ip.ipv4_mapped is not None:
                        ip = ip.ipv4_mapped
                    found.append((str(ip), int(port, 16)))
    return found


def open_file_targets(pid: int) -> list[str]:
    """What process ``pid``'s file descriptors point at (paths, ``socket:[inode]``, ...), from /proc;
    empty once it is gone."""
    targets = []
    with contextlib.suppress(OSError):
        for fd in os.listdir(f"/proc/{pid}/fd"):
            with contextlib.suppress(OSError):
                targets.append(os.readlink(f"/proc/{pid}/fd/{fd}"))
    return targets


def process_tree(pid: int) -> list[int]:
    """``pid`` and every process it started, and they started (in their own sessions too)."""
    parents: dict[int, list[int]] = {}
    for entry in os.listdir("/proc") if os.path.isdir("/proc") else ():
        if entry.isdigit():
            with contextlib.suppress(OSError, IndexError, ValueError), open(f"/proc/{entry}/stat") as f:
                parents.setdefault(int(f.read().rsplit(")", 1)[1].split()[1]), []).append(int(entry))
    tree, todo = [], [pid]
    while todo:
        tree.append(todo.pop())
        todo += parents.get(tree[-1], [])
    return tree


def group_members(pgid: int) -> list[int]:
    """The processes in process group ``pgid`` (a child's session: the node and what it started)."""
    members = []
    for entry in os.listdir("/proc") if os.path.isdir("/proc") else ():
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue
        if len(fields) > 2 and int(fields[2]) == pgid:
            members.append(int(entry))
    return members


def block_stop_signals() -> None:
    """In a child (``preexec_fn``) that runs pppbot's node runner: SIGINT and SIGTERM stay pending
    until the runner has its handlers (:func:`pppbot_lockstep.ros.runner.take_stop_signals`), so
    a stop while the child is still importing ends it cleanly instead of killing it. The mask
    survives ``exec``; only for children that unblock them (a stop signal is never lost)."""
    signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)


def _stop_signals_by_default() -> None:
    """In a child (``preexec_fn``): SIGINT takes its default action even where this process ignores
    it (a shell starts a background job, such as a CI run, with SIGINT ignored, and Python then
    installs no KeyboardInterrupt handler in the children): a child is stopped as it would be from
    a terminal."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _signal_group(proc: subprocess.Popen[bytes] | subprocess.Popen[str], sig: int) -> None:
    try:
        os.killpg(proc.pid, sig)
    except ProcessLookupError:
        pass
    except PermissionError:
        proc.send_signal(sig)


def stop_process_group(
    proc: subprocess.Popen[bytes] | subprocess.Popen[str],
    timeouts: StopTimeouts = StopTimeouts(),
) -> int:
    """Stop ``proc`` and its process group; return its exit code.

    ``proc`` must have been started with ``start_new_session=True``. Whatever the
    leader's fate, the rest of its group is killed at the end, so no grandchild
    survives.
    """
    try:
        if proc.poll() is None:
            for sig, wait_s in timeouts.ladder():
                _signal_group(proc, sig)
                try:
                    proc.wait(timeout=wait_s)
                    break
                except subprocess.TimeoutExpired:
                    continue
            else:
                proc.wait()  # killed: only the kernel's bookkeeping is left
    finally:
        _signal_group(proc, signal.SIGKILL)
    return proc.returncode


class ChildProcess:
    """A child in its own process group whose merged output is kept and can be waited on.

    ``stop()`` (also on ``with`` exit) escalates SIGINT → SIGTERM → SIGKILL and
    kills the whole group, so nothing the child started survives it.
    """

    def __init__(self, cmd: Sequence[str], name: str | None = None,
                 env: Mapping[str, str] | None = None, cwd: str | os.PathLike[str] | None = None,
                 timeouts: StopTimeouts = StopTimeouts()) -> None:
        self.name = name or os.path.basename(cmd[0])
        self.cmd = list(cmd)
        self.timeouts = timeouts
        self._lines: list[str] = []
        self._changed = threading.Condition()
        self.proc = subprocess.Popen(
            self.cmd, env=None if env is None else dict(env), cwd=cwd,
            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
            start_new_session=True, text=True, errors="replace", bufsize=1, preexec_fn=_stop_signals_by_default,
        )
        self._reader = threading.Thread(target=self._read, name=f"{self.name}-output", daemon=True)
        self._reader.start()

    def _read(self) -> None:
        stdout = self.proc.stdout
        if stdout is None:  # only for the type checker: Popen was given PIPE
            return
        for line in stdout:
            with self._changed:
                self._lines.append(line.rstrip("\n"))
                self._changed.notify_all()
        with self._changed:
            self._changed.notify_all()

    @property
    def pid(self) -> int:
        return self.proc.pid

    @property
    def output(self) -> str:
        """Everything the child printed so far (stdout and stderr)."""
        with self._changed:
            return "\n".join(self._lines)

    def running(self) -> bool:
        return self.proc.poll() is None

    def wait_for_output(self, pattern: str | re.Pattern[str], timeout_s: float) -> re.Match[str]:
        """Wait until a line matches ``pattern`` (a regex); return the first match.

        Raises:
            TimeoutExpired: no such line in time, or the child ended first.
        """
        return self.wait_for_lines(pattern, 1, timeout_s)[0]

    def wait_for_lines(self, pattern: str | re.Pattern[str], count: int,
                       timeout_s: float) -> list[re.Match[str]]:
        """Wait until ``count`` lines match ``pattern``; return those matches in order.

        Raises:
            TimeoutExpired: fewer lines matched in time, or the child ended first.
        """
        regex = re.compile(pattern)
        deadline = time.monotonic() + timeout_s
        matches: list[re.Match[str]] = []
        seen = 0
        with self._changed:
            while True:
                for line in self._lines[seen:]:
                    match = regex.search(line)
                    if match:
                        matches.append(match)
                seen = len(self._lines)
                if len(matches) >= count:
                    return matches[:count]
                remaining = deadline - time.monotonic()
                ended = self.proc.poll() is not None and not self._reader.is_alive()
                if remaining <= 0 or ended:
                    why = f"it exited with {self.proc.returncode}" if ended else f"{timeout_s:.1f} s passed"
                    message = (f"{self.name}: {len(matches)} of {count} output lines matched {regex.pattern!r} "
                               f"({why}); output was:\n" + "\n".join(self._lines[-40:]))
                    break
                self._changed.wait(timeout=min(remaining, 0.5))
        if not ended:
            message += group_stacks(self.proc.pid)
        raise TimeoutExpired(message)

    def wait(self, timeout_s: float) -> int:
        """Wait for the child to exit on its own; return its exit code.

        Raises:
            TimeoutExpired: still running after ``timeout_s``.
        """
        try:
            code = self.proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            raise TimeoutExpired(f"{self.name} still running after {timeout_s:.1f} s") from None
        self._reader.join(timeout=5.0)
        return code

    def stop(self) -> int:
        """Stop the child and its group (see :func:`stop_process_group`); return the exit code."""
        code = stop_process_group(self.proc, self.timeouts)
        self._reader.join(timeout=5.0)
        return code

    def __enter__(self) -> ChildProcess:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.stop()
