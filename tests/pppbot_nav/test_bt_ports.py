"""The navigator's rclpy ports: a goal's answer is read from its future, whether or not rclpy has
run the future's done callback yet (it runs them later, on the executor), so a tick in between
never takes an accepted goal for a refused one."""
from __future__ import annotations

from types import SimpleNamespace
from typing import Any

from nav2_msgs.action import FollowPath
from rclpy.action.client import ClientGoalHandle
from rclpy.task import Future
from unique_identifier_msgs.msg import UUID

from pppbot_nav.ros.bt_ports import PROMPT_ACTIONS, RosGoalCall


def goal_call(sent: Future, prompt: bool = True) -> RosGoalCall:
    """A call whose done callbacks never run (as between a future's end and the executor's next turn)."""
    ports = SimpleNamespace(waited=lambda future, then=None: None, cancels=SimpleNamespace(cancel=lambda *a: None))
    client = SimpleNamespace(send_goal_async=lambda goal, feedback_callback=None: sent)
    port: Any = SimpleNamespace(client=client, live=[], prompt=prompt, ports=ports)
    return RosGoalCall(port, FollowPath.Goal(), None)


def handle(accepted: bool) -> ClientGoalHandle:
    results: Future = Future()
    client = SimpleNamespace(_get_result_async=lambda goal_handle: results)
    return ClientGoalHandle(client, UUID(), FollowPath.Impl.SendGoalService.Response(accepted=accepted))


def test_an_accepted_goal_is_seen_accepted_before_its_callback_ran():
    assert FollowPath not in PROMPT_ACTIONS
    sent: Future = Future()
    call = goal_call(sent)
    assert call.accepted() is None and not call.ended()
    sent.set_result(handle(True))
    assert call.accepted() is True
    assert not call.ended() and call.outcome() is None  # running: no result yet


def test_a_refused_or_failed_send_is_refused_and_ended():
    sent: Future = Future()
    call = goal_call(sent)
    sent.set_result(handle(False))
    assert call.accepted() is False and call.ended()
    broken: Future = Future()
    call = goal_call(broken)
    broken.set_exception(RuntimeError("the server went away"))
    assert call.accepted() is False and call.ended()
