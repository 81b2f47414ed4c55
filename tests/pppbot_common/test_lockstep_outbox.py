"""A lockstep participant's outbox: sends held until the next step, counted at once, in order."""
from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import pytest
from std_msgs.msg import String
from std_srvs.srv import Trigger

from pppbot_common.ros.lockstep_counting import COUNTERS, OUTBOX, HeldFuture, install_counting
from pppbot_common.ros.wait import wait_until

pytestmark = pytest.mark.ros
TOPIC = "/outbox_test"


@pytest.fixture
def holding() -> Iterator[None]:
    install_counting()
    OUTBOX.holding = True
    try:
        yield
    finally:
        OUTBOX.send_all()  # as a participant leaving: nothing held is lost


def spin_for(node: Any, seconds: float) -> None:
    """Serve callbacks for ``seconds`` (a message sent meanwhile would arrive)."""
    end = time.monotonic() + seconds
    wait_until(lambda: time.monotonic() >= end, seconds + 1.0, "time to pass", node=node)


def answer_and_step() -> None:
    """What a participant does: its answer seals what it holds; the next step sends it."""
    with OUTBOX.lock:
        OUTBOX.seal()
    OUTBOX.send_sealed()


def test_held_messages_are_counted_at_once_and_go_out_in_order_with_the_next_step(ros_node: Any, holding: None):
    got: list[str] = []
    pub = ros_node.create_publisher(String, TOPIC, 10)
    ros_node.create_subscription(String, TOPIC, lambda m: got.append(m.data), 10)
    wait_until(lambda: pub.get_subscription_count() > 0, 10, "the subscription matched", node=ros_node)
    published, sends = COUNTERS.published.get(TOPIC, 0), COUNTERS.sends
    msg = String(data="a")
    pub.publish(msg)
    msg.data = "b"  # the sender reuses its message: what was held is what it published
    pub.publish(msg)
    # Counted when held: the answer reports them, the next step's totals include them.
    assert COUNTERS.published[TOPIC] == published + 2 and COUNTERS.sends == sends + 2
    with OUTBOX.lock:
        OUTBOX.seal()  # the answer
    pub.publish(String(data="c"))  # after the answer: it waits for the step after next
    spin_for(ros_node, 0.3)
    assert got == []
    OUTBOX.send_sealed()  # the next step
    wait_until(lambda: len(got) >= 2, 10, "the sealed messages", node=ros_node)
    spin_for(ros_node, 0.3)
    assert got == ["a", "b"]
    answer_and_step()
    wait_until(lambda: len(got) >= 3, 10, "the message held after the answer", node=ros_node)
    assert got == ["a", "b", "c"]


def test_a_held_request_gets_a_future_that_completes_with_the_reply(ros_node: Any, holding: None):
    calls: list[int] = []

    def serve(request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        calls.append(1)
        response.success, response.message = True, f"call {len(calls)}"
        return response

    ros_node.create_service(Trigger, "/outbox_test_service", serve)
    client = ros_node.create_client(Trigger, "/outbox_test_service")
    assert client.wait_for_service(timeout_sec=10)
    sent_at: list[bool] = []
    future = client.call_async(Trigger.Request())
    assert isinstance(future, HeldFuture) and not future.sent
    future.when_sent(lambda: sent_at.append(True))  # where a participant takes its hold
    spin_for(ros_node, 0.3)
    assert calls == [] and not future.done() and sent_at == []
    answer_and_step()
    assert future.sent and sent_at == [True]
    wait_until(future.done, 10, "the reply", node=ros_node)
    assert calls == [1] and future.result().success and future.result().message == "call 1"


def test_without_holding_sends_go_out_at_once(ros_node: Any):
    install_counting()
    assert not OUTBOX.holding
    got: list[str] = []
    pub = ros_node.create_publisher(String, TOPIC, 10)
    ros_node.create_subscription(String, TOPIC, lambda m: got.append(m.data), 10)
    wait_until(lambda: pub.get_subscription_count() > 0, 10, "the subscription matched", node=ros_node)
    published = COUNTERS.published.get(TOPIC, 0)
    pub.publish(String(data="now"))
    assert COUNTERS.published[TOPIC] == published + 1
    wait_until(lambda: got == ["now"], 10, "the message", node=ros_node)
