"""What the navigator decides when a step fails: Nav2's default tree
(``navigate_to_pose_w_replanning_and_recovery``) as a policy without ROS.

The navigator (``pppbot_nav.ros.navigator``) plans at ``replanning_frequency`` and hands
each path to the controller. When something fails it asks this policy what to do next:

* a failed plan (:meth:`NavigationPolicy.after_plan_failure`): a planner that is not ready
  yet (no pose or map, as in a just-started stack) is asked again every
  ``planner_not_ready_retry_s`` until ``server_timeout_s``; any other failure clears the
  global costmap and plans once more (the tree's ``ComputePathToPose`` recovery); then the
  plan fails;
* a failed follow (:meth:`NavigationPolicy.after_follow_failure`): the first clears the
  local costmap and replans (the tree's ``FollowPath`` recovery); the next fails;
* a failed plan-and-follow (:meth:`NavigationPolicy.after_failure`): the next recovery of
  the round robin (:class:`pppbot_nav.behaviors.RecoveryRoundRobin`), until
  ``number_of_retries`` recoveries have run; then the goal fails. As Jazzy's tree (its
  ``WouldAPlannerRecoveryHelp`` condition), no recovery runs for a planner error that no
  recovery can mend: a start or goal outside the map or in an obstacle, or no valid path once
  the global costmap has been cleared; the goal fails at once with the planner's error code.
"""
from __future__ import annotations

import enum
from dataclasses import dataclass, field

from pppbot_nav.behaviors import Recovery, RecoveryRoundRobin

#: ComputePathToPose's error codes (nav2_msgs) that no recovery can mend.
START_OUTSIDE_MAP, GOAL_OUTSIDE_MAP, START_OCCUPIED, GOAL_OCCUPIED, NO_VALID_PATH = 203, 204, 205, 206, 208
HOPELESS = frozenset({START_OUTSIDE_MAP, GOAL_OUTSIDE_MAP, START_OCCUPIED, GOAL_OCCUPIED, NO_VALID_PATH})


class PlanDecision(enum.Enum):
    RETRY_LATER = "retry later"  # the planner is not ready yet
    CLEAR_AND_RETRY = "clear the global costmap and plan again"
    FAIL = "fail"


class FollowDecision(enum.Enum):
    CLEAR_AND_REPLAN = "clear the local costmap and plan again"
    FAIL = "fail"


@dataclass(frozen=True)
class PolicySettings:
    """Nav2's default tree's numbers, with bt_navigator's parameter names where it has them."""

    number_of_retries: int = 6  # recoveries per goal
    server_timeout_s: float = 10.0  # how long a planner that is not ready is waited for
    planner_not_ready_retry_s: float = 0.5
    follow_failures_before_recovery: int = 2  # the first is met by clearing the local costmap


@dataclass
class NavigationPolicy:
    """One goal's failure handling: counts its recoveries and keeps the round robin's place."""

    settings: PolicySettings = field(default_factory=PolicySettings)
    recoveries: int = 0
    _robin: RecoveryRoundRobin = field(default_factory=RecoveryRoundRobin)

    def after_plan_failure(self, planner_not_ready: bool, waited_s: float, cleared: bool) -> PlanDecision:
        """A plan failed: ``planner_not_ready`` (TF_ERROR or UNKNOWN), ``waited_s`` since the
        first attempt of this plan, ``cleared``: the global costmap was cleared for it already."""
        if planner_not_ready and waited_s < self.settings.server_timeout_s:
            return PlanDecision.RETRY_LATER
        return PlanDecision.FAIL if cleared else PlanDecision.CLEAR_AND_RETRY

    def after_follow_failure(self, failures: int) -> FollowDecision:
        """The controller failed ``failures`` times in this plan-and-follow."""
        return FollowDecision.FAIL if failures >= self.settings.follow_failures_before_recovery \
            else FollowDecision.CLEAR_AND_REPLAN

    def after_failure(self, error_code: int = 0) -> Recovery | None:
        """Plan-and-follow failed with ``error_code``: the recovery to run next, or None when the
        retries are spent or no recovery can help (:data:`HOPELESS`)."""
        if self.recoveries >= self.settings.number_of_retries or error_code in HOPELESS:
            return None
        self.recoveries += 1
        return self._robin.next()
