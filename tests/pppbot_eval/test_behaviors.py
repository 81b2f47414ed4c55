"""The evaluation's navigation behaviour against a navigator that answers, or never does."""
from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from rclpy.task import Future

from pppbot_common.maps import OccupancyGrid
from pppbot_eval.ros.behaviors import GoalLimits, NavigateGoals
from pppbot_eval.scenarios import Recording
from pppbot_lockstep.ros.port import FREE_RUNNING

FREE_ROOM = OccupancyGrid(np.zeros((100, 100), dtype=np.int8), 0.05, (-2.5, -2.5, 0.0))


class FakeNode:
    """What a behaviour acts through, with a navigator that answers each goal as ``answer`` says."""

    def __init__(self, answer: str) -> None:
        self.recording = Recording()
        self.sim_now_s: float | None = 0.0
        self.truth_pose: tuple[float, float, float] | None = (0.0, 0.0, 0.0)
        self.amcl_poses = 1  # the localizer has published its first pose
        self.localizes = True  # navigating on a map (False: without one, in odom)
        self.driving = False
        self.answer = answer
        self.sent: list[tuple[float, float, float]] = []
        self.port = FREE_RUNNING  # free running: no lockstep here

    def send_goal(self, x: float, y: float, yaw: float) -> Future:
        self.sent.append((x, y, yaw))
        future = Future()
        if self.answer == "rejects":
            future.set_result(Handle(accepted=False))
        return future  # "never": the request is lost

    def recoveries(self) -> int:
        return 0

    def command(self, linear_mps: float, angular_radps: float) -> None: ...
    def send_initial_pose(self, x: float, y: float, yaw: float, covariance: list[float]) -> None: ...
    def request_global_localization(self) -> Any: ...


class Handle:
    def __init__(self, accepted: bool) -> None:
        self.accepted = accepted


def run(node: FakeNode, behavior: NavigateGoals, until_s: float, tick_s: float = 0.05) -> None:
    while behavior.outcome is None and node.sim_now_s is not None and node.sim_now_s < until_s:
        behavior.tick(node)
        node.sim_now_s += tick_s


def test_a_goal_the_navigator_never_answers_is_recorded_unanswered_and_the_run_goes_on() -> None:
    node = FakeNode("never")
    behavior = NavigateGoals([(1.0, 0.0, 0.0), (-1.0, 0.0, 0.0)], FREE_ROOM, (0.0, 0.0, 0.0), max_speed_mps=0.5,
                             limits=GoalLimits(base_s=10.0, per_shortest=4.0))
    run(node, behavior, until_s=200.0)
    assert behavior.outcome == ""  # ended, instead of waiting for ever
    assert [g.status for g in node.recording.goals] == ["unanswered", "unanswered"]
    assert len(node.sent) == 2
    first = node.recording.goals[0]
    assert "did not answer" in first.error_msg
    # Given up once past the goal's limit: 10 s + 4 × (1 m / 0.5 m/s), not before.
    assert 18.0 <= first.end_s - first.start_s <= 18.2


def test_a_rejected_goal_is_recorded_at_once() -> None:
    node = FakeNode("rejects")
    behavior = NavigateGoals([(1.0, 0.0, 0.0)], FREE_ROOM, (0.0, 0.0, 0.0), max_speed_mps=0.5)
    run(node, behavior, until_s=5.0)
    assert behavior.outcome == "" and [g.status for g in node.recording.goals] == ["rejected"]
    assert node.recording.goals[0].end_s < 0.2


def test_the_first_goal_waits_for_the_localizers_first_pose() -> None:
    """As BasicNavigator's waitUntilNav2Active: no goal before AMCL's first pose (and its map -> odom),
    which the navigator would abort ("no transform from 'base_link' to 'map'")."""
    node = FakeNode("rejects")
    node.amcl_poses = 0
    behavior = NavigateGoals([(1.0, 0.0, 0.0)], FREE_ROOM, (0.0, 0.0, 0.0), max_speed_mps=0.5)
    run(node, behavior, until_s=2.0)
    assert node.sent == [] and behavior.outcome is None
    node.amcl_poses = 1
    run(node, behavior, until_s=4.0)
    assert len(node.sent) == 1 and [g.status for g in node.recording.goals] == ["rejected"]
    # Without a map nothing localizes: the goal (in odom, which starts at the spawn pose) goes at once.
    free = FakeNode("rejects")
    free.amcl_poses, free.localizes = 0, False
    spawn = (1.0, 2.0, math.pi / 2)
    run(free, NavigateGoals([(1.0, 3.0, math.pi / 2)], FREE_ROOM, spawn, max_speed_mps=0.5), until_s=0.5)
    assert len(free.sent) == 1 and free.sent[0] == pytest.approx((1.0, 0.0, 0.0))
