"""What an action server of pppbot keeps of an ended goal for rclpy's ``result_timeout``: not
its request, and its result serialized, still answered in full to a client asking late."""
from __future__ import annotations

from typing import Any

import pytest
from geometry_msgs.msg import PoseStamped
from nav2_msgs.action import ComputePathToPose
from rclpy.action import ActionClient
from rclpy.experimental import EventsExecutor

from pppbot_lockstep.ros.goals import GoalEnd, GoalServer
from pppbot_lockstep.ros.node import StepNode

pytestmark = pytest.mark.ros


def path(poses: int) -> ComputePathToPose.Result:
    result = ComputePathToPose.Result()
    result.path.header.frame_id = "map"
    for i in range(poses):
        pose = PoseStamped()
        pose.header.frame_id = "map"
        pose.pose.position.x, pose.pose.position.y = 0.01 * i, -0.02 * i
        pose.pose.orientation.w = 1.0
        result.path.poses.append(pose)
    result.planning_time.nanosec = 1234
    return result


def test_an_ended_goal_keeps_no_request_and_a_serialized_result_answered_in_full(ros_node: Any) -> None:
    node = StepNode("ended_goals_test_node", context=ros_node.context)
    goals: list[Any] = []
    server = GoalServer(node, ComputePathToPose, "ended_goals_test", goals.append)
    client = ActionClient(ros_node, ComputePathToPose, "ended_goals_test")
    executor = EventsExecutor(context=ros_node.context)
    executor.add_node(node)
    executor.add_node(ros_node)
    try:
        assert client.wait_for_server(timeout_sec=10)
        goal = ComputePathToPose.Goal(planner_id="GridBased", use_start=False)
        goal.goal.pose.position.x = 3.0
        sent = client.send_goal_async(goal)
        executor.spin_until_future_complete(sent, timeout_sec=10)
        accepted = sent.result()
        assert accepted.accepted
        result = accepted.get_result_async()  # asked before the goal ends, as clients do
        executor.spin_once(timeout_sec=0.1)
        assert len(goals) == 1 and goals[0].request.goal.pose.position.x == 3.0  # running: its request is there
        server.finish(goals[0], GoalEnd.SUCCEEDED, path(500))
        executor.spin_until_future_complete(result, timeout_sec=10)
        assert result.result().result == path(500)

        uuid = bytes(accepted.goal_id.uuid)
        kept = server.server._result_futures[uuid].result()
        assert goals[0].request is None  # ended: the path server no longer holds the goal
        assert isinstance(kept, bytes) and len(kept) < 40_000  # 500 poses at ~70 bytes, not ~500 Python objects

        late = client._get_result_async(accepted)  # another client, or this one again, later
        executor.spin_until_future_complete(late, timeout_sec=10)
        assert late.result().status == 4 and late.result().result == path(500)  # SUCCEEDED, in full
    finally:
        executor.remove_node(ros_node)
        executor.shutdown()
        client.destroy()
        server.destroy()
        node.destroy_node()
