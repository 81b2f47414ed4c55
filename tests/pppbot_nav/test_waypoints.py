"""Waypoint following's decisions (Nav2's waypoint_follower loop) and the wait_at_waypoint task, without ROS."""
from __future__ import annotations

import pytest

from pppbot_nav.errors import WaypointError
from pppbot_nav.waypoints import (
    WAIT_AT_WAYPOINT,
    Decision,
    MissedWaypoint,
    MissReason,
    Next,
    TaskStatus,
    WaitAtWaypoint,
    WaypointRun,
    load_task_executor,
)


def visit(run: WaypointRun, outcomes: dict[int, bool] | None = None) -> tuple[list[int], Decision]:
    """Go through ``run`` (every pose reached with its task done, unless ``outcomes`` says a pose's
    navigation fails): the poses navigated to, in order, and the last decision."""
    outcomes = outcomes or {}
    visited = [run.index]
    while True:
        ok = outcomes.get(run.index, True)
        decision = run.reached(task_succeeded=True) if ok else run.missed(navigation_error_code=104)
        if decision.next is not Next.NAVIGATE:
            return visited, decision
        visited.append(decision.index)


def test_the_poses_are_visited_in_order_and_the_run_succeeds():
    visited, end = visit(WaypointRun(3))
    assert visited == [0, 1, 2]
    assert end == Decision(Next.SUCCEED, 2)


def test_goal_index_starts_part_way_and_each_loop_starts_again_at_the_first_pose():
    visited, end = visit(WaypointRun(3, goal_index=1, number_of_loops=2))
    assert visited == [1, 2, 0, 1, 2, 0, 1, 2]
    assert end.next is Next.SUCCEED


def test_a_missed_waypoint_stops_the_run_with_stop_on_failure():
    run = WaypointRun(3, stop_on_failure=True)
    visited, end = visit(run, {1: False})
    assert visited == [0, 1]
    assert end == Decision(Next.STOP_ON_MISSED_WAYPOINT, 1)
    assert run.missed_waypoints == [MissedWaypoint(1, MissReason.NAVIGATION, 104)]


def test_without_stop_on_failure_a_missed_waypoint_is_recorded_and_the_run_goes_on():
    run = WaypointRun(3, stop_on_failure=False, number_of_loops=1)
    visited, end = visit(run, {1: False})
    assert visited == [0, 1, 2, 0, 1, 2]
    assert end.next is Next.SUCCEED
    assert [m.index for m in run.missed_waypoints] == [1, 1]  # once per loop


def test_a_failed_task_is_a_missed_waypoint_and_stops_the_run_with_stop_on_failure():
    run = WaypointRun(2, stop_on_failure=True)
    assert run.reached(task_succeeded=False) == Decision(Next.STOP_ON_TASK_FAILURE, 0)
    assert run.missed_waypoints == [MissedWaypoint(0, MissReason.TASK)]
    going_on = WaypointRun(2, stop_on_failure=False)
    assert going_on.reached(task_succeeded=False) == Decision(Next.NAVIGATE, 1)
    assert going_on.missed_waypoints == [MissedWaypoint(0, MissReason.TASK)]


@pytest.mark.parametrize(("count", "goal_index", "loops", "message"), [
    (0, 0, 0, "no waypoints"),
    (3, 3, 0, "goal_index 3 is out of range: the goal has 3 poses"),
    (3, -1, 0, "goal_index -1 is out of range"),
    (3, 0, -1, "number_of_loops -1"),
])
def test_a_request_that_cannot_be_followed_is_refused_naming_the_value(count, goal_index, loops, message):
    with pytest.raises(WaypointError, match=message):
        WaypointRun(count, goal_index=goal_index, number_of_loops=loops)


def test_wait_at_waypoint_pauses_its_duration_from_the_arrival():
    task = WaitAtWaypoint(enabled=True, waypoint_pause_duration_ms=1500)
    task.start(0, now_s=10.0)
    assert task.step(10.0) is TaskStatus.RUNNING
    assert task.step(11.49) is TaskStatus.RUNNING
    assert task.step(11.5) is TaskStatus.SUCCEEDED
    task.start(1, now_s=20.0)  # the next waypoint pauses again
    assert task.step(20.1) is TaskStatus.RUNNING


def test_wait_at_waypoint_disabled_is_done_at_once():
    task = WaitAtWaypoint(enabled=False, waypoint_pause_duration_ms=1500)
    task.start(0, now_s=10.0)
    assert task.step(10.0) is TaskStatus.SUCCEEDED


def test_task_executors_are_loaded_by_their_nav2_plugin_type():
    task = load_task_executor(WAIT_AT_WAYPOINT, enabled=True, waypoint_pause_duration_ms=0)
    assert isinstance(task, WaitAtWaypoint)
    with pytest.raises(WaypointError, match="'nav2_waypoint_follower::PhotoAtWaypoint'.*pppbot has "
                                            "'nav2_waypoint_follower::WaitAtWaypoint'"):
        load_task_executor("nav2_waypoint_follower::PhotoAtWaypoint")
    with pytest.raises(WaypointError, match="waypoint_pause_duration -5 ms"):
        load_task_executor(WAIT_AT_WAYPOINT, waypoint_pause_duration_ms=-5)
