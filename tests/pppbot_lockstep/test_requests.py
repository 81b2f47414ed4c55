"""Requests to a participant's servers are handled at steps: kept between steps, counted like
messages, handled when the next step is (or once overdue), on the executor the nodes run on."""
from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import pytest
import rclpy
from nav2_msgs.action import Wait
from std_srvs.srv import Trigger

from pppbot_common.ros.wait import wait_until
from pppbot_lockstep.ros import requests as lockstep_requests
from pppbot_lockstep.ros.action_client import ActionClient
from pppbot_lockstep.ros.node import StepActionServer, StepExecutor, StepNode
from pppbot_lockstep.ros.participant import Participant
from pppbot_lockstep.ros.requests import request_key

pytestmark = pytest.mark.ros


@pytest.fixture
def stepped(ros_node: Any) -> Iterator[tuple[StepNode, Participant, Any]]:
    """A node of a participant's process, on the executor ``run_nodes`` spins it with; requests are
    kept (time runs, no step is being handled)."""
    participant = Participant("requests_test", ros_node)
    node = StepNode("requests_test_node", port=participant, context=ros_node.context)
    participant.requests.leave_step(time_runs=True)
    executor = StepExecutor(participant, context=ros_node.context)
    executor.add_node(node)
    try:
        yield node, participant, executor
    finally:
        participant.requests.overdue(lambda execute: None, everything=True)
        executor.shutdown()
        node.destroy_node()


def spin(executor: Any, seconds: float) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        executor.spin_once(timeout_sec=0.05)


def spin_until(executor: Any, condition: Any, what: str, timeout_s: float = 10.0) -> None:
    end = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < end, f"timed out waiting for {what}"
        executor.spin_once(timeout_sec=0.05)


def counted(participant: Participant, key: str) -> Any:
    return next(c for c in participant.deliveries.subscriptions if c.topic == key)


def test_a_service_request_between_steps_is_answered_at_the_next_step_with_that_steps_state(
        stepped: tuple[StepNode, Participant, Any]) -> None:
    node, participant, executor = stepped
    state = {"time": "step 1"}

    def answer(request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        response.success, response.message = True, state["time"]
        return response

    service = node.create_service(Trigger, "requests_test_trigger", answer)
    key = request_key(service.service_name)
    client = node.create_client(Trigger, "requests_test_trigger")
    wait_until(client.service_is_ready, 10, "the service", node=None)
    sent = participant.counters.published.get(key, 0)
    future = client.call_async(Trigger.Request())
    assert participant.counters.published[key] == sent + 1  # the client counts it on the server's key
    spin_until(executor, lambda: counted(participant, key).received == 1, "the request taken")
    spin(executor, 0.3)
    assert not future.done()  # kept: no step is being handled
    state["time"] = "step 2"
    participant.requests.enter_step(executor.create_task)
    spin_until(executor, future.done, "the answer")
    assert future.result().message == "step 2"  # handled at the step, with what the step brought


def test_a_request_during_a_step_is_answered_at_once(stepped: tuple[StepNode, Participant, Any]) -> None:
    node, participant, executor = stepped
    participant.requests.enter_step(executor.create_task)
    node.create_service(Trigger, "requests_test_now",
                        lambda request, response: Trigger.Response(success=True, message="now"))
    client = node.create_client(Trigger, "requests_test_now")
    wait_until(client.service_is_ready, 10, "the service", node=None)
    future = client.call_async(Trigger.Request())
    spin_until(executor, future.done, "the answer")
    assert future.result().message == "now"


def test_a_kept_request_no_step_comes_for_is_answered_once_overdue(
        stepped: tuple[StepNode, Participant, Any], monkeypatch: pytest.MonkeyPatch) -> None:
    node, participant, executor = stepped
    monkeypatch.setattr(lockstep_requests, "OVERDUE_S", 0.5)
    node.create_service(Trigger, "requests_test_overdue",
                        lambda request, response: Trigger.Response(success=True, message="late"))
    client = node.create_client(Trigger, "requests_test_overdue")
    wait_until(client.service_is_ready, 10, "the service", node=None)
    future = client.call_async(Trigger.Request())
    taken = time.monotonic()
    while not future.done():
        assert time.monotonic() - taken < 10, "the overdue answer"
        executor.spin_once(timeout_sec=0.05)
        participant.requests.overdue(executor.create_task)  # as the participant's spin loop does
    assert future.result().message == "late"
    assert time.monotonic() - taken >= 0.5  # not before it was overdue


def test_an_action_goal_between_steps_is_accepted_and_executed_at_the_next_step(
        stepped: tuple[StepNode, Participant, Any]) -> None:
    node, participant, executor = stepped
    executed: list[str] = []
    state = {"time": "step 1"}

    def execute(handle: Any) -> Wait.Result:
        executed.append(state["time"])
        handle.succeed()
        return Wait.Result()

    server = StepActionServer(node, Wait, "requests_test_wait", execute)
    key = request_key(node.resolve_topic_name("requests_test_wait", only_expand=True))
    client = ActionClient(node, Wait, "requests_test_wait")
    wait_until(client.server_is_ready, 10, "the action server", node=None)
    sent = participant.counters.published.get(key, 0)
    goal = client.send_goal_async(Wait.Goal())
    assert participant.counters.published[key] == sent + 1
    spin_until(executor, lambda: counted(participant, key).received == 1, "the goal taken")
    spin(executor, 0.3)
    assert not goal.done() and executed == []
    state["time"] = "step 2"
    participant.requests.enter_step(executor.create_task)
    spin_until(executor, goal.done, "the goal's answer")
    assert goal.result().accepted
    result = goal.result().get_result_async()
    spin_until(executor, result.done, "the result")
    assert executed == ["step 2"]
    server.destroy()
    client.destroy()


def test_a_plain_rclpy_server_in_the_same_process_answers_at_once(
        stepped: tuple[StepNode, Participant, Any], ros_node: Any) -> None:
    """Only a StepNode's servers keep requests: a plain rclpy node beside them is rclpy's."""
    _, _, executor = stepped
    plain = rclpy.create_node("requests_test_plain", context=ros_node.context)
    executor.add_node(plain)
    try:
        plain.create_service(Trigger, "requests_test_plain_service",
                             lambda request, response: Trigger.Response(success=True, message="plain"))
        client = plain.create_client(Trigger, "requests_test_plain_service")
        wait_until(client.service_is_ready, 10, "the service", node=None)
        future = client.call_async(Trigger.Request())
        spin_until(executor, future.done, "the answer")  # no step is handled: a StepNode's would wait
        assert future.result().message == "plain"
    finally:
        plain.destroy_node()
