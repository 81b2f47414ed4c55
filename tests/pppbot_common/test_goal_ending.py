"""The one cancel and preemption check of pppbot's action servers (navigator, controller_server)."""
from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import pytest

from pppbot_common.ros.goals import GoalEnd, Stopped, check_running, stopped_end


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
