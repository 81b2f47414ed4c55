"""A service of pppbot's answers every request, even one its callback fails on: the caller gets
the response as it stood (its failure fields false), the node logs the failure once per kind and
serves on."""
from __future__ import annotations

import time
import warnings
from typing import Any

import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.experimental import EventsExecutor
from std_srvs.srv import SetBool

from pppbot_lockstep.ros.node import StepNode, delivered

pytestmark = pytest.mark.ros


def test_a_request_the_callback_fails_on_is_answered_and_the_node_serves_on(ros_node: Any) -> None:
    node = StepNode("answering_test_node", context=ros_node.context)
    logged: list[str] = []
    node.get_logger().error = lambda text, **_: logged.append(text)

    def set_bool(request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        if not request.data:
            raise ValueError("false is not taken")
        response.success, response.message = True, "taken"
        return response

    node.create_service(SetBool, "answering_test", set_bool)
    client = ros_node.create_client(SetBool, "answering_test")
    executor = SingleThreadedExecutor(context=ros_node.context)
    executor.add_node(node)
    executor.add_node(ros_node)
    try:
        assert client.wait_for_service(timeout_sec=10)
        answers = []
        for data in (False, False, True):
            future = client.call_async(SetBool.Request(data=data))
            executor.spin_until_future_complete(future, timeout_sec=10)
            assert future.done()
            answers.append((future.result().success, future.result().message))
        assert answers == [(False, ""), (False, ""), (True, "taken")]
        # Named once for the two failures of one kind within its throttle period.
        assert logged == ["answering_test: could not handle a request (ValueError: false is not taken); "
                          "answered with an empty response"]
    finally:
        executor.remove_node(ros_node)
        executor.shutdown()
        node.destroy_node()



# ----------------------------------------------------------------- answers Fast DDS could not deliver yet
def test_delivered_tells_a_dropped_answer_and_passes_other_warnings_on() -> None:
    def dropped() -> None:  # what rclpy does when rmw_fastrtps timed out waiting for the client's reply reader
        warnings.warn("failed to send response (timeout): client will not receive response", RuntimeWarning,
                      stacklevel=1)

    assert not delivered(dropped)
    assert delivered(lambda: None)
    with pytest.warns(UserWarning, match="something else"):
        assert delivered(lambda: warnings.warn("something else", UserWarning, stacklevel=1))


def spin_until(executor: Any, done: Any, timeout_s: float = 10.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not done() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)


def test_an_undelivered_answer_is_sent_again_until_it_goes_and_then_the_node_rests(ros_node: Any) -> None:
    node = StepNode("resend_test_node", context=ros_node.context)
    node.create_service(SetBool, "resend_test", lambda request, response: response)
    timers_before = list(node.timers)
    assert timers_before == []  # nothing to send again: no timer
    executor = EventsExecutor(context=ros_node.context)  # the node runner's
    executor.add_node(node)
    outcomes = iter([False, False, True])  # the client's reply reader matched at the third try
    tries: list[bool] = []

    def attempt() -> bool:
        tries.append(next(outcomes))
        return tries[-1]

    try:
        node._send_again("/resend_test", attempt)
        spin_until(executor, lambda: not node._undelivered)
        (timer,) = node.timers  # made for the answer sent again, canceled once it went
        assert len(tries) == 3 and timer.is_canceled()
    finally:
        executor.shutdown()
        node.destroy_node()


def test_an_answer_that_never_goes_is_given_up_after_its_window_and_named(ros_node: Any,
                                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("pppbot_lockstep.ros.node.RESEND_WINDOW_S", 0.3)
    node = StepNode("resend_give_up_node", context=ros_node.context)
    logged: list[str] = []
    node.get_logger().warning = lambda text, **_: logged.append(text)
    node.create_service(SetBool, "resend_give_up", lambda request, response: response)
    executor = SingleThreadedExecutor(context=ros_node.context)
    executor.add_node(node)
    tries: list[bool] = []

    def attempt() -> bool:  # the client never discovered: never delivered
        tries.append(False)
        return False

    try:
        node._send_again("/resend_give_up", attempt)
        spin_until(executor, lambda: not node._undelivered)
        assert not node._undelivered and node._resend_timer.is_canceled()
        assert len(tries) >= 2  # sent again until the window closed
        assert logged == ["/resend_give_up: an answer could not reach its client within 0.3 s (the client gone "
                          "before it was discovered?)"]
    finally:
        executor.shutdown()
        node.destroy_node()
