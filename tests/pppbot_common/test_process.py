"""ChildProcess / stop_process_group: escalation and no survivors."""
from __future__ import annotations

import os
import shlex
import signal
import socket
import subprocess
import sys
import textwrap

import pytest

from pppbot_common.errors import TimeoutExpired
from pppbot_common.process import KILL_WAIT_S, ChildProcess, StopTimeouts, listening_addresses


def python(code: str) -> list[str]:
    return [sys.executable, "-c", textwrap.dedent(code)]


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # A zombie is dead for our purposes.
    with open(f"/proc/{pid}/stat") as f:
        return f.read().split(")")[-1].split()[0] != "Z"


def test_sigint_is_enough_for_a_well_behaved_child():
    child = ChildProcess(python("""
        import time
        try:
            print('up', flush=True)  # inside the try: a SIGINT right after it is handled too
            time.sleep(60)
        except KeyboardInterrupt:
            print('interrupted', flush=True)
    """))
    child.wait_for_output("^up$", 10)
    code = child.stop()
    assert code == 0
    assert "interrupted" in child.output


def test_child_ignoring_sigint_gets_sigterm():
    child = ChildProcess(python("""
        import signal, time
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        print('up', flush=True)
        time.sleep(60)
    """), timeouts=StopTimeouts(0.5, 5.0))
    child.wait_for_output("^up$", 10)
    assert child.stop() == -signal.SIGTERM


def test_child_ignoring_sigint_and_sigterm_gets_sigkill():
    child = ChildProcess(python("""
        import signal, time
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        print('up', flush=True)
        time.sleep(60)
    """), timeouts=StopTimeouts(0.3, 0.3))
    child.wait_for_output("^up$", 10)
    assert child.stop() == -signal.SIGKILL


def test_grandchildren_do_not_survive():
    child = ChildProcess(python("""
        import subprocess, sys, signal, time
        grand = subprocess.Popen([sys.executable, '-c',
            'import signal, time; signal.signal(signal.SIGINT, signal.SIG_IGN); time.sleep(60)'])
        print('grandchild', grand.pid, flush=True)
        time.sleep(60)
    """), timeouts=StopTimeouts(0.5, 0.5))
    grand_pid = int(child.wait_for_output(r"^grandchild (\d+)$", 10).group(1))
    assert alive(grand_pid)
    child.stop()
    # The group is SIGKILLed at the end; give the kernel a moment to reap.
    import time
    deadline = time.monotonic() + 5
    while alive(grand_pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not alive(grand_pid)


def test_wait_for_output_reports_early_exit():
    child = ChildProcess(python("print('only line'); raise SystemExit(3)"))
    with pytest.raises(TimeoutExpired, match=r"exited with 3\)(?s:.*)only line"):
        child.wait_for_output("never printed", 10)
    assert child.wait(5) == 3


def test_wait_times_out_on_a_running_child():
    with ChildProcess(python("import time; time.sleep(60)")) as child, \
            pytest.raises(TimeoutExpired, match="still running"):
        child.wait(0.2)
    assert not child.running()


def test_a_child_that_prints_nothing_in_time_is_reported_with_where_it_is():
    # A bash wrapper runs the Python process, as ./pppbot does: the report looks through the group.
    code = "import time\ndef stuck_here():\n    time.sleep(60)\nprint('started', flush=True)\nstuck_here()"
    with ChildProcess(["bash", "-c", f"{sys.executable} -c {shlex.quote(code)}; true"]) as child:
        child.wait_for_output("started", 10)
        with pytest.raises(TimeoutExpired, match=r"0 of 1 output lines matched 'ready'") as failed:
            child.wait_for_output("ready", 0.5)
    report = str(failed.value)
    if "Permission" in report or "not permitted" in report:  # py-spy is pinned; ptrace may not be allowed
        pytest.skip("py-spy may not attach to a process here (ptrace)")
    assert "stuck_here" in report


def test_the_stop_ladder_is_ros2_launchs_one_definition_for_every_stopper():
    ladder = StopTimeouts(2.0, 3.0).ladder()
    assert ladder == ((signal.SIGINT, 2.0), (signal.SIGTERM, 3.0), (signal.SIGKILL, KILL_WAIT_S))


_STUCK = """
import sys, time
from pppbot_common.process import exit_if_stuck
with exit_if_stuck(0.5):
    pass  # done in time: nothing happens
print("first block done", flush=True)
with exit_if_stuck(0.5):
    time.sleep(60)  # stuck (as in a binding call that never returns)
"""


def test_a_process_stuck_in_its_end_prints_its_stack_and_exits():
    """exit_if_stuck: a block that finishes in time changes nothing; one that hangs ends the process
    with status 1 and every thread's stack on stderr, naming where it hung."""
    proc = subprocess.run([sys.executable, "-c", _STUCK], capture_output=True, text=True, timeout=30)
    assert proc.stdout == "first block done\n"
    assert proc.returncode == 1
    assert "Timeout (0:00:00.500000)!" in proc.stderr
    assert 'File "<string>", line 8' in proc.stderr  # the sleep in the second block


def test_listening_addresses_are_read_from_proc_as_bound() -> None:
    with socket.socket() as local, socket.socket(socket.AF_INET6) as everywhere, socket.socket() as unlistened:
        local.bind(("127.0.0.1", 0))
        local.listen()
        everywhere.bind(("::", 0))
        everywhere.listen()
        unlistened.bind(("127.0.0.1", 0))
        found = listening_addresses([os.getpid()])
        assert ("127.0.0.1", local.getsockname()[1]) in found and ("::", everywhere.getsockname()[1]) in found
        assert ("127.0.0.1", unlistened.getsockname()[1]) not in found
