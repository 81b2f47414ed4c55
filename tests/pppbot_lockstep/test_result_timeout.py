"""Action servers keep a goal's result for Nav2's ``action_server_result_timeout`` after the goal
ends (10 s; rclpy's own 900 s kept a navigation's goals and paths for 15 minutes): a result asked
for while the goal ran is answered however long it ran, and the server then forgets the goal."""
from __future__ import annotations

from typing import Any

import pytest
from action_msgs.msg import GoalStatus
from nav2_msgs.action import Wait
from rclpy.parameter import Parameter

from pppbot_common.errors import ParameterError
from pppbot_common.ros.wait import wait_until
from pppbot_lockstep.ros.action_client import ActionClient
from pppbot_lockstep.ros.goals import GoalEnd, GoalServer
from pppbot_lockstep.ros.node import RESULT_TIMEOUT_S, StepExecutor, StepNode, result_timeout_of
from pppbot_lockstep.ros.port import FREE_RUNNING
from tests.pppbot_lockstep.test_requests import spin_until

pytestmark = pytest.mark.ros


def test_a_result_outlives_a_goal_longer_than_the_timeout_and_then_the_goal_is_forgotten(ros_node: Any) -> None:
    node = StepNode("result_timeout_test", context=ros_node.context,
                    parameter_overrides=[Parameter("action_server_result_timeout", value=0.5)])
    executor = StepExecutor(FREE_RUNNING, context=ros_node.context)
    executor.add_node(node)
    handles: list[Any] = []
    server = GoalServer(node, Wait, "result_timeout_test_wait", handles.append)
    client = ActionClient(node, Wait, "result_timeout_test_wait")
    try:
        wait_until(client.server_is_ready, 10, "the action server", node=None)
        goal = client.send_goal_async(Wait.Goal())
        spin_until(executor, goal.done, "the goal accepted")
        result = goal.result().get_result_async()  # as Nav2's clients ask: at once
        started = node.get_clock().now()
        spin_until(executor, lambda: (node.get_clock().now() - started).nanoseconds > 1.5e9, "1.5 s running")
        ended = Wait.Result(error_msg="ran three times the timeout")
        server.finish(handles[0], GoalEnd.SUCCEEDED, ended)
        spin_until(executor, result.done, "the result")
        assert result.result().status == GoalStatus.STATUS_SUCCEEDED
        assert result.result().result.error_msg == "ran three times the timeout"
        spin_until(executor, lambda: not server.server._goal_handles, "the goal forgotten")
        late = goal.result().get_result_async()
        spin_until(executor, late.done, "the late answer")
        assert late.result().status == GoalStatus.STATUS_UNKNOWN
    finally:
        server.destroy()
        client.destroy()
        executor.shutdown()
        node.destroy_node()


@pytest.mark.parametrize("value", [-1.0, 0.0, float("nan"), "ten", True])
def test_a_result_timeout_that_is_no_time_is_refused_naming_the_parameter(ros_node: Any, value: Any) -> None:
    node = StepNode("result_timeout_bad", context=ros_node.context,
                    parameter_overrides=[Parameter("action_server_result_timeout", value=value)])
    try:
        with pytest.raises(ParameterError, match=r"parameter 'action_server_result_timeout' = .*seconds above 0"):
            result_timeout_of(node)
    finally:
        node.destroy_node()


def test_nav2s_default_is_declared_when_the_node_has_none(ros_node: Any) -> None:
    node = StepNode("result_timeout_default", context=ros_node.context)
    try:
        assert result_timeout_of(node) == RESULT_TIMEOUT_S == 10.0
        assert node.get_parameter("action_server_result_timeout").value == 10.0
    finally:
        node.destroy_node()
