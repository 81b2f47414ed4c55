"""The navigator's failure policy without ROS: Nav2's default tree's retries, clears and recoveries."""
from __future__ import annotations

import pytest

from pppbot_nav.behaviors import Recovery
from pppbot_nav.navigation_policy import FollowDecision, NavigationPolicy, PlanDecision, PolicySettings


def test_a_planner_that_is_not_ready_is_asked_again_until_the_server_timeout():
    policy = NavigationPolicy(PolicySettings(server_timeout_s=10.0))
    assert policy.after_plan_failure(planner_not_ready=True, waited_s=9.9, cleared=False) is PlanDecision.RETRY_LATER
    # past the timeout a not-ready planner is a failure like any other: clear, then fail
    assert policy.after_plan_failure(True, 10.0, cleared=False) is PlanDecision.CLEAR_AND_RETRY
    assert policy.after_plan_failure(True, 10.0, cleared=True) is PlanDecision.FAIL


def test_any_other_plan_failure_clears_the_global_costmap_once_then_fails():
    policy = NavigationPolicy()
    assert policy.after_plan_failure(planner_not_ready=False, waited_s=0.0, cleared=False) \
        is PlanDecision.CLEAR_AND_RETRY
    assert policy.after_plan_failure(False, 0.0, cleared=True) is PlanDecision.FAIL


def test_the_first_follow_failure_clears_the_local_costmap_and_replans_the_second_fails():
    policy = NavigationPolicy()
    assert policy.after_follow_failure(1) is FollowDecision.CLEAR_AND_REPLAN
    assert policy.after_follow_failure(2) is FollowDecision.FAIL
    lenient = NavigationPolicy(PolicySettings(follow_failures_before_recovery=3))
    assert lenient.after_follow_failure(2) is FollowDecision.CLEAR_AND_REPLAN


def test_recoveries_go_round_the_robin_until_the_retries_are_spent():
    policy = NavigationPolicy(PolicySettings(number_of_retries=6))
    recoveries = [policy.after_failure() for _ in range(7)]
    assert recoveries == [Recovery.CLEAR_COSTMAPS, Recovery.SPIN, Recovery.WAIT, Recovery.BACKUP,
                          Recovery.CLEAR_COSTMAPS, Recovery.SPIN, None]
    assert policy.recoveries == 6
    assert policy.after_failure() is None  # and stays spent


def test_no_retries_means_the_first_failure_ends_the_goal():
    policy = NavigationPolicy(PolicySettings(number_of_retries=0))
    assert policy.after_failure() is None and policy.recoveries == 0


def test_each_goal_has_its_own_count_and_place_in_the_robin():
    first, second = NavigationPolicy(), NavigationPolicy()
    first.after_failure()
    first.after_failure()
    assert second.after_failure() is Recovery.CLEAR_COSTMAPS and second.recoveries == 1


@pytest.mark.parametrize("code", [203, 204, 205, 206, 208])
def test_no_recovery_for_planner_errors_no_recovery_can_mend(code: int) -> None:
    """Jazzy's tree (WouldAPlannerRecoveryHelp): outside the map, occupied start or goal, no path once
    the global costmap was cleared: the goal fails at once."""
    policy = NavigationPolicy()
    assert policy.after_failure(code) is None and policy.recoveries == 0


@pytest.mark.parametrize("code", [0, 200, 207, 104, 105])
def test_recoveries_for_errors_a_recovery_may_mend(code: int) -> None:
    """Unknown, timeouts, a controller that failed or made no progress: the round robin runs."""
    assert NavigationPolicy().after_failure(code) is Recovery.CLEAR_COSTMAPS
