"""The supervisor with plain Python children: order, readiness, respawn, required nodes,
signal escalation, and no process left behind in any case."""
from __future__ import annotations

import json
import os
import re
import signal
import sys
import time
from pathlib import Path

import pytest

from pppbot_common.dds_isolation import claimed_domain_id
from pppbot_common.dds_shm import SETTLING_S, SHM

SCRIPT = str(Path(__file__).resolve().parents[1] / "scripts" / "supervise.py")

SLEEPER = "print('up', flush=True)\nwhile True: time.sleep(0.1)\n"


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[-1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def wait_dead(pids: list[int], timeout_s: float = 5.0) -> list[int]:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline and any(alive(p) for p in pids):
        time.sleep(0.05)
    return [p for p in pids if alive(p)]


def started_pids(output: str) -> list[int]:
    return [int(p) for p in re.findall(r"process started with pid \[(\d+)\]", output)]


@pytest.fixture
def supervise(spawn, tmp_path):
    def start(children: list[dict], **options: float | str):
        config = {"children": children, "marks": str(tmp_path / "marks"), **options}
        child = spawn([sys.executable, SCRIPT, json.dumps(config)], name="supervisor")
        child.wait_for_output("SUPERVISOR READY", 20)
        return child
    return start


def test_order_follows_readiness(supervise):
    sup = supervise([
        {"name": "a", "code": "time.sleep(0.5); mark('a ready')\nwhile True: time.sleep(0.1)\n",
         "ready": "a ready"},
        {"name": "b", "code": SLEEPER, "after": ["a"]},
    ])
    sup.wait_for_output(r"\[b-1\] up", 20)
    out = sup.output
    assert out.index("[INFO] [a-1]: ready after") < out.index("[INFO] [b-1]: process started with pid")
    assert re.search(r"\[INFO\] \[a-1\]: ready after 0\.\d s \('a ready' marked\)", out)
    os.kill(sup.pid, signal.SIGINT)
    assert sup.wait(20) == 0
    assert wait_dead(started_pids(sup.output)) == []


def test_readiness_timeout_ends_the_launch(supervise):
    sup = supervise([
        {"name": "mute", "code": SLEEPER, "ready": "never", "ready_timeout": 0.5},
        {"name": "later", "code": SLEEPER, "after": ["mute"]},
    ])
    assert sup.wait(20) == 1
    assert "[ERROR] [mute-1]: not ready after 0.5 s (waited for 'never' marked)" in sup.output
    assert "later-1" not in sup.output
    assert wait_dead(started_pids(sup.output)) == []


def test_respawn_stops_at_its_limit_and_required_ends_the_launch(supervise):
    sup = supervise([
        {"name": "flaky", "code": "print('boom', flush=True); sys.exit(3)\n", "respawn": True,
         "max_respawns": 2, "required": True, "respawn_delay": 0.1},
        {"name": "steady", "code": SLEEPER},
    ])
    assert sup.wait(30) == 1
    out = sup.output
    assert out.count("[flaky-") and "[INFO] [flaky-3]: process started" in out and "flaky-4" not in out
    assert "respawning in 0.1 s (1 of 2)" in out and "respawning in 0.1 s (2 of 2)" in out
    assert "not respawning: 2 respawns used" in out
    assert re.search(r"\[ERROR\] \[flaky-1\]: process has died \[pid \d+, exit code 3", out)
    assert "required node 'flaky' exited" in out
    assert wait_dead(started_pids(out)) == []


def test_sigterm_escalates_for_a_child_that_ignores_sigint(supervise):
    sup = supervise([
        {"name": "stubborn", "code": SLEEPER, "ignore": ["INT"]},
        {"name": "obedient", "code": SLEEPER},
    ], sigint_timeout=0.5, sigterm_timeout=2.0)
    sup.wait_for_output(r"\[stubborn-1\] up", 20)
    sup.wait_for_output(r"\[obedient-1\] up", 20)
    os.kill(sup.pid, signal.SIGTERM)
    assert sup.wait(20) == 1  # ended by SIGTERM
    out = sup.output
    assert "shutting down (signal SIGTERM)" in out
    assert "[WARNING] [launch]: sending SIGTERM to stubborn-1" in out
    assert re.search(r"\[ERROR\] \[stubborn-1\]: process has died \[pid \d+, exit code -15", out)
    assert "[INFO] [obedient-1]: process has finished cleanly" in out or "obedient-1]: process has died" in out
    assert wait_dead(started_pids(out)) == []


def test_a_child_ended_by_the_stop_sigint_finished_cleanly(supervise):
    # rerun's server keeps SIGINT's default action: the launch's Ctrl-C ends it by that signal.
    sup = supervise([{"name": "viewer", "code": "signal.signal(signal.SIGINT, signal.SIG_DFL)\n" + SLEEPER}])
    sup.wait_for_output(r"\[viewer-1\] up", 20)
    os.kill(sup.pid, signal.SIGINT)
    assert sup.wait(20) == 0
    assert "[INFO] [viewer-1]: process has finished cleanly" in sup.output
    # The same signal from anyone else, while the launch runs, is a death.
    sup = supervise([{"name": "viewer", "code": "signal.signal(signal.SIGINT, signal.SIG_DFL)\n" + SLEEPER},
                     {"name": "other", "code": SLEEPER}])
    sup.wait_for_output(r"\[viewer-1\] up", 20)
    os.kill(started_pids(sup.output)[0], signal.SIGINT)
    sup.wait_for_output(r"\[ERROR\] \[viewer-1\]: process has died \[pid \d+, exit code -2", 20)
    os.kill(sup.pid, signal.SIGINT)
    assert sup.wait(20) == 0


HANGS_ON_THE_WAY_DOWN = """
from pppbot_common.process import STOP_SIGNALS, dump_stacks_on_signal
dump_stacks_on_signal()
signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)
def stuck_in_teardown():
    while True: time.sleep(0.1)
print('up', flush=True)
stuck_in_teardown()
"""


def test_a_pppbot_node_still_running_after_sigint_prints_its_stacks_before_sigterm(supervise):
    sup = supervise([{"name": "hung", "code": HANGS_ON_THE_WAY_DOWN, "ignore": ["INT"], "pppbot_node": True},
                     {"name": "plain", "code": SLEEPER, "ignore": ["INT"]}],
                    sigint_timeout=0.5, sigterm_timeout=2.0)
    sup.wait_for_output(r"\[hung-1\] up", 20)
    sup.wait_for_output(r"\[plain-1\] up", 20)
    os.kill(sup.pid, signal.SIGINT)
    assert sup.wait(20) == 0
    out = sup.output
    # only pppbot's nodes are asked (SIGUSR1 would end a plain program)
    assert "[WARNING] [launch]: hung-1 still running 0.5 s after SIGINT; their stacks follow" in out
    assert re.search(r"\[hung-1\] .*line \d+ in stuck_in_teardown", out)
    assert out.index("their stacks follow") < out.index("sending SIGTERM to hung-1, plain-1")
    assert wait_dead(started_pids(out)) == []


def test_sigkill_for_a_child_that_ignores_everything_and_a_second_ctrl_c_waits(supervise):
    sup = supervise([{"name": "deaf", "code": SLEEPER, "ignore": ["INT", "TERM"]}],
                    sigint_timeout=0.5, sigterm_timeout=0.5)
    sup.wait_for_output(r"\[deaf-1\] up", 20)
    os.kill(sup.pid, signal.SIGINT)
    sup.wait_for_output("shutting down", 10)
    os.kill(sup.pid, signal.SIGINT)  # impatient user
    assert sup.wait(20) == 0
    out = sup.output
    assert "already shutting down, please wait" in out
    assert "sending SIGKILL to deaf-1" in out
    assert wait_dead(started_pids(out)) == []


FLOODS = """
stop = []
signal.signal(signal.SIGINT, lambda *_: stop.append(True))
def flood():  # 256 KiB of output: more than a pipe holds, so it blocks unless someone reads
    for _ in range(256): print('x' * 1023)
print('up')
flood()
mark('flooded')
while not stop: time.sleep(0.05)
flood()  # the way down is chatty too
print('stopping')
"""


def test_a_node_whose_output_cannot_be_written_still_runs_and_stops_on_sigint(supervise, tmp_path):
    # Its log file is on a full disk: writing its first line fails in the thread reading its output.
    (tmp_path / "chatty-1.log").symlink_to("/dev/full")
    sup = supervise([{"name": "chatty", "code": FLOODS, "ready": "flooded", "ready_timeout": 15.0},
                     {"name": "quiet", "code": "mark('up')\nwhile True: time.sleep(0.1)\n", "ready": "up"}],
                    log_dir=str(tmp_path), sigint_timeout=15.0, sigterm_timeout=2.0)
    sup.wait_for_output(r"\[INFO\] \[chatty-1\]: ready after", 30)  # it wrote on past a pipe's worth
    sup.wait_for_output(r"\[INFO\] \[quiet-1\]: ready after", 30)
    os.kill(sup.pid, signal.SIGINT)
    assert sup.wait(30) == 0
    out = sup.output
    assert re.search(r"\[ERROR\] \[chatty-1\]: cannot write its output \(OSError: .*No space left on device", out)
    assert out.count("cannot write its output") == 1  # said once, not once a line
    assert "[INFO] [chatty-1]: process has finished cleanly" in out
    assert "[INFO] [quiet-1]: process has finished cleanly" in out
    assert "sending SIGTERM" not in out
    assert wait_dead(started_pids(out)) == []


def test_a_killed_supervisor_leaves_no_orphans(supervise):
    sup = supervise([{"name": "a", "code": SLEEPER}, {"name": "b", "code": SLEEPER}])
    sup.wait_for_output(r"\[a-1\] up", 20)
    sup.wait_for_output(r"\[b-1\] up", 20)
    pids = started_pids(sup.output)
    assert len(pids) == 2 and all(alive(p) for p in pids)
    os.kill(sup.pid, signal.SIGKILL)
    sup.wait(10)
    assert wait_dead(pids) == []  # PR_SET_PDEATHSIG: the kernel sent them SIGTERM


def test_bad_specs_are_refused():
    from pppbot_bringup.supervisor import NodeSpec, Supervisor

    with pytest.raises(ValueError, match="waits for unknown node"):
        Supervisor([NodeSpec("a", ["true"], after=("ghost",))])
    with pytest.raises(ValueError, match="node names must be unique: a"):
        Supervisor([NodeSpec("a", ["true"]), NodeSpec("a", ["true"])])


def test_a_node_dying_before_ready_ends_the_launch_instead_of_hanging(supervise):
    sup = supervise([
        {"name": "fragile", "code": "sys.exit(4)\n", "ready": "never"},
        {"name": "dependent", "code": SLEEPER, "after": ["fragile"]},
    ])
    assert sup.wait(20) == 1
    assert "[ERROR] [fragile-1]: exited before it was ready; dependent cannot start" in sup.output
    assert "dependent-1" not in sup.output


def test_a_segment_never_sized_does_not_hang_the_first_node(supervise):
    """A process killed between making a Fast DDS port segment and sizing it leaves 0 bytes, on
    which the next participant with that port hangs forever (a CI run lost six bringups so). The
    launch removes such files before its first node: a real rclpy node comes up over them."""
    with claimed_domain_id() as domain:
        ports = [7410 + 250 * domain + offset for offset in range(8)]  # participants 0-3: both unicast ports
        planted = [SHM / f"fastrtps_port{port}" for port in ports]
        then = time.time() - 10 * SETTLING_S
        for path in planted:
            for left in (path.with_name(f"{path.name}_el"), path.with_name(f"sem.{path.name}_mutex")):
                left.unlink(missing_ok=True)  # (an unheld lock would let Fast DDS see the port as dead itself)
            path.touch()
            os.utime(path, (then, then))
        try:
            sup = supervise([{"name": "probe", "ready": "up", "ready_timeout": 60.0, "code": (
                f"import os\nos.environ['ROS_DOMAIN_ID'] = '{domain}'\n"
                "import rclpy\nrclpy.init()\nnode = rclpy.create_node('probe')\nmark('up')\n"
                "while True: time.sleep(0.1)\n")}])
            sup.wait_for_output(r"\[INFO\] \[probe-1\]: ready after", 90)
            assert re.search(r"\[INFO\] \[launch\]: removed \d+ shared-memory file\(s\)", sup.output)
            assert all(not p.exists() or p.stat().st_size > 0 for p in planted)  # gone, or made anew by the node
            os.kill(sup.pid, signal.SIGINT)
            assert sup.wait(20) == 0
        finally:
            for path in planted:
                if path.exists() and path.stat().st_size == 0:
                    path.unlink()
