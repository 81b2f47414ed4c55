"""Requests to a participant's servers are handled at steps: kept between steps, counted like
messages, handled when the next step is (or once overdue), on the executor the nodes run on."""
from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import pytest
from nav2_msgs.action import Wait
from rclpy.action import ActionClient, ActionServer
from rclpy.experimental import EventsExecutor
from std_srvs.srv import Trigger

from pppbot_common.ros import lockstep_requests
from pppbot_common.ros.lockstep_counting import COUNTERS, Receiver, install_counting
from pppbot_common.ros.lockstep_requests import REQUESTS, request_key
from pppbot_common.ros.wait import wait_until

pytestmark = pytest.mark.ros


@pytest.fixture
def executor(ros_node: Any) -> Iterator[Any]:
    """The test node in lockstep's bookkeeping (as a participant's process), on an EventsExecutor
    as ``run_nodes`` spins nodes; requests are kept (time runs, no step is being handled)."""
    install_counting()
    deliveries: list[int] = []
    REQUESTS.context, REQUESTS.receiver = ros_node.context, Receiver(lambda: deliveries.append(1))
    REQUESTS.leave_step(time_runs=True)
    events = EventsExecutor()
    events.add_node(ros_node)
    try:
        yield events
    finally:
        REQUESTS.reset()
        events.shutdown()


def spin(executor: Any, seconds: float) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        executor.spin_once(timeout_sec=0.05)


def spin_until(executor: Any, condition: Any, what: str, timeout_s: float = 10.0) -> None:
    end = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < end, f"timed out waiting for {what}"
        executor.spin_once(timeout_sec=0.05)


def counted(key: str) -> Any:
    return next(c for c in REQUESTS.receiver.deliveries.subscriptions if c.topic == key)


def test_a_service_request_between_steps_is_answered_at_the_next_step_with_that_steps_state(
        ros_node: Any, executor: Any) -> None:
    state = {"time": "step 1"}

    def answer(request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        response.success, response.message = True, state["time"]
        return response

    service = ros_node.create_service(Trigger, "requests_test_trigger", answer)
    key = request_key(service.service_name)
    client = ros_node.create_client(Trigger, "requests_test_trigger")
    wait_until(client.service_is_ready, 10, "the service", node=None)
    sent = COUNTERS.published.get(key, 0)
    future = client.call_async(Trigger.Request())
    assert COUNTERS.published[key] == sent + 1  # the client counts it on the server's key
    spin_until(executor, lambda: counted(key).received == 1, "the request taken")
    spin(executor, 0.3)
    assert not future.done()  # kept: no step is being handled
    state["time"] = "step 2"
    REQUESTS.enter_step(executor.create_task)
    spin_until(executor, future.done, "the answer")
    assert future.result().message == "step 2"  # handled at the step, with what the step brought


def test_a_request_during_a_step_is_answered_at_once(ros_node: Any, executor: Any) -> None:
    REQUESTS.enter_step(executor.create_task)
    ros_node.create_service(Trigger, "requests_test_now",
                            lambda request, response: Trigger.Response(success=True, message="now"))
    client = ros_node.create_client(Trigger, "requests_test_now")
    wait_until(client.service_is_ready, 10, "the service", node=None)
    future = client.call_async(Trigger.Request())
    spin_until(executor, future.done, "the answer")
    assert future.result().message == "now"


def test_a_kept_request_no_step_comes_for_is_answered_once_overdue(
        ros_node: Any, executor: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(lockstep_requests, "OVERDUE_S", 0.5)
    ros_node.create_service(Trigger, "requests_test_overdue",
                            lambda request, response: Trigger.Response(success=True, message="late"))
    client = ros_node.create_client(Trigger, "requests_test_overdue")
    wait_until(client.service_is_ready, 10, "the service", node=None)
    future = client.call_async(Trigger.Request())
    taken = time.monotonic()
    while not future.done():
        assert time.monotonic() - taken < 10, "the overdue answer"
        executor.spin_once(timeout_sec=0.05)
        REQUESTS.overdue(executor.create_task)  # as the participant's spin loop does
    assert future.result().message == "late"
    assert time.monotonic() - taken >= 0.5  # not before it was overdue


def test_an_action_goal_between_steps_is_accepted_and_executed_at_the_next_step(
        ros_node: Any, executor: Any) -> None:
    executed: list[str] = []
    state = {"time": "step 1"}

    def execute(handle: Any) -> Wait.Result:
        executed.append(state["time"])
        handle.succeed()
        return Wait.Result()

    server = ActionServer(ros_node, Wait, "requests_test_wait", execute)
    key = server._pppbot_request_key  # type: ignore[attr-defined]
    assert key == request_key(ros_node.resolve_topic_name("requests_test_wait", only_expand=True))
    client = ActionClient(ros_node, Wait, "requests_test_wait")
    wait_until(client.server_is_ready, 10, "the action server", node=None)
    sent = COUNTERS.published.get(key, 0)
    goal = client.send_goal_async(Wait.Goal())
    assert COUNTERS.published[key] == sent + 1
    spin_until(executor, lambda: counted(key).received == 1, "the goal taken")
    spin(executor, 0.3)
    assert not goal.done() and executed == []
    state["time"] = "step 2"
    REQUESTS.enter_step(executor.create_task)
    spin_until(executor, goal.done, "the goal's answer")
    assert goal.result().accepted
    result = goal.result().get_result_async()
    spin_until(executor, result.done, "the result")
    assert executed == ["step 2"]
    server.destroy()
    client.destroy()
