"""The one cancel and preemption check of pppbot's action servers (navigator, controller_server), and
what a flow stopped between a goal's send and its answer leaves running."""
from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import pytest
from action_msgs.msg import GoalStatus
from rclpy.action.client import ClientGoalHandle
from rclpy.task import Future

from pppbot_lockstep.ros.goals import Cancels, Flow, GoalEnd, Stopped, check_running, stopped_end


def handle(cancel: bool = False) -> Any:  # a ServerGoalHandle as far as these read it
    return SimpleNamespace(is_cancel_requested=cancel)


def test_a_running_goal_passes_a_canceled_or_replaced_one_stops_with_why():
    goal = handle()
    check_running(goal, goal)  # the server's current goal, not canceled: goes on
    with pytest.raises(Stopped, match="^canceled$"):
        check_running(handle(cancel=True), None)
    canceled = handle(cancel=True)
    with pytest.raises(Stopped, match="^canceled$"):  # a cancel wins over a preemption
        check_running(canceled, handle())
    with pytest.raises(Stopped, match="^preempted by a new goal$"):
        check_running(goal, handle())
    with pytest.raises(Stopped, match="^preempted by a new path$"):
        check_running(goal, None, "a new path")


def test_a_goal_that_did_not_succeed_is_canceled_only_when_its_client_asked():
    assert stopped_end(handle(cancel=True)) is GoalEnd.CANCELED
    assert stopped_end(handle()) is GoalEnd.ABORTED


class Client:
    """An action client as a ClientGoalHandle calls it: the cancels it was asked for."""

    def __init__(self) -> None:
        self.canceled: list[Any] = []

    def _cancel_goal_async(self, goal: Any) -> Future:
        self.canceled.append(goal)
        return Future()


@pytest.mark.parametrize("ticked", [True, False], ids=["stopped at a tick", "stopped as the answer came"])
@pytest.mark.parametrize("accepted", [True, False])
def test_a_goal_sent_by_a_flow_stopped_before_its_answer_is_canceled_once_accepted(accepted: bool, ticked: bool):
    stop: list[str] = []
    ends: list[Any] = []

    def check() -> None:
        if stop:
            raise Stopped(stop[0])

    def steps() -> Any:
        yield sent  # the send_goal_async future: the flow waits for the server's answer
        raise AssertionError("the flow never resumes with the answer")
    sent = Future()
    flow: Flow[None] = Flow(steps(), lambda: 0.0, lambda value, error: ends.append(error), check=check)
    flow.start()
    stop.append("canceled")  # the goal the flow runs for is canceled before the answer came
    if ticked:
        flow.tick()  # the flow sees it before the answer
        assert flow.ended and isinstance(ends[0], Stopped)
    client = Client()
    handle = ClientGoalHandle(client, SimpleNamespace(uuid=bytes(16)), SimpleNamespace(accepted=accepted, stamp=None))
    sent.set_result(handle)  # else the flow sees the cancel as it resumes with the answer
    assert flow.ended and isinstance(ends[0], Stopped)
    assert client.canceled == ([handle] if accepted else [])


def test_a_canceled_goal_is_canceled_again_until_it_ends_and_no_more_than_attempts_times():
    now = [0.0]
    cancels = Cancels(lambda: now[0], again_s=1.0, attempts=3)
    client = Client()
    lost = ClientGoalHandle(client, SimpleNamespace(uuid=bytes(16)), SimpleNamespace(accepted=True, stamp=None))
    ends = ClientGoalHandle(client, SimpleNamespace(uuid=bytes([1] * 16)), SimpleNamespace(accepted=True, stamp=None))
    result = Future()  # ends's result
    cancels.cancel(lost)  # its cancels are lost: the goal runs on
    cancels.cancel(ends, result)
    assert client.canceled == [lost, ends]
    now[0] = 0.9
    assert cancels.tick() and client.canceled == [lost, ends]  # not due yet
    now[0] = 1.0
    assert cancels.tick() and client.canceled == [lost, ends, lost, ends]
    result.set_result(SimpleNamespace(status=GoalStatus.STATUS_CANCELED))  # ends ended
    now[0] = 2.0
    assert cancels.tick() and client.canceled[4:] == [lost]  # the third and last ask
    now[0] = 3.0
    assert not cancels.tick() and len(client.canceled) == 5  # given up on: the timer may stop


def test_a_canceled_goal_whose_status_says_it_ended_is_not_asked_again():
    now = [0.0]
    cancels = Cancels(lambda: now[0])
    client = Client()
    goal = ClientGoalHandle(client, SimpleNamespace(uuid=bytes(16)), SimpleNamespace(accepted=True, stamp=None))
    cancels.cancel(goal)
    goal._status = GoalStatus.STATUS_ABORTED  # as the action's status topic sets it
    now[0] = 5.0
    assert not cancels.tick() and client.canceled == [goal]
