"""bt_navigator's goals as Nav2's: a new goal on the running tree preempts it (the old goal aborts,
the tree goes on with the new goal), a goal asking another tree while one runs is refused and
the running one goes on, and a cancel ends the goal canceled. The trees are written by the test
and name no server; the robot's pose is a static transform."""
from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from action_msgs.msg import GoalStatus
from geometry_msgs.msg import TransformStamped
from lifecycle_msgs.msg import Transition
from nav2_msgs.action import NavigateThroughPoses, NavigateToPose
from rclpy.action import ActionClient
from tf2_msgs.msg import TFMessage

from pppbot_common.ros.qos import LATCHED
from pppbot_common.ros.wait import change_state, send_goal, wait_until
from pppbot_nav.ros.navigator import OTHER_TREE, Navigator

#: Runs until halted (a minute), then succeeds.
LONG = ('<root BTCPP_format="4" main_tree_to_execute="MainTree"><BehaviorTree ID="MainTree">'
        '<Delay delay_msec="60000"><AlwaysSuccess/></Delay></BehaviorTree></root>\n')
SHORT = ('<root BTCPP_format="4" main_tree_to_execute="MainTree"><BehaviorTree ID="MainTree">'
         '<AlwaysSuccess/></BehaviorTree></root>\n')


class Goals:
    def __init__(self, node: Any, folder: Path) -> None:
        self.node = node
        self.long, self.short = folder / "long.xml", folder / "short.xml"
        self.long.write_text(LONG)
        self.short.write_text(SHORT)
        self.client = ActionClient(node, NavigateToPose, "navigate_to_pose")
        self.through = ActionClient(node, NavigateThroughPoses, "navigate_through_poses")
        assert self.client.wait_for_server(timeout_sec=10) and self.through.wait_for_server(timeout_sec=10)

    def send(self, tree: Path, x: float = 1.0) -> Any:
        goal = NavigateToPose.Goal(behavior_tree=str(tree))
        goal.pose.header.frame_id = "map"
        goal.pose.pose.position.x = x
        goal.pose.pose.orientation.w = 1.0
        handle = send_goal(self.client, goal, self.node)
        assert handle.accepted
        return handle

    def end(self, handle: Any, timeout_s: float = 20.0) -> Any:
        future = handle.get_result_async()
        return wait_until(lambda: future.result() if future.done() else None, timeout_s, "the goal's end",
                          node=self.node)


@pytest.fixture
def goals(ros_node: Any, spin_in_background: Any, tmp_path: Path) -> Iterator[Goals]:
    tf = ros_node.create_publisher(TFMessage, "/tf_static", LATCHED)
    robot = TransformStamped()
    robot.header.frame_id, robot.child_frame_id = "map", "base_link"
    robot.transform.rotation.w = 1.0
    tf.publish(TFMessage(transforms=[robot]))
    navigator = Navigator()
    spin_in_background(navigator)
    assert change_state(ros_node, "bt_navigator", Transition.TRANSITION_CONFIGURE)
    assert change_state(ros_node, "bt_navigator", Transition.TRANSITION_ACTIVATE)
    yield Goals(ros_node, tmp_path)


@pytest.mark.ros
def test_a_new_goal_preempts_the_running_tree_and_a_cancel_ends_it(goals: Goals) -> None:
    first = goals.send(goals.long, x=1.0)
    second = goals.send(goals.long, x=2.0)
    end = goals.end(first)
    assert end.status == GoalStatus.STATUS_ABORTED and end.result.error_msg == "preempted by a new goal"
    second.cancel_goal_async()
    end = goals.end(second)
    assert end.status == GoalStatus.STATUS_CANCELED
    # The navigator takes goals again, and a tree that ends ends its goal.
    assert goals.end(goals.send(goals.short)).status == GoalStatus.STATUS_SUCCEEDED


@pytest.mark.ros
def test_a_goal_with_another_tree_is_refused_and_the_running_one_goes_on(goals: Goals) -> None:
    running = goals.send(goals.long)
    refused = goals.send(goals.short)
    end = goals.end(refused)
    assert end.status == GoalStatus.STATUS_ABORTED and end.result.error_msg == OTHER_TREE
    # A navigate_through_poses goal is another navigator's: refused too.
    through = NavigateThroughPoses.Goal()
    through.poses.append(NavigateToPose.Goal().pose)
    through.poses[0].header.frame_id = "map"
    handle = send_goal(goals.through, through, goals.node)
    assert handle.accepted
    assert goals.end(handle).status == GoalStatus.STATUS_ABORTED
    future = running.get_result_async()
    assert not future.done()  # still running
    running.cancel_goal_async()
    assert goals.end(running).status == GoalStatus.STATUS_CANCELED
