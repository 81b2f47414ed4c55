"""A lockstep participant's outbox: sends held until the next step, counted at once, in order."""
from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import pytest
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry, Path
from sensor_msgs.msg import LaserScan
from std_msgs.msg import String
from std_srvs.srv import Trigger

from pppbot_common.ros.wait import wait_until
from pppbot_lockstep.ros.counting import HeldFuture, copied
from pppbot_lockstep.ros.node import StepNode
from pppbot_lockstep.ros.participant import Participant

pytestmark = pytest.mark.ros
TOPIC = "/outbox_test"


@pytest.fixture
def participant(ros_node: Any) -> Iterator[Participant]:
    """A participant holding what its nodes send (time runs) on a topic another participant counts."""
    p = Participant("outbox_test", ros_node)
    p.outbox.holding = True
    p.outbox.held_topics = frozenset({TOPIC})
    try:
        yield p
    finally:
        p.outbox.send_all()  # as a participant leaving: nothing held is lost


@pytest.fixture
def node(ros_node: Any, participant: Participant, spin_in_background: Any) -> StepNode:
    """A node of the participant's process, spun as ``run_nodes`` spins it."""
    step_node = StepNode("outbox_test_node", port=participant, context=ros_node.context)
    spin_in_background(step_node)
    return step_node


def spin_for(node: Any, seconds: float) -> None:
    """Serve callbacks for ``seconds`` (a message sent meanwhile would arrive)."""
    end = time.monotonic() + seconds
    wait_until(lambda: time.monotonic() >= end, seconds + 1.0, "time to pass", node=node)


def answer_and_step(p: Participant) -> None:
    """What a participant does: its answer seals what it holds; the next step sends it."""
    with p.outbox.lock:
        p.outbox.seal()
    p.outbox.send_sealed()


def test_held_messages_are_counted_at_once_and_go_out_in_order_with_the_next_step(
        ros_node: Any, participant: Participant, node: StepNode) -> None:
    counters, outbox = participant.counters, participant.outbox
    got: list[str] = []
    pub = node.create_publisher(String, TOPIC, 10)
    ros_node.create_subscription(String, TOPIC, lambda m: got.append(m.data), 10)
    wait_until(lambda: pub.get_subscription_count() > 0, 10, "the subscription matched", node=ros_node)
    published, sends = counters.published.get(TOPIC, 0), counters.sends
    msg = String(data="a")
    pub.publish(msg)
    msg.data = "b"  # the sender reuses its message: what was held is what it published
    pub.publish(msg)
    # Counted when held: the answer reports them, the next step's totals include them.
    assert counters.published[TOPIC] == published + 2 and counters.sends == sends + 2
    with outbox.lock:
        outbox.seal()  # the answer
    pub.publish(String(data="c"))  # after the answer: it waits for the step after next
    spin_for(ros_node, 0.3)
    assert got == []
    outbox.send_sealed()  # the next step
    wait_until(lambda: len(got) >= 2, 10, "the sealed messages", node=ros_node)
    spin_for(ros_node, 0.3)
    assert got == ["a", "b"]
    answer_and_step(participant)
    wait_until(lambda: len(got) >= 3, 10, "the message held after the answer", node=ros_node)
    assert got == ["a", "b", "c"]


def test_what_nobody_else_counts_goes_out_at_once_in_a_step_and_right_after_the_answer_outside_one(
        ros_node: Any, participant: Participant, node: StepNode) -> None:
    counters, outbox = participant.counters, participant.outbox
    outbox.held_topics = frozenset()  # only the simulator's process counts the topic (a hosted twist_mux's input)
    got: list[str] = []
    pub = node.create_publisher(String, TOPIC, 10)
    ros_node.create_subscription(String, TOPIC, lambda m: got.append(m.data), 10)
    wait_until(lambda: pub.get_subscription_count() > 0, 10, "the subscription matched", node=ros_node)
    sends = counters.sends
    pub.publish(String(data="before the step"))  # between steps (a message came in): held until the answer
    with outbox.lock:
        outbox.in_step = True  # a step came
    pub.publish(String(data="in the step"))  # out at once
    wait_until(lambda: got == ["in the step"], 10, "the message sent in the step", node=ros_node)
    assert counters.sends == sends  # no round asked: the simulator's process waits for it after the answers
    with outbox.lock:
        outbox.seal()  # the answer, then what waited for it
    outbox.send_with_answer()
    wait_until(lambda: len(got) == 2, 10, "the message sent before the step", node=ros_node)
    assert got == ["in the step", "before the step"] and counters.published[TOPIC] == 2


