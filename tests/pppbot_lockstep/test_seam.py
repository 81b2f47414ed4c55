"""Lockstep's one seam: a node takes part through its step port; nothing of rclpy is replaced.

rclpy's classes are the same before and after a participant has run a step with its nodes'
publishers, clients, services, action servers and clients; a plain rclpy node in the same
process is rclpy's alone (tests/pppbot_lockstep/test_outbox.py and test_requests.py send and
serve beside a participant). The rclpy members pppbot's subclasses extend are rclpy's public
arguments and Waitable's interface, plus two private methods of rclpy's ActionClient that its
goal handles call: this test fails loudly when an rclpy release renames them.
"""
from __future__ import annotations

import inspect
from typing import Any

import pytest
import rclpy
import rclpy.action.client
import rclpy.action.server
import rclpy.client
import rclpy.executors
import rclpy.lifecycle
import rclpy.node
import rclpy.publisher
import rclpy.service
import rclpy.subscription
import rclpy.task
import rclpy.timer
from builtin_interfaces.msg import Time as TimeMsg
from nav2_msgs.action import Wait
from std_msgs.msg import String
from std_srvs.srv import Trigger

from pppbot_interfaces.msg import LockstepStep
from pppbot_lockstep.ros.action_client import ActionClient
from pppbot_lockstep.ros.lifecycle import ManagedNode
from pppbot_lockstep.ros.node import StepActionServer, StepExecutor, StepNode
from pppbot_lockstep.ros.participant import Participant

pytestmark = pytest.mark.ros

RCLPY_CLASSES = (rclpy.node.Node, rclpy.publisher.Publisher, rclpy.subscription.Subscription, rclpy.client.Client,
                 rclpy.service.Service, rclpy.timer.Timer, rclpy.task.Task, rclpy.task.Future,
                 rclpy.action.client.ActionClient, rclpy.action.client.ClientGoalHandle,
                 rclpy.action.server.ActionServer, rclpy.action.server.ServerGoalHandle,
                 rclpy.lifecycle.LifecycleNode, rclpy.lifecycle.LifecyclePublisher, rclpy.executors.Executor)


def members(cls: type) -> dict[str, Any]:
    return dict(vars(cls))


def test_rclpys_classes_are_the_same_after_a_participant_ran_a_step(ros_node: Any) -> None:
    before = {cls: members(cls) for cls in RCLPY_CLASSES}
    participant = Participant("seam_test", ros_node)
    node = StepNode("seam_test_node", port=participant, context=ros_node.context)
    managed = ManagedNode("seam_test_managed", port=participant, context=ros_node.context)
    executor = StepExecutor(participant, context=ros_node.context)
    try:
        node.create_publisher(String, "seam_test", 10)
        node.create_subscription(String, "seam_test", lambda msg: None, 10, data_path=True)
        node.create_client(Trigger, "seam_test_service")
        node.create_service(Trigger, "seam_test_service", lambda request, response: response)
        StepActionServer(node, Wait, "seam_test_wait", lambda handle: Wait.Result())
        ActionClient(node, Wait, "seam_test_wait")
        managed.create_publisher(String, "seam_test_managed", 10)
        node.step_timer(0.1, lambda: None)
        executor.add_node(node)
        participant.start(executor, [node, managed])
        participant._joined = True
        participant._on_step(LockstepStep(seq=1, stamp=TimeMsg(sec=1), round=0, timers=True))
        executor.spin_once(timeout_sec=0.1)
    finally:
        executor.shutdown()
        managed.destroy_node()
        node.destroy_node()
    after = {cls: members(cls) for cls in RCLPY_CLASSES}
    for cls in RCLPY_CLASSES:
        assert after[cls] == before[cls], f"{cls.__module__}.{cls.__qualname__} was changed"


def test_the_rclpy_members_pppbot_extends_are_still_rclpys() -> None:
    """The public arguments and methods the seam builds on, and the private ones it overrides."""
    assert "publisher_class" in inspect.signature(rclpy.node.Node.create_publisher).parameters
    for cls, name in ((rclpy.client.Client, "call_async"), (rclpy.service.Service, "send_response"),
                      (rclpy.action.server.ActionServer, "execute"),
                      (rclpy.action.client.ActionClient, "send_goal_async"),
                      (rclpy.action.client.ActionClient, "_cancel_goal_async"),
                      (rclpy.action.client.ActionClient, "_get_result_async"),
                      (rclpy.lifecycle.LifecyclePublisher, "publish")):
        assert callable(getattr(cls, name, None)), f"rclpy's {cls.__qualname__} has no {name}"
    # A goal handle's cancel and result requests go through its client's private methods:
    source = inspect.getsource(rclpy.action.client.ClientGoalHandle)
    assert "_cancel_goal_async" in source and "_get_result_async" in source


def test_a_node_without_a_port_runs_freely_as_rclpys(ros_node: Any) -> None:
    """A StepNode made by a test or a tool (no port) publishes, calls and serves at once."""
    node = StepNode("seam_test_free", context=ros_node.context)
    try:
        assert not node.port.counts and not node.port.lockstep
        publisher = node.create_publisher(String, "seam_test_free", 10)
        publisher.publish(String(data="now"))  # sent at once: nothing to hold it
        assert node.step_timer(0.1, lambda: None).__class__ is rclpy.timer.Timer
    finally:
        node.destroy_node()


