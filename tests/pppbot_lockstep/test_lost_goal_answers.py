"""An action server of pppbot whose acceptance or result Fast DDS dropped (a client whose reply
reader it has not matched: rclpy only warns) sends it again until it goes, as its services do;
one that never goes is named. The goal runs meanwhile, as it would have."""
from __future__ import annotations

import time
from typing import Any

import pytest
from nav2_msgs.action import ComputePathToPose
from rclpy.action import ActionClient
from rclpy.action.client import ClientGoalHandle
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, QoSProfile

from pppbot_lockstep.ros import node as node_module
from pppbot_lockstep.ros.goals import GoalEnd, GoalServer
from pppbot_lockstep.ros.node import StepNode

pytestmark = pytest.mark.ros

#: The client's goal and result replies asked TRANSIENT_LOCAL: the server's VOLATILE reply writers
#: never match them, so every answer sent to it is dropped (its requests still arrive).
UNMATCHED = QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def spin_until(executor: Any, done: Any, timeout_s: float = 15.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while not done() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    return bool(done())


@pytest.fixture
def unmatched(ros_node: Any) -> Any:
    """A GoalServer on a StepNode, a client whose replies it never matches, an executor for both;
    what the node logged as warnings."""
    node = StepNode("lost_answers_test_node", context=ros_node.context)
    logged: list[str] = []
    node.get_logger().warning = lambda text, **_: logged.append(text)
    goals: list[Any] = []
    server = GoalServer(node, ComputePathToPose, "lost_answers_test", goals.append)
    client = ActionClient(ros_node, ComputePathToPose, "lost_answers_test", goal_service_qos_profile=UNMATCHED,
                          result_service_qos_profile=UNMATCHED)
    executor = SingleThreadedExecutor(context=ros_node.context)
    executor.add_node(node)
    executor.add_node(ros_node)
    try:
        yield node, server, client, executor, goals, logged
    finally:
        executor.remove_node(ros_node)
        executor.shutdown()
        client.destroy()
        server.destroy()
        node.destroy_node()


def send_until_taken(client: Any, executor: Any, goals: list[Any]) -> None:
    """Send goals until the server took one (its request reader may match the client late)."""
    for _ in range(20):
        client.send_goal_async(ComputePathToPose.Goal(planner_id="GridBased"))
        if spin_until(executor, lambda: goals, timeout_s=1.0):
            return
    raise AssertionError("the server never took a goal")


def test_an_acceptance_that_never_goes_is_sent_again_until_its_window_closes_and_named(
        unmatched: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(node_module, "RESEND_WINDOW_S", 0.5)
    node, server, client, executor, goals, logged = unmatched
    send_until_taken(client, executor, goals)
    assert goals[0].is_active  # the goal runs, as rclpy runs it
    assert [service for service, _, _ in node._undelivered] == ["/lost_answers_test/_action/send_goal"]
    assert spin_until(executor, lambda: not node._undelivered)
    assert logged == ["/lost_answers_test/_action/send_goal: an answer could not reach its client within 0.5 s "
                      "(the client gone before it was discovered?)"]


def test_an_acceptance_and_a_result_are_sent_again_until_they_go(unmatched: Any,
                                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    node, server, client, executor, goals, logged = unmatched
    real, sends = node_module.delivered, []

    def went_at_the_third_try(send: Any) -> bool:
        """The client's reply reader matched at the third try of each answer (the send itself is
        real, to a reader that never matches)."""
        went = real(send)
        name = send.func.__name__  # "_run_now": rclpy's handling of the goal, its acceptance sent in it
        sends.append((name, went))
        answer = {"_run_now": "send_goal_response"}.get(name, name)
        tries = sum({"_run_now": "send_goal_response"}.get(n, n) == answer for n, _ in sends)
        return went or (name != "_run_now" and tries >= 3)

    monkeypatch.setattr(node_module, "delivered", went_at_the_third_try)
    send_until_taken(client, executor, goals)
    assert sends[0] == ("_run_now", False)  # rclpy's own send of the acceptance: dropped
    assert spin_until(executor, lambda: not node._undelivered)
    assert [name for name, _ in sends] == ["_run_now", "send_goal_response", "send_goal_response"]
    assert logged == []

    goal_id = goals[0].goal_id
    accepted = ComputePathToPose.Impl.SendGoalService.Response(accepted=True)
    client._get_result_async(ClientGoalHandle(client, goal_id, accepted))  # the handle it never got
    server.finish(goals[0], GoalEnd.SUCCEEDED, ComputePathToPose.Result())
    assert spin_until(executor, lambda: any(name == "send_result_response" for name, _ in sends))
    assert spin_until(executor, lambda: not node._undelivered)
    assert [name for name, _ in sends[3:]] == ["send_result_response"] * 3 and logged == []
