"""DWB's own critics as plugins (``pppbot_nav.controller.dwb_critic_plugins``): found by Nav2's type
names, made from their parameters under their name in ``critics``, refusing bad values with the
critic named, and reading the controller's own settings each period."""
from __future__ import annotations

import dataclasses
import math

import pytest
from test_dwb import DT, PPP, free_costmap, ppp, straight

from pppbot_nav.controller.dwb_critic_plugins import critic_type, make_critics
from pppbot_nav.controller.dwb_critics import BaseObstacle, GoalDist, ObstacleFootprint, PathAlign, RotateToGoal
from pppbot_nav.errors import ControllerError


def test_dwbs_own_critics_are_plugins_made_from_their_parameters_under_their_name():
    made = make_critics(("BaseObstacle", "dwb_critics::PathAlignCritic", "GoalDistCritic"),
                        {"BaseObstacle": {"scale": 0.02, "sum_scores": True},
                         "dwb_critics::PathAlignCritic": {"forward_point_distance": 0.1}})
    base, align, goal = made.values()
    assert isinstance(base, BaseObstacle) and (base.scale, base.sum_scores) == (0.02, True)
    assert isinstance(align, PathAlign) and align.name == "dwb_critics::PathAlignCritic"
    assert isinstance(goal, GoalDist) and goal.scale == 1.0  # Nav2's defaults
    assert critic_type("Twirling") == "dwb_critics::TwirlingCritic"


@pytest.mark.parametrize(("values", "parameter"), [
    ({"PathDist": {"aggregation_type": "mean"}}, "PathDist.aggregation_type"),
    ({"BaseObstacle": {"scale": -0.02}}, "BaseObstacle.scale"),
    ({"RotateToGoal": {"slowing_factor": math.inf}}, "RotateToGoal.slowing_factor"),
    ({"BaseObstacle": {"sum_scores": 1}}, "BaseObstacle.sum_scores"),
    ({"BaseObstacle": {"scales": 1.0}}, "BaseObstacle.scales"),
])
def test_a_bad_critic_parameter_is_named_with_its_critic(values, parameter):
    with pytest.raises(ControllerError) as err:
        make_critics(("BaseObstacle", "PathDist", "RotateToGoal"), values)
    assert err.value.parameter == parameter and f"'{parameter}'" in str(err.value)


def test_the_footprint_and_goal_tolerance_critics_read_are_the_controllers_each_period():
    planner = ppp(dataclasses.replace(PPP, critics=("ObstacleFootprint", "RotateToGoal"), xy_goal_tolerance=0.5))
    footprint, rotate = planner.critics
    planner.compute((0.7, 0.0, 0.0), (0.0, 0.0), straight(1.0, yaw=1.0), free_costmap(), DT)
    assert isinstance(rotate, RotateToGoal) and rotate.in_window  # 0.3 m from the goal: the controller's 0.5 m
    assert isinstance(footprint, ObstacleFootprint) and footprint.footprint[0] == pytest.approx([0.31, 0.0])
    planner.set_footprint(0.2, 0.0)
    planner.compute((0.7, 0.0, 0.0), (0.0, 0.0), straight(1.0, yaw=1.0), free_costmap(), DT)
    assert footprint.footprint[0] == pytest.approx([0.2, 0.0]) and planner.critics == [footprint, rotate]
