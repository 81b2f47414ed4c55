"""send_goal: an action goal whose answer Fast DDS dropped is sent again."""
from __future__ import annotations

from typing import Any

import pytest
from rclpy.task import Future

from pppbot_common.errors import TimeoutExpired
from pppbot_common.ros.wait import send_goal


class Client:
    """An action client whose first ``lost`` answers never come."""

    _action_name = "navigate_to_pose"

    def __init__(self, lost: int) -> None:
        self.lost = lost
        self.sent: list[tuple[Any, Any]] = []

    def send_goal_async(self, goal: Any, feedback_callback: Any = None) -> Future:
        self.sent.append((goal, feedback_callback))
        future = Future()
        if len(self.sent) > self.lost:
            future.set_result(f"handle {len(self.sent)}")
        return future


def test_a_goal_whose_answer_was_lost_is_sent_again_with_its_feedback_callback():
    client = Client(lost=1)
    on_feedback = print
    assert send_goal(client, "goal", None, timeout_s=0.3, attempts=3, feedback_callback=on_feedback) == "handle 2"
    assert client.sent == [("goal", on_feedback), ("goal", on_feedback)]


def test_an_answer_at_once_is_sent_once():
    client = Client(lost=0)
    assert send_goal(client, "goal", None, timeout_s=0.3) == "handle 1" and len(client.sent) == 1


def test_no_answer_to_any_attempt_names_the_action():
    client = Client(lost=5)
    with pytest.raises(TimeoutExpired, match=r"gave up on a goal on action navigate_to_pose: no answer \(3 requests"):
        send_goal(client, "goal", None, timeout_s=0.3, attempts=3)
    assert len(client.sent) == 3
