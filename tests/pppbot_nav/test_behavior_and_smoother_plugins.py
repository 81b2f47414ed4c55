"""pppbot's behaviour and smoother plugins without a node: found by Nav2's type names in their
entry-point groups, Nav2's parameters and defaults, and what their runs and smoothers do."""
from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pytest
from builtin_interfaces.msg import Duration
from nav2_msgs.action import AssistedTeleop, BackUp, DriveOnHeading, Spin, Wait

from pppbot_common.maps import OccupancyGrid
from pppbot_common.params import ParameterError, from_values
from pppbot_nav.behaviors import Outcome
from pppbot_nav.planner.simple_smoother import (
    SimpleSmootherParameters,
    SimpleSmootherSettings,
    blocked_cells,
    smooth_path,
)
from pppbot_nav.planner.smoother_interface import Smoother, SmootherPlugin
from pppbot_nav.plugins import PluginGroup
from pppbot_nav.ros.behavior_interface import BehaviorPlugin, BehaviorRun, BehaviorSettings, InvalidInput
from pppbot_nav.ros.behavior_plugins import (
    DEFAULT_BEHAVIOR_TYPES,
    AssistedTeleopPlugin,
    BackUpPlugin,
    CoreRun,
    DriveOnHeadingPlugin,
    SpinPlugin,
    WaitPlugin,
    back_up_core,
    drive_on_heading_core,
    spin_core,
    wait_core,
)

SETTINGS = BehaviorSettings(cycle_frequency_hz=10.0, simulate_ahead_time_s=2.0, max_rotational_vel=1.0,
                            min_rotational_vel=0.4, rotational_acc_lim=3.2)

# What the servers ask of an entry point, checked by mypy on pppbot's own.
_PLUGINS: list[BehaviorPlugin] = [SpinPlugin(), BackUpPlugin(), DriveOnHeadingPlugin(), WaitPlugin(),
                                  AssistedTeleopPlugin()]
_SMOOTHER: SmootherPlugin = SimpleSmootherParameters()
_MADE: Smoother = SimpleSmootherParameters().make()


@pytest.mark.parametrize("type_name, cls, action", [
    ("nav2_behaviors::Spin", SpinPlugin, Spin),
    ("nav2_behaviors/BackUp", BackUpPlugin, BackUp),
    ("nav2_behaviors::DriveOnHeading", DriveOnHeadingPlugin, DriveOnHeading),
    ("nav2_behaviors/Wait", WaitPlugin, Wait),
    ("nav2_behaviors::AssistedTeleop", AssistedTeleopPlugin, AssistedTeleop),
])
def test_nav2s_behaviour_types_are_entry_points_serving_their_action(type_name: str, cls: Any, action: Any) -> None:
    found = PluginGroup("behavior")[type_name]
    assert found is cls and found.ACTION is action


def test_nav2s_default_behaviour_ids_have_its_types() -> None:
    group = PluginGroup("behavior")
    assert {name: group[t].ACTION for name, t in DEFAULT_BEHAVIOR_TYPES.items()} == {
        "spin": Spin, "backup": BackUp, "drive_on_heading": DriveOnHeading, "assisted_teleop": AssistedTeleop,
        "wait": Wait}


def test_the_simple_smoother_is_an_entry_point_with_nav2s_parameters() -> None:
    assert PluginGroup("smoother")["nav2_smoother/SimpleSmoother"] is SimpleSmootherParameters
    defaults = {f.name: f.default for f in dataclasses.fields(SimpleSmootherParameters)}
    assert defaults == {"tolerance": 1e-10, "max_its": 1000, "w_data": 0.2, "w_smooth": 0.3, "do_refinement": True,
                        "refinement_num": 2}
    # A bad value names the parameter itself: the server puts the smoother's name in front.
    with pytest.raises(ParameterError, match=r"^parameter 'w_smooth' = 0.9"):
        from_values(SimpleSmootherParameters, {"w_smooth": 0.9})
    with pytest.raises(ParameterError, match=r"^parameter 'max_its' = 0"):
        from_values(SimpleSmootherParameters, {"max_its": 0})


