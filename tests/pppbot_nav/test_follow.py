"""The controller server's per-period follow policy without ROS (pppbot_nav.controller.follow)."""
from __future__ import annotations

import numpy as np

from pppbot_nav.controller.checkers import SimpleGoalChecker, SimpleProgressChecker
from pppbot_nav.controller.follow import MIN_TF_TOLERANCE_S, FollowEnd, Follower
from pppbot_nav.controller.pure_pursuit import PurePursuit, PurePursuitSettings
from pppbot_nav.costmap.costs import LETHAL_OBSTACLE
from pppbot_nav.costmap.grid import Costmap

PERIOD = 0.05
PATH = np.c_[np.arange(0.0, 3.0001, 0.05), np.zeros(61), np.zeros(61)]  # along +x, goal yaw 0
GOAL = (3.0, 0.0, 0.0)


def follower(failure_tolerance_s: float = 0.3) -> Follower:
    controller = PurePursuit(PurePursuitSettings())
    controller.set_path(PATH)
    return Follower(controller, SimpleGoalChecker(), SimpleProgressChecker(0.5, 10.0), failure_tolerance_s)


def costmap(wall_at_x: float | None = None) -> Costmap:
    grid = Costmap(np.zeros((100, 100), np.uint8), 0.05, (-2.5, -2.5), "odom")
    if wall_at_x is not None:
        _, col = grid.cell_of(wall_at_x, 0.0)
        grid.costs[:, int(col)] = LETHAL_OBSTACLE
    return grid


def test_on_the_path_it_commands_the_controllers_velocity():
    step = follower().step(0.0, (0.0, 0.0, 0.0), GOAL, PATH, (0.0, 0.0), costmap(), PERIOD)
    assert step.end is None and step.command is not None and step.command.linear_mps > 0.0


def test_within_the_goal_tolerance_the_goal_succeeds():
    step = follower().step(0.0, (2.9, 0.05, 0.1), GOAL, PATH, (0.0, 0.0), costmap(), PERIOD)
    assert step.end is FollowEnd.SUCCEEDED and step.command is None


def test_a_robot_that_does_not_move_fails_to_make_progress_after_the_allowance():
    f = follower()
    for t in np.arange(0.0, 10.0, 1.0):
        assert f.step(float(t), (0.0, 0.0, 0.0), GOAL, PATH, (0.0, 0.0), costmap(), PERIOD).end is None
    step = f.step(10.5, (0.1, 0.0, 0.0), GOAL, PATH, (0.0, 0.0), costmap(), PERIOD)
    assert step.end is FollowEnd.FAILED_TO_MAKE_PROGRESS
    assert step.message == "the robot moved less than 0.5 m in 10.0 s"


def test_without_a_transform_it_stops_then_fails_after_at_least_a_second():
    f = follower(failure_tolerance_s=0.3)
    first = f.step(5.0, None, GOAL, PATH, (0.0, 0.0), costmap(), PERIOD, no_pose_reason="no odom")
    assert first.end is None and first.command is None and "no odom" in first.problem
    # the failure tolerance (0.3 s) is too short for transforms: they get a second
    assert f.step(5.0 + MIN_TF_TOLERANCE_S - 0.1, None, GOAL, PATH, (0.0, 0.0), costmap(), PERIOD).end is None
    late = f.step(5.0 + MIN_TF_TOLERANCE_S + 0.1, None, GOAL, PATH, (0.0, 0.0), costmap(), PERIOD,
                  no_pose_reason="no odom")
    assert late.end is FollowEnd.TF_ERROR and late.message == "no transform for the path: no odom"


def test_a_collision_ahead_stops_the_robot_and_fails_after_the_failure_tolerance():
    f = follower(failure_tolerance_s=0.3)
    wall = costmap(wall_at_x=0.32)
    first = f.step(0.0, (0.0, 0.0, 0.0), GOAL, PATH, (0.0, 0.0), wall, PERIOD)
    assert first.command is None and first.end is None and first.problem.startswith("no command this period:")
    assert f.step(0.25, (0.0, 0.0, 0.0), GOAL, PATH, (0.0, 0.0), wall, PERIOD).end is None
    last = f.step(0.35, (0.0, 0.0, 0.0), GOAL, PATH, (0.0, 0.0), wall, PERIOD)
    assert last.end is FollowEnd.NO_VALID_CONTROL and "lethal" in last.message


def test_a_good_command_resets_the_failure_clock():
    f = follower(failure_tolerance_s=0.3)
    wall = costmap(wall_at_x=0.32)
    assert f.step(0.0, (0.0, 0.0, 0.0), GOAL, PATH, (0.0, 0.0), wall, PERIOD).command is None
    assert f.step(0.25, (0.0, 0.0, 0.0), GOAL, PATH, (0.0, 0.0), costmap(), PERIOD).command is not None
    # failing again starts a new clock: 0.3 s from now, not from the first failure
    assert f.step(0.4, (0.0, 0.0, 0.0), GOAL, PATH, (0.0, 0.0), wall, PERIOD).end is None
    assert f.step(0.65, (0.0, 0.0, 0.0), GOAL, PATH, (0.0, 0.0), wall, PERIOD).end is None
    assert f.step(0.75, (0.0, 0.0, 0.0), GOAL, PATH, (0.0, 0.0), wall, PERIOD).end is FollowEnd.NO_VALID_CONTROL