def test_a_send_only_quiet_processes_count_is_held_without_asking_for_a_round(
        ros_node: Any, participant: Participant, node: StepNode) -> None:
    """Another participant only records the topic (quiet): the message still waits for the next step,
    but that can be the next sync time's: the answer asks for no round at this one."""
    counters, outbox = participant.counters, participant.outbox
    outbox.quiet_topics = frozenset({TOPIC})  # held (the fixture), and nobody else reacts to it
    got: list[str] = []
    pub = node.create_publisher(String, TOPIC, 10)
    ros_node.create_subscription(String, TOPIC, lambda m: got.append(m.data), 10)
    wait_until(lambda: pub.get_subscription_count() > 0, 10, "the subscription matched", node=ros_node)
    sends = counters.sends
    with outbox.lock:
        outbox.in_step = True
    pub.publish(String(data="recorded by another"))
    assert counters.sends == sends and counters.published[TOPIC] == 1  # counted, no round asked
    with outbox.lock:
        outbox.seal()
    outbox.send_with_answer()
    assert got == []  # not with the answer: with the next step
    outbox.send_sealed()
    wait_until(lambda: got == ["recorded by another"], 10, "the held message, with the next step", node=ros_node)
    outbox.quiet_topics = frozenset()
    pub.publish(String(data="reacted to"))  # a reacting participant counts it again: a round is asked
    assert counters.sends == sends + 1
    answer_and_step(participant)
    wait_until(lambda: len(got) == 2, 10, "the second message", node=ros_node)


def test_a_held_request_gets_a_future_that_completes_with_the_reply(
        ros_node: Any, participant: Participant, node: StepNode) -> None:
    calls: list[int] = []

    def serve(request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        calls.append(1)
        response.success, response.message = True, f"call {len(calls)}"
        return response

    ros_node.create_service(Trigger, "/outbox_test_service", serve)
    client = node.create_client(Trigger, "/outbox_test_service")
    assert client.wait_for_service(timeout_sec=10)
    sent_at: list[bool] = []
    future = client.call_async(Trigger.Request())
    assert isinstance(future, HeldFuture) and not future.sent
    future.when_sent(lambda: sent_at.append(True))  # where a participant takes its hold
    spin_for(ros_node, 0.3)
    assert calls == [] and not future.done() and sent_at == []
    answer_and_step(participant)
    assert future.sent and sent_at == [True]
    wait_until(future.done, 10, "the reply", node=ros_node)
    assert calls == [1] and future.result().success and future.result().message == "call 1"


def test_without_holding_sends_go_out_at_once(ros_node: Any, participant: Participant, node: StepNode) -> None:
    participant.outbox.send_all()  # time holds at its start: nothing is held
    assert not participant.outbox.holding
    got: list[str] = []
    pub = node.create_publisher(String, TOPIC, 10)
    ros_node.create_subscription(String, TOPIC, lambda m: got.append(m.data), 10)
    wait_until(lambda: pub.get_subscription_count() > 0, 10, "the subscription matched", node=ros_node)
    published = participant.counters.published.get(TOPIC, 0)
    pub.publish(String(data="now"))
    assert participant.counters.published[TOPIC] == published + 1
    wait_until(lambda: got == ["now"], 10, "the message", node=ros_node)


def test_a_plain_rclpy_publisher_beside_them_is_never_held(ros_node: Any, participant: Participant,
                                                           node: StepNode) -> None:
    """Only a StepNode's endpoints go through the participant: a plain rclpy node in the same
    process publishes as rclpy does, while the participant holds."""
    got: list[str] = []
    pub = ros_node.create_publisher(String, TOPIC, 10)
    ros_node.create_subscription(String, TOPIC, lambda m: got.append(m.data), 10)
    wait_until(lambda: pub.get_subscription_count() > 0, 10, "the subscription matched", node=ros_node)
    published = participant.counters.published.get(TOPIC, 0)
    pub.publish(String(data="plain"))
    wait_until(lambda: got == ["plain"], 10, "the plain message", node=ros_node)
    assert participant.counters.published.get(TOPIC, 0) == published  # not counted either


def test_a_held_request_is_copied_whole_and_apart_from_the_senders_message() -> None:
    """What a held request sends is the message as it was at the call: every field equal, nothing
    shared that can change (nested messages, lists of them, arrays), whatever the sender does after."""
    goal = Path()  # as a FollowPath goal carries it
    goal.header.frame_id = "map"
    goal.poses = [PoseStamped() for _ in range(3)]
    for i, pose in enumerate(goal.poses):
        pose.pose.position.x, pose.header.stamp.sec = 0.5 * i, i
    scan = LaserScan(ranges=[1.0, 2.0, float("inf")], intensities=[3.0, 4.0, 5.0])
    odom = Odometry()
    odom.pose.covariance[0] = 0.25
    for message in (goal, scan, odom):
        twin = copied(message)
        assert twin == message and twin is not message
    twin = copied(goal)
    goal.poses[1].pose.position.x = 9.0
    goal.poses.append(PoseStamped())
    goal.header.frame_id = "odom"
    assert twin.header.frame_id == "map" and len(twin.poses) == 3
    assert [p.pose.position.x for p in twin.poses] == [0.0, 0.5, 1.0]
    twin_scan, twin_odom = copied(scan), copied(odom)
    scan.ranges[0] = 7.0
    odom.pose.covariance[0] = 1.0
    assert twin_scan.ranges[0] == 1.0 and twin_odom.pose.covariance[0] == 0.25
    assert copied(3) == 3 and copied("a") == "a"