def test_the_simple_smoother_keeps_off_the_costmaps_inscribed_cells() -> None:
    stairs = np.vstack([[0.0, 0.0], np.cumsum(np.array([[0.05, 0.0], [0.0, 0.05]])[np.arange(40) % 2], axis=0)])
    yaws = np.zeros(len(stairs))
    grid = OccupancyGrid(np.zeros((80, 80), dtype=np.int8), 0.05, (-1.0, -1.0, 0.0), "map")
    params = SimpleSmootherParameters(w_data=0.1, w_smooth=0.4)
    free = params.make().smooth(stairs, yaws, grid, clock_s=lambda: 0.0, max_duration_s=1.0)
    expected = smooth_path(stairs, yaws, SimpleSmootherSettings(w_data=0.1, w_smooth=0.4), clock_s=lambda: 0.0,
                           max_duration_s=1.0)
    np.testing.assert_allclose(free.points_xy, expected.points_xy)
    assert free.completed
    # An inscribed cell where the smoothed path would go: the smoothing stops short of it.
    row, col = grid.cell_of(free.points_xy[20:21, 0], free.points_xy[20:21, 1])
    grid.data[row, col] = 99
    blocked = params.make().smooth(stairs, yaws, grid, clock_s=lambda: 0.0, max_duration_s=1.0)
    assert not blocked.completed
    assert not blocked_cells(grid)(blocked.points_xy).any()


def drive_goal(action: Any, x: float, speed: float, y: float = 0.0) -> Any:
    goal = action.Goal(speed=speed)
    goal.target.x, goal.target.y = x, y
    return goal


def test_backup_and_drive_on_heading_refuse_what_nav2_refuses() -> None:
    with pytest.raises(InvalidInput, match=r"reverse drives along the heading only: .*\(got 0.1, 0\)"):
        back_up_core(drive_goal(BackUp, 0.3, 0.1, y=0.1), 10.0, "reverse", SETTINGS)
    with pytest.raises(InvalidInput, match="signs"):
        drive_on_heading_core(drive_goal(DriveOnHeading, -0.3, 0.2), 10.0, "drive_on_heading", SETTINGS)
    with pytest.raises(InvalidInput, match="speed is 0"):
        back_up_core(drive_goal(BackUp, 0.3, 0.0), 10.0, "backup", SETTINGS)
    backwards = back_up_core(drive_goal(BackUp, 0.3, 0.1), 10.0, "backup", SETTINGS)  # backwards whatever the signs
    assert (backwards.distance_m, backwards.speed) == (-0.3, -0.1)


def test_a_spin_run_turns_with_the_servers_limits_and_reports_its_progress() -> None:
    settings = dataclasses.replace(SETTINGS, max_rotational_vel=0.6)
    run: BehaviorRun = CoreRun(spin_core(Spin.Goal(target_yaw=-1.0), 10.0, "spin", settings), settings)
    run.start((0.0, 0.0, 0.0), 0.0)
    assert run.step((0.0, 0.0, 0.0), 0.0) == (0.0, -0.6)  # far from the target: the top speed
    command = run.step((0.0, 0.0, -0.5), 1.0)
    assert command == (0.0, -0.6)
    feedback = Spin.Feedback()
    run.feedback(feedback, 1.0)
    assert feedback.angular_distance_traveled == pytest.approx(0.5)
    assert run.step((0.0, 0.0, -1.0), 2.0) is Outcome.DONE
    timed_out = CoreRun(spin_core(Spin.Goal(target_yaw=1.0), 0.5, "spin", settings), settings)
    timed_out.start((0.0, 0.0, 0.0), 0.0)
    assert timed_out.step((0.0, 0.0, 0.0), 0.6) is Outcome.TIMEOUT


def test_a_drive_run_checks_collisions_ahead_and_a_wait_run_none() -> None:
    data = np.zeros((80, 80), dtype=np.int8)
    data[:, 54:] = 99  # inscribed from x = 0.7 m
    grid = OccupancyGrid(data, 0.05, (-2.0, -2.0, 0.0), "odom")
    drive = CoreRun(drive_on_heading_core(drive_goal(DriveOnHeading, 2.0, 0.25), 10.0, "drive_on_heading",
                                          SETTINGS), SETTINGS)
    drive.start((0.0, 0.0, 0.0), 0.0)
    assert drive.collision_ahead(grid, (0.0, 0.0, 0.0), (0.25, 0.0)) is None  # 0.5 m in 2 s: short of it
    assert "collision ahead" in (drive.collision_ahead(grid, (0.3, 0.0, 0.0), (0.25, 0.0)) or "")
    assert drive.collision_ahead(grid, (0.3, 0.0, math.pi), (0.25, 0.0)) is None  # facing away
    wait = CoreRun(wait_core(Wait.Goal(time=Duration(sec=1)), 10.0, "wait", SETTINGS), SETTINGS)
    assert wait.collision_ahead(grid, (0.75, 0.0, 0.0), (0.0, 0.0)) is None


def test_assisted_teleops_parameters_are_checked_by_their_own_names() -> None:
    with pytest.raises(ParameterError, match=r"^parameter 'simulation_time_step' = 2.0"):
        from_values(AssistedTeleopPlugin, {"projection_time": 1.0, "simulation_time_step": 2.0})
    with pytest.raises(ParameterError, match=r"^parameter 'cmd_vel_teleop' = ''"):
        from_values(AssistedTeleopPlugin, {"cmd_vel_teleop": ""})
