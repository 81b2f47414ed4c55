"""teleop_keyboard driven through a pseudo-terminal: keys become twists; it restores the terminal."""
from __future__ import annotations

import os
import pty
import subprocess
import termios
import time
from pathlib import Path

import pytest
from geometry_msgs.msg import Twist

from pppbot_common.ros.wait import wait_until

pytestmark = pytest.mark.ros
PPPBOT = str(Path(__file__).resolve().parents[2] / "pppbot")


@pytest.fixture
def teleop(spawn):
    """teleop_keyboard with a pty as its terminal; yields (child, write_key, master_fd)."""
    master, slave = pty.openpty()
    proc = subprocess.Popen([PPPBOT, "run", "pppbot_control", "teleop_keyboard", "--ros-args",
                             "-p", "key_timeout:=0.6", "-p", "repeat_rate:=10.0"],
                            stdin=slave, stdout=slave, stderr=slave, start_new_session=True)
    os.close(slave)
    output = bytearray()

    def read_available(timeout_s: float = 0.0) -> str:
        import select
        deadline = time.monotonic() + timeout_s
        while True:
            ready, _, _ = select.select([master], [], [], max(0.0, deadline - time.monotonic()))
            if not ready:
                return output.decode(errors="replace")
            try:
                chunk = os.read(master, 4096)
            except OSError:
                return output.decode(errors="replace")
            output.extend(chunk)

    def wait_text(text: str, timeout_s: float = 20.0) -> None:
        deadline = time.monotonic() + timeout_s
        while text not in read_available(0.1):
            if time.monotonic() > deadline:
                raise AssertionError(f"'{text}' not printed; output: {output.decode(errors='replace')[-2000:]}")

    try:
        wait_text("CTRL-C to quit")
        yield proc, (lambda keys: os.write(master, keys.encode())), wait_text, master
    finally:
        from pppbot_common.process import stop_process_group
        stop_process_group(proc)
        os.close(master)


def listen(ros_node, on_twist) -> None:
    """Subscribe to teleop's output and wait until its publisher is matched."""
    ros_node.create_subscription(Twist, "/cmd_vel_teleop", on_twist, 10)
    wait_until(lambda: ros_node.count_publishers("/cmd_vel_teleop") > 0, 10, "teleop's publisher", node=ros_node)


def test_keys_publish_the_twists_of_teleop_twist_keyboard(ros_node, teleop):
    proc, press, wait_text, _ = teleop
    got: list[Twist] = []
    listen(ros_node, got.append)
    press("i")
    wait_until(lambda: any(t.linear.x == 0.5 for t in got), 10, "forward 0.5", node=ros_node)
    press("q")
    wait_text("currently:\tspeed 0.55\tturn 1.1")
    press("j")
    wait_until(lambda: any(t.angular.z == pytest.approx(1.1) and t.linear.x == 0 for t in got), 10, "turn left",
               node=ros_node)
    got.clear()
    press("k")
    wait_until(lambda: got and got[-1].linear.x == 0 and got[-1].angular.z == 0, 10, "stop", node=ros_node)


@pytest.mark.exclusive  # times the key timeout by the wall clock
def test_holding_repeats_and_releasing_stops(ros_node, teleop):
    proc, press, _, _ = teleop
    got: list[tuple[float, float]] = []
    listen(ros_node, lambda m: got.append((time.monotonic(), m.linear.x)))
    press("i")
    start = time.monotonic()
    # No more keys: it repeats at 10 Hz until the 0.6 s key timeout, then sends one zero.
    wait_until(lambda: got and got[-1][1] == 0.0, 5, "the stop after the key timeout", node=ros_node)
    forward = [t for t, x in got if x == 0.5]
    assert len(forward) >= 4
    stop_time = got[-1][0] - start
    assert 0.5 < stop_time < 1.2
    count = len(got)
    wait_until(lambda: time.monotonic() - start > stop_time + 0.5, 2, "", node=ros_node)
    assert len(got) == count  # zeros are not repeated


def test_ctrl_c_restores_the_terminal_and_stops(ros_node, teleop):
    proc, press, _, master = teleop
    got: list[Twist] = []
    listen(ros_node, got.append)
    press("i")
    wait_until(lambda: any(t.linear.x == 0.5 for t in got), 10, "forward", node=ros_node)
    press("\x03")
    assert proc.wait(timeout=15) == 0
    wait_until(lambda: got[-1].linear.x == 0.0, 5, "a last zero twist", node=ros_node)
    attrs = termios.tcgetattr(master)
    assert attrs[3] & termios.ICANON and attrs[3] & termios.ECHO  # canonical mode and echo are back


def test_without_a_terminal_it_says_how_to_run_it():
    result = subprocess.run([PPPBOT, "run", "pppbot_control", "teleop_keyboard"], stdin=subprocess.DEVNULL,
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 1
    assert "standard input is not one" in result.stderr and "./pppbot teleop" in result.stderr
