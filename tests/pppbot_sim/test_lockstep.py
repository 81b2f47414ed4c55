"""Lockstep over DDS: the real simulator and small participants (tests/scripts/lockstep_participant.py)."""
from __future__ import annotations

import os
import signal
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Int64MultiArray

from pppbot_common.process import ChildProcess
from pppbot_common.ros.wait import wait_until

pytestmark = pytest.mark.ros

ROOT = Path(__file__).resolve().parents[2]
PPPBOT = str(ROOT / "pppbot")
TICK_NS = 50_000_000


def simulator(spawn: Callable[..., ChildProcess], participants: str, timeout_s: float = 20.0) -> ChildProcess:
    return spawn([PPPBOT, "run", "pppbot_sim", "simulator", "--ros-args", "-p", "world:=empty",
                  "-p", "lockstep:=true", "-p", "real_time_factor:=0.0", "-p", f"lockstep_participants:={participants}",
                  "-p", f"lockstep_timeout:={timeout_s}"], name="simulator")


def participant(spawn: Callable[..., ChildProcess], python_script: Callable[..., list[str]], role: str,
                *extra: str) -> ChildProcess:
    return spawn(python_script("lockstep_participant.py", role, *extra, "--ros-args", "-p", "use_sim_time:=true",
                               "-p", "lockstep:=true", "-p", f"lockstep_name:={role}"), name=role)


def test_time_waits_for_a_slow_participant_and_a_chain_of_nodes_takes_no_sim_time(
        ros_node: Any, spawn: Any, python_script: Any) -> None:
    simulator(spawn, "[ticker, relay]")
    # Every tenth tick the ticker sleeps 0.3 wall seconds: time must wait for it.
    participant(spawn, python_script, "ticker", "--sleep-every", "10", "--sleep-s", "0.3")
    participant(spawn, python_script, "relay")
    relayed: list[list[int]] = []
    clocks: list[int] = []
    ros_node.create_subscription(Int64MultiArray, "/ls_test/relayed", lambda m: relayed.append(list(m.data)), 1000)
    # A plain node, no participant: it gets the clock (and is never waited for).
    ros_node.create_subscription(Clock, "/clock", lambda m: clocks.append(m.clock.sec * 10**9 + m.clock.nanosec), 100)
    # (the plain node may discover the simulator after the first ticks: it waits for a clock too)
    wait_until(lambda: len(relayed) >= 40 and len(clocks) >= 2, 90, "40 ticks through the relay and a /clock",
               node=ros_node)
    counts = [count for count, _, _ in relayed]
    assert counts == list(range(counts[0], counts[0] + len(counts)))  # none skipped, none late
    for count, tick_ns, relay_ns in relayed:
        assert tick_ns == count * TICK_NS  # each tick at its period, slow or not
        assert relay_ns == tick_ns  # the relay handled it before time moved on
    assert clocks and clocks == sorted(clocks)


def test_a_hung_participant_is_named_and_the_simulator_stops(spawn: Any, python_script: Any) -> None:
    sim = simulator(spawn, "[ticker]", timeout_s=3.0)
    participant(spawn, python_script, "ticker", "--hang-at", "1.0")
    assert sim.wait(timeout_s=90) == 1
    assert "'ticker' did not answer step" in sim.output and "within lockstep_timeout = 3 s; stopping" in sim.output


def test_a_participant_that_dies_is_named_and_one_that_stops_is_let_go(
        ros_node: Any, spawn: Any, python_script: Any) -> None:
    sim = simulator(spawn, "[ticker, relay]", timeout_s=3.0)
    ticker = participant(spawn, python_script, "ticker")
    relay = participant(spawn, python_script, "relay")
    relayed: list[list[int]] = []
    ros_node.create_subscription(Int64MultiArray, "/ls_test/relayed", lambda m: relayed.append(list(m.data)), 1000)
    wait_until(lambda: len(relayed) >= 5, 90, "ticks through the relay", node=ros_node)
    # Ctrl-C: the relay leaves lockstep on its way out; time goes on with the ticker alone.
    os.kill(relay.pid, signal.SIGINT)
    assert relay.wait(timeout_s=20) == 0
    sim.wait_for_output("lockstep: 'relay' leaves", 20)
    ticks: list[int] = []
    ros_node.create_subscription(Int64MultiArray, "/ls_test/tick", lambda m: ticks.append(m.data[0]), 1000)
    wait_until(lambda: len(ticks) >= 5, 60, "ticks without the relay", node=ros_node)
    # Killed: no goodbye. After lockstep_timeout the simulator names it and stops.
    os.kill(ticker.pid, signal.SIGKILL)
    assert sim.wait(timeout_s=60) == 1
    assert "'ticker' did not answer step" in sim.output
