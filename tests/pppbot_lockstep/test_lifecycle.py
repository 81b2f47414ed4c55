"""ManagedNode: Nav2's lifecycle on rclpy, over real DDS (its services called as ``ros2 lifecycle`` calls them)."""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
from lifecycle_msgs.msg import State, Transition
from lifecycle_msgs.srv import GetState
from nav2_msgs.action import NavigateToPose
from rclpy.action import ActionClient, ActionServer
from std_msgs.msg import String

from pppbot_common.errors import PppbotError
from pppbot_common.ros.wait import change_state, send_goal, wait_until
from pppbot_lockstep.ros.lifecycle import ManagedNode

pytestmark = pytest.mark.ros


class Talker(ManagedNode):
    """Publishes on a timer and serves navigate_to_pose; configure fails while ``broken``."""

    def __init__(self) -> None:
        super().__init__("lifecycle_talker")
        self.broken = False
        self.calls: list[str] = []
        self.pub = self.create_publisher(String, "chatter", 10)
        self.create_timer(0.05, lambda: self.pub.publish(String(data=self.state)))
        self.server = ActionServer(self, NavigateToPose, "navigate_to_pose", self._execute,
                                   goal_callback=self.gated())

    def _execute(self, handle: Any) -> NavigateToPose.Result:
        handle.succeed()
        return NavigateToPose.Result()

    def configure(self) -> None:
        if self.broken:
            raise PppbotError("map file 'nowhere.yaml' not found")
        self.calls.append("configure")

    def activate(self) -> None:
        self.calls.append("activate")

    def deactivate(self) -> None:
        self.calls.append("deactivate")

    def cleanup(self) -> None:
        self.calls.append("cleanup")


@pytest.fixture
def talker(spin_in_background: Callable[..., Any]) -> Talker:
    node = Talker()
    spin_in_background(node)
    return node


def change(node: Any, transition: int = 0, label: str = "") -> bool:
    return change_state(node, "lifecycle_talker", transition, label)


def state_of(node: Any) -> str:
    client = node.create_client(GetState, "lifecycle_talker/get_state")
    assert client.wait_for_service(timeout_sec=10)
    future = client.call_async(GetState.Request())
    return str(wait_until(lambda: future.result() if future.done() else None, 10, "get_state",
                          node=node).current_state.label)


def test_a_managed_node_publishes_and_serves_goals_only_while_active(ros_node, talker):
    heard: list[str] = []
    ros_node.create_subscription(String, "chatter", lambda msg: heard.append(msg.data), 10)
    client = ActionClient(ros_node, NavigateToPose, "navigate_to_pose")
    assert client.wait_for_server(timeout_sec=10)
    assert state_of(ros_node) == "unconfigured"
    assert not send_goal(client, NavigateToPose.Goal(), ros_node).accepted
    assert change(ros_node, Transition.TRANSITION_CONFIGURE) and state_of(ros_node) == "inactive"
    assert not send_goal(client, NavigateToPose.Goal(), ros_node).accepted
    assert change(ros_node, label="activate") and state_of(ros_node) == "active"
    wait_until(lambda: len(heard) >= 3, 10, "the talker's messages", node=ros_node)
    assert set(heard) == {"active"}  # nothing it published before came through
    assert send_goal(client, NavigateToPose.Goal(), ros_node).accepted
    assert change(ros_node, Transition.TRANSITION_DEACTIVATE) and state_of(ros_node) == "inactive"
    assert not send_goal(client, NavigateToPose.Goal(), ros_node).accepted
    assert change(ros_node, Transition.TRANSITION_CLEANUP) and state_of(ros_node) == "unconfigured"
    assert talker.calls == ["configure", "activate", "deactivate", "cleanup"]
    assert change(ros_node, label="shutdown") and state_of(ros_node) == "finalized"


def test_a_transition_not_available_is_refused_and_the_node_lives_on(ros_node, talker):
    assert not change(ros_node, Transition.TRANSITION_ACTIVATE)  # rclpy alone raises out of the executor
    assert not change(ros_node, label="no_such_transition")
    assert state_of(ros_node) == "unconfigured"
    assert change(ros_node, Transition.TRANSITION_CONFIGURE) and talker.active is False
    assert talker.state == "inactive"


def test_a_configure_that_fails_leaves_the_node_unconfigured_and_says_why(ros_node, talker):
    talker.broken = True
    assert not change(ros_node, Transition.TRANSITION_CONFIGURE)
    assert state_of(ros_node) == "unconfigured"
    assert talker.configure_failure == "map file 'nowhere.yaml' not found"
    talker.broken = False
    assert change(ros_node, Transition.TRANSITION_CONFIGURE) and talker.configure_failure == ""
    assert int(talker._state_machine.current_state[0]) == State.PRIMARY_STATE_INACTIVE
