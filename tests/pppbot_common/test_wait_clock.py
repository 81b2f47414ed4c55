"""Waiting on the node's clock (sim time) and on futures, from a thread other than the spinning one."""
from __future__ import annotations

import threading
import time
from typing import Any

import pytest
from rclpy.parameter import Parameter
from rclpy.task import Future
from rclpy.time import Time

from pppbot_common.ros.wait import sleep_until_clock, wait_for_future


def sim_time(node: Any, start_s: float) -> Any:
    """The node on sim time, set to ``start_s`` (as /clock would: the clock's ROS time override)."""
    node.set_parameters([Parameter("use_sim_time", value=True)])
    clock = node.get_clock()
    clock.set_ros_time_override(Time(seconds=start_s, clock_type=clock.clock_type))
    return clock


def test_sleeps_until_the_sim_clock_gets_there(ros_node: Any) -> None:
    clock = sim_time(ros_node, 1.0)
    stop = threading.Event()

    def tick() -> None:  # 100 Hz of sim time, ten times faster than the wall
        t = 1.0
        while not stop.is_set() and t < 3.0:
            t += 0.01
            clock.set_ros_time_override(Time(seconds=t, clock_type=clock.clock_type))
            time.sleep(0.001)

    ticker = threading.Thread(target=tick)
    ticker.start()
    try:
        wall0 = time.monotonic()
        assert sleep_until_clock(ros_node, 1.5, timeout_s=10.0)
        assert 1.5 <= clock.now().nanoseconds * 1e-9 < 1.8
        assert time.monotonic() - wall0 < 5.0
    finally:
        stop.set()
        ticker.join()


def test_a_stopped_clock_times_out_and_a_past_time_returns_at_once(ros_node: Any) -> None:
    sim_time(ros_node, 5.0)
    wall0 = time.monotonic()
    assert not sleep_until_clock(ros_node, 6.0, timeout_s=0.2)
    assert 0.15 < time.monotonic() - wall0 < 2.0
    wall0 = time.monotonic()
    assert sleep_until_clock(ros_node, 4.0, timeout_s=10.0)
    assert time.monotonic() - wall0 < 0.1


def test_without_sim_time_it_sleeps_the_difference(ros_node: Any) -> None:
    now_s = ros_node.get_clock().now().nanoseconds * 1e-9
    wall0 = time.monotonic()
    assert sleep_until_clock(ros_node, now_s + 0.1, timeout_s=5.0)
    assert 0.09 < time.monotonic() - wall0 < 1.0


def test_waits_for_a_future_completed_elsewhere_checking_as_it_goes() -> None:
    future: Future = Future()
    threading.Timer(0.1, future.set_result, args=(42,)).start()
    checks = []
    assert wait_for_future(future, 5.0, check=lambda: checks.append(1), check_every_s=0.01)
    assert future.result() == 42 and len(checks) >= 2
    assert not wait_for_future(Future(), 0.1)

    def give_up() -> None:
        raise RuntimeError("canceled")

    with pytest.raises(RuntimeError, match="canceled"):
        wait_for_future(Future(), 5.0, check=give_up)
