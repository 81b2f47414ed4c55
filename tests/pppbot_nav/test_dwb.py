"""Nav2's DWB controller core: settings, the dynamic window, trajectory simulation, each critic on
hand-computed trajectories, plan pruning, and the command chosen in small scenes."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from pppbot_common.params import ParameterError, from_values, parameter_fields, ros_name
from pppbot_nav.controller.dwb import (
    LIMITED_ACCEL_GENERATOR,
    DWBLocalPlanner,
    DWBSettings,
    axis_samples,
    generate_trajectories,
    sample_twists,
)
from pppbot_nav.controller.dwb_critic_plugins import make_critics
from pppbot_nav.controller.dwb_critics import (
    BaseObstacle,
    Context,
    GoalAlign,
    GoalDist,
    ObstacleFootprint,
    Oscillation,
    PathAlign,
    PathDist,
    PreferForward,
    RotateToGoal,
    Trajectories,
    Twirling,
    _outline_cells,
    adjust_plan_resolution,
)
from pppbot_nav.controller.plugin_settings import DWBParameters
from pppbot_nav.controller.pure_pursuit import ControlMode
from pppbot_nav.costmap.costs import INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE, NO_INFORMATION
from pppbot_nav.costmap.grid import Costmap
from pppbot_nav.costmap.layers import InflationLayer
from pppbot_nav.errors import CollisionAhead, ControllerError

DT = 0.05
RES = 0.05
#: ppp_bot's DWB configuration (Nav2 bringup's critics, its speed limits and samples) …
PPP = DWBSettings(max_vel_x=1.5, max_speed_xy=1.5, max_vel_theta=2.0, vx_samples=20, vtheta_samples=40,
                  linear_granularity=0.05, angular_granularity=0.025)
#: … and its critics' parameters (Nav2 bringup's scales).
PPP_CRITICS = {"BaseObstacle": {"scale": 0.02}, "PathAlign": {"scale": 32.0, "forward_point_distance": 0.1},
               "GoalAlign": {"scale": 24.0, "forward_point_distance": 0.1}, "PathDist": {"scale": 32.0},
               "GoalDist": {"scale": 24.0}, "RotateToGoal": {"scale": 32.0}}


#: The controller's settings a critic sees in :func:`context`: a 0.3 m footprint, unpadded.
UNPADDED = DWBSettings(robot_radius=0.3, footprint_padding=0.0)


def ppp(settings: DWBSettings = PPP) -> DWBLocalPlanner:
    """DWB with ``settings`` and ppp_bot's critics."""
    return DWBLocalPlanner(settings, make_critics(settings.critics, PPP_CRITICS))


def straight(length_m: float = 5.0, yaw: float | None = None) -> np.ndarray:
    xs = np.arange(0.0, length_m + 1e-9, RES)
    path = np.c_[xs, np.zeros_like(xs)]
    return path if yaw is None else np.c_[path, np.full(len(xs), yaw)]


def free_costmap(size_m: float = 5.0, centre: tuple[float, float] = (0.0, 0.0)) -> Costmap:
    cells = round(size_m / RES)
    return Costmap(np.zeros((cells, cells), np.uint8), RES, (centre[0] - size_m / 2, centre[1] - size_m / 2), "odom")


def with_obstacles(costmap: Costmap, points: list[tuple[float, float]]) -> Costmap:
    """``costmap`` with lethal cells at ``points``, inflated as pppbot's local costmap (0.9 m, 3.0, r 0.3)."""
    lethal = np.zeros(costmap.costs.shape, dtype=bool)
    for x, y in points:
        row, col = costmap.cell_of(x, y)
        lethal[int(row), int(col)] = True
    costs = InflationLayer(inflation_radius=0.9, cost_scaling_factor=3.0).spread(lethal, costmap.resolution)
    return Costmap(costs.copy(), costmap.resolution, costmap.origin, costmap.frame_id)


def trajectories(poses: list[list[tuple[float, float, float]]], velocity: list[tuple[float, float, float]],
                 step_s: float = 0.5) -> Trajectories:
    """Hand-made trajectories (each pose list in full; shorter ones padded with their last pose)."""
    longest = max(len(p) for p in poses)
    padded = np.array([p + [p[-1]] * (longest - len(p)) for p in poses], dtype=float)
    counts = np.array([len(p) for p in poses])
    return Trajectories(np.array(velocity, dtype=float), padded, counts, counts - 1, np.full(len(poses), step_s))


def context(costmap: Costmap, plan: np.ndarray, pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
            goal: tuple[float, float, float] | None = None, velocity: tuple[float, float, float] = (0.0, 0.0, 0.0),
            now_s: float = 0.0, settings: DWBSettings = UNPADDED) -> Context:
    end = (float(plan[-1, 0]), float(plan[-1, 1]), 0.0) if goal is None else goal
    return Context(np.array(pose, float), np.array(velocity, float), np.array(end, float), plan, costmap, now_s,
                   settings)


# ------------------------------------------------------------------------------------ settings
def test_default_settings_are_valid_and_ppp_bot_settings_too():
    DWBSettings().validate()
    PPP.validate()


@pytest.mark.parametrize(("change", "parameter"), [
    ({"max_vel_x": -0.1}, "min_vel_x"),
    ({"decel_lim_x": 2.5}, "decel_lim_x"),
    ({"acc_lim_theta": -1.0}, "acc_lim_theta"),
    ({"vx_samples": 0}, "vx_samples"),
    ({"vtheta_samples": 2.5}, "vtheta_samples"),
    ({"sim_time": 0.0}, "sim_time"),
    ({"linear_granularity": math.nan}, "linear_granularity"),
    ({"prune_plan": 1}, "prune_plan"),
    ({"max_vel_y": 0.2}, "max_vel_y"),
    ({"trajectory_generator_name": "dwb_plugins::Other"}, "trajectory_generator_name"),
    ({"critics": ()}, "critics"),
    ({"critics": ["PathDist"]}, "critics"),
])
def test_bad_settings_name_the_parameter(change, parameter):
    with pytest.raises(ControllerError) as err:
        DWBLocalPlanner(dataclasses.replace(DWBSettings(), **change))
    assert err.value.parameter == parameter
    assert parameter in str(err.value)


def test_unknown_critic_is_refused_with_the_known_ones_listed():
    with pytest.raises(ControllerError) as err:
        DWBSettings(critics=("BaseObstacle", "Obstacle")).validate()
    assert err.value.parameter == "critics"
    assert "'Obstacle'" in str(err.value)
    for known in ("BaseObstacle", "GoalAlign", "GoalDist", "ObstacleFootprint", "Oscillation", "PathAlign",
                  "PathDist", "PreferForward", "RotateToGoal", "Twirling"):
        assert known in str(err.value)


def test_critic_names_resolve_as_nav2s():
    planner = DWBLocalPlanner(DWBSettings(critics=("dwb_critics::PathDistCritic", "TwirlingCritic")))
    assert [type(c) for c in planner.critics] == [PathDist, Twirling]
    assert [c.name for c in planner.critics] == ["dwb_critics::PathDistCritic", "TwirlingCritic"]


def test_dwb_parameters_are_its_settings_but_the_costmap_s_footprint():
    """The plugin's parameters are DWBSettings' fields (typed there), the footprint excepted: the
    local costmap gives it, and a YAML value for it is refused."""
    declared = {ros_name(f) for f in parameter_fields(DWBParameters)}
    assert declared == {f.name for f in dataclasses.fields(DWBSettings)} - {"robot_radius", "footprint_padding"}
    params = from_values(DWBParameters, {"max_vel_x": 0.4, "critics": ["BaseObstacle", "PathDist"]})
    assert params.settings(robot_radius=0.25, footprint_padding=0.0) == DWBSettings(
        max_vel_x=0.4, critics=("BaseObstacle", "PathDist"), robot_radius=0.25, footprint_padding=0.0)
    assert params.make(robot_radius=0.25).settings.robot_radius == 0.25
    with pytest.raises(ParameterError, match="robot_radius"):
        from_values(DWBParameters, {"robot_radius": 0.2})
    with pytest.raises(ParameterError, match="max_vel_x"):
        from_values(DWBParameters, {"max_vel_x": math.nan})


# ------------------------------------------------------------------------------ dynamic window
def test_window_reaches_what_the_acceleration_limits_allow_in_the_period():
    samples = axis_samples(0.5, 0.0, 1.5, 2.5, -2.5, DT, 20)
    assert len(samples) == 20
    assert samples[0] == pytest.approx(0.5 - 2.5 * DT)
    assert samples[-1] == pytest.approx(0.5 + 2.5 * DT)
    assert np.allclose(np.diff(samples), 0.25 / 19)


def test_window_uses_the_deceleration_limit_below_the_current_speed():
    assert axis_samples(1.0, 0.0, 1.5, 0.5, -2.0, 0.1, 3) == pytest.approx([0.8, 0.925, 1.05])


def test_window_is_clamped_to_the_velocity_limits():
    assert axis_samples(0.05, 0.0, 1.5, 2.5, -2.5, 1.7, 4) == pytest.approx([0.0, 0.5, 1.0, 1.5])
    assert axis_samples(2.0, 0.0, 1.5, 2.5, -0.5, 0.2, 2) == pytest.approx([1.4, 1.5])  # from max_vel


def test_zero_is_slipped_in_where_the_samples_cross_it():
    assert axis_samples(0.0, -1.0, 1.0, 10.0, -10.0, 1.0, 4) == pytest.approx([-1.0, -1 / 3, 0.0, 1 / 3, 1.0])
    assert axis_samples(0.0, 0.0, 0.0, 1.0, -1.0, 1.0, 5) == [0.0]


def test_twists_too_slow_on_both_counts_or_all_zero_are_skipped():
    s = DWBSettings(vx_samples=3, vtheta_samples=3, max_vel_x=0.2, max_speed_xy=0.2, max_vel_theta=0.5,
                    min_speed_xy=0.15, min_speed_theta=0.4)
    twists = sample_twists(s, (0.0, 0.0, 0.0), 1.7)
    kept = {(round(x, 3), round(w, 3)) for x, _, w in twists}
    assert kept == {(0.0, -0.5), (0.0, 0.5), (0.2, -0.5), (0.2, 0.0), (0.2, 0.5), (0.1, -0.5), (0.1, 0.5)}


def test_twists_faster_than_max_speed_xy_are_skipped():
    twists = sample_twists(DWBSettings(max_vel_x=1.0, max_speed_xy=0.5, vx_samples=5), (0.0, 0.0, 0.0), 1.7)
    assert twists[:, 0].max() == pytest.approx(0.5)


# ---------------------------------------------------------------------------------- simulation
def test_standard_generator_ramps_the_velocity_by_the_acceleration_limit():
    s = DWBSettings(acc_lim_x=1.0, max_vel_x=1.0, max_speed_xy=1.0)  # 1.7 s in 4 steps of 0.425 s
    traj = generate_trajectories(s, np.zeros(3), np.zeros(3), np.array([[1.0, 0.0, 0.0]]))
    assert traj.steps.tolist() == [4] and traj.counts.tolist() == [6]
    x = traj.poses[0, :, 0]
    assert x[1:5] == pytest.approx(0.425 * np.cumsum([0.425, 0.85, 1.0, 1.0]))
    assert x[5] == x[4]  # include_last_point repeats the last pose


def test_limited_accel_generator_holds_the_twist_and_euler_steps_turn_after_moving():
    s = DWBSettings(trajectory_generator_name=LIMITED_ACCEL_GENERATOR, include_last_point=False,
                    discretize_by_time=True, time_granularity=0.85)
    traj = generate_trajectories(s, np.array([1.0, 2.0, 0.0]), np.zeros(3), np.array([[0.2, 0.0, 0.5]]))
    assert traj.counts.tolist() == [3]
    expected = [[1.0, 2.0, 0.0], [1.17, 2.0, 0.425],
                [1.17 + 0.17 * math.cos(0.425), 2.0 + 0.17 * math.sin(0.425), 0.85]]
    assert traj.poses[0] == pytest.approx(np.array(expected))


def test_limit_vel_cmd_in_traj_commands_the_first_step_velocity():
    s = DWBSettings(acc_lim_x=1.0, limit_vel_cmd_in_traj=True)
    traj = generate_trajectories(s, np.zeros(3), np.zeros(3), np.array([[0.26, 0.0, 0.0]]))
    step = 1.7 / traj.steps[0]
    assert traj.velocity[0, 0] == pytest.approx(min(0.26, step))


# ------------------------------------------------------------------------------------ critics
def test_path_dist_scores_cells_from_the_path_at_half_a_cell_per_unit_of_scale():
    costmap = Costmap(np.zeros((20, 20), np.uint8), 0.1, (0.0, 0.0))
    plan = np.c_[np.arange(0.05, 2.0, 0.1), np.full(20, 0.55)]  # row 5
    critic = PathDist("PathDist", 32.0, "last")
    assert critic.prepare(context(costmap, plan))
    traj = trajectories([[(1.05, 0.55, 0.0), (1.05, 0.65, 0.0), (1.05, 0.75, 0.0)]], [(0.2, 0.0, 0.0)])
    scores, illegal = critic.score(traj)
    assert scores.tolist() == [2.0] and illegal.tolist() == [0]
    assert critic.effective_scale() == pytest.approx(0.1 * 0.5 * 32.0)  # so it adds 2 · 1.6
    summed = PathDist("PathDist", 32.0, "sum")
    summed.prepare(context(costmap, plan))
    assert summed.score(traj)[0].tolist() == [3.0]


def test_goal_dist_scores_manhattan_cells_to_the_last_plan_cell_on_the_costmap():
    costmap = Costmap(np.zeros((20, 20), np.uint8), 0.1, (0.0, 0.0))
    plan = np.c_[np.arange(0.05, 3.0, 0.1), np.full(30, 0.55)]  # leaves the costmap after column 19
    critic = GoalDist("GoalDist", 24.0, "last")
    critic.prepare(context(costmap, plan))
    traj = trajectories([[(1.05, 0.75, 0.0)], [(2.5, 0.75, 0.0)]], [(0.2, 0.0, 0.0), (0.2, 0.0, 0.0)])
    scores, illegal = critic.score(traj)
    assert scores[0] == 2 + 9  # from (row 7, col 10) to (row 5, col 19)
    assert illegal.tolist() == [0, 1]  # the second leaves the grid


def test_map_grid_critics_without_plan_on_the_costmap():
    costmap = Costmap(np.zeros((20, 20), np.uint8), 0.1, (0.0, 0.0))
    plan = np.array([[5.0, 5.0], [6.0, 5.0]])
    traj = trajectories([[(1.0, 1.0, 0.0)]], [(0.2, 0.0, 0.0)])
    path_dist, path_align = PathDist("PathDist", 1.0, "last"), PathAlign("PathAlign", 1.0, "last", 0.1)
    assert not path_dist.prepare(context(costmap, plan))
    assert path_dist.score(traj)[1].tolist() == [2]  # stops on the unreachable cell: illegal
    assert not path_align.prepare(context(costmap, plan))
    scores, illegal = path_align.score(traj)
    assert illegal.tolist() == [0] and scores.tolist() == [20 * 20 + 1]  # legal, at the unreachable score


def test_align_critics_score_a_point_ahead_of_the_last_pose():
    costmap = Costmap(np.zeros((20, 20), np.uint8), 0.1, (0.0, 0.0))
    plan = np.c_[np.arange(0.05, 2.0, 0.1), np.full(20, 0.55)]
    align = PathAlign("PathAlign", 32.0, "last", 0.3)
    assert align.prepare(context(costmap, plan, pose=(0.05, 0.55, 0.0)))
    up = trajectories([[(0.05, 0.55, 0.0), (0.55, 0.55, math.pi / 2)]], [(0.2, 0.0, 0.5)])
    assert align.score(up)[0].tolist() == [3.0]  # (0.55, 0.85): three cells above the path
    goal_align = GoalAlign("GoalAlign", 24.0, "last", 0.3)
    goal_align.prepare(context(costmap, plan[:10], pose=(0.05, 0.55, 0.0)))  # goal (0.95, 0.55) → (1.25, 0.55)
    ahead = trajectories([[(0.95, 0.55, 0.0)]], [(0.2, 0.0, 0.0)])
    assert goal_align.score(ahead)[0].tolist() == [0.0]


def test_path_align_is_off_within_its_forward_distance_of_the_goal():
    costmap = Costmap(np.zeros((20, 20), np.uint8), 0.1, (0.0, 0.0))
    plan = np.c_[np.arange(0.05, 1.0, 0.1), np.full(10, 0.55)]
    align = PathAlign("PathAlign", 32.0, "last", 0.1)
    align.prepare(context(costmap, plan, pose=(0.9, 0.55, 0.0)))
    assert align.effective_scale() == 0.0


def test_base_obstacle_scores_the_last_pose_or_the_sum_and_rules_out_obstacles():
    costs = np.zeros((20, 20), np.uint8)
    costs[0, 1:4] = [10, 20, 30]
    costs[5, 5], costs[6, 6], costs[7, 7] = INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE, NO_INFORMATION
    costmap = Costmap(costs, 0.1, (0.0, 0.0))
    line = [(0.15, 0.05, 0.0), (0.25, 0.05, 0.0), (0.35, 0.05, 0.0)]
    traj = trajectories([line, [(0.55, 0.55, 0.0)], [(0.65, 0.65, 0.0)], [(0.75, 0.75, 0.0)], [(-0.1, 0.0, 0.0)]],
                        [(0.1, 0.0, 0.0)] * 5)
    last, summed = BaseObstacle("BaseObstacle", 0.02, False), BaseObstacle("BaseObstacle", 0.02, True)
    for critic in (last, summed):
        critic.prepare(context(costmap, np.array([[1.0, 1.0]])))
    scores, illegal = last.score(traj)
    assert scores[0] == 30.0 and illegal.tolist() == [0, 2, 2, 2, 1]
    assert summed.score(traj)[0][0] == 60.0


def test_obstacle_footprint_rules_out_lethal_cells_under_the_outline_only():
    costs = np.zeros((40, 40), np.uint8)
    costs[20, 26] = LETHAL_OBSTACLE  # 0.3 m right of the centre cell (20, 20)
    costmap = Costmap(costs, 0.05, (0.0, 0.0))
    critic = ObstacleFootprint("ObstacleFootprint", 1.0, False)
    critic.prepare(context(costmap, np.array([[1.0, 1.0]])))
    traj = trajectories([[(1.025, 1.025, 0.0)], [(0.6, 1.025, 0.0)]], [(0.1, 0.0, 0.0)] * 2)
    _, illegal = critic.score(traj)
    assert illegal.tolist() == [3, 0]


def nav2_line(x0: int, y0: int, x1: int, y1: int) -> list[tuple[int, int]]:
    """Nav2's ``dwb_critics::LineIterator``, step by step."""
    dx, dy = abs(x1 - x0), abs(y1 - y0)
    sx, sy = (1 if x1 >= x0 else -1), (1 if y1 >= y0 else -1)
    den, num = max(dx, dy), max(dx, dy) // 2
    x, y, cells = x0, y0, [(x0, y0)]
    for _ in range(den):
        num += min(dx, dy)
        if num >= den:
            num -= den
            x, y = (x + sx, y) if dx < dy else (x, y + sy)  # the minor axis steps
        x, y = (x + sx, y) if dx >= dy else (x, y + sy)  # the major axis always steps
        cells.append((x, y))
    return cells


def test_footprint_outline_is_rasterised_as_nav2s_line_iterator():
    rng = np.random.default_rng(7)
    ends = rng.integers(-6, 7, size=(200, 4))
    xs, ys = _outline_cells(*(ends[:, k, None] for k in range(4)))  # (200, 1) lines → (200, K) cells
    for (x0, y0, x1, y1), row_x, row_y in zip(ends, xs, ys, strict=True):
        expected = nav2_line(int(x0), int(y0), int(x1), int(y1))
        got = list(zip(row_x.tolist(), row_y.tolist(), strict=True))
        assert got[:len(expected)] == expected and set(got[len(expected):]) <= {expected[-1]}


def test_obstacle_footprint_takes_the_highest_cost_under_nav2s_outline():
    rng = np.random.default_rng(3)
    costs = rng.integers(0, 253, size=(40, 40)).astype(np.uint8)
    costs[rng.integers(0, 40, 30), rng.integers(0, 40, 30)] = LETHAL_OBSTACLE
    costmap = Costmap(costs, 0.05, (0.0, 0.0))
    poses = np.c_[rng.uniform(0.4, 1.6, 300), rng.uniform(0.4, 1.6, 300), rng.uniform(-4.0, 4.0, 300)]
    critic = ObstacleFootprint("ObstacleFootprint", 1.0, False)
    critic.prepare(context(costmap, np.array([[1.0, 1.0]])))
    scores, illegal = critic.score(trajectories([[tuple(p)] for p in poses], [(0.1, 0.0, 0.0)] * len(poses)))
    angles = np.arange(16) * 2.0 * math.pi / 16
    for pose, score, code in zip(poses, scores, illegal, strict=True):
        x = pose[0] + 0.3 * np.cos(angles + pose[2])
        y = pose[1] + 0.3 * np.sin(angles + pose[2])
        corners = [(int(cx // 0.05), int(cy // 0.05)) for cx, cy in zip(x, y, strict=True)]
        cells = [c for a, b in zip(corners, corners[1:] + corners[:1], strict=True) for c in nav2_line(*a, *b)]
        under = [int(costs[cy, cx]) for cx, cy in cells]
        assert (code == 3) == (LETHAL_OBSTACLE in under)
        assert score == max(under)


def test_footprint_padding_moves_each_vertex_out_along_its_axes_as_nav2s_pad_footprint():
    critic = ObstacleFootprint("ObstacleFootprint", 1.0, False)
    critic.prepare(context(free_costmap(), np.array([[1.0, 1.0]]),
                           settings=DWBSettings(robot_radius=0.3, footprint_padding=0.01)))
    footprint = critic.footprint
    assert footprint[0] == pytest.approx([0.31, 0.0])
    assert footprint[2] == pytest.approx([0.3 / math.sqrt(2) + 0.01, 0.3 / math.sqrt(2) + 0.01])
    assert footprint[4] == pytest.approx([0.01, 0.31])  # cos(π/2) is 6e-17 > 0 in doubles, as in Nav2


def test_rotate_to_goal_allows_only_turns_in_place_once_stopped_at_the_goal():
    costmap = free_costmap()
    critic = RotateToGoal("RotateToGoal", 32.0, 5.0, -1.0)
    plan = np.array([[0.0, 0.0], [1.0, 0.0]])
    critic.prepare(context(costmap, plan, pose=(1.1, 0.0, 0.0), goal=(1.0, 0.0, 1.0)))
    assert critic.in_window and critic.rotating
    traj = trajectories([[(1.1, 0.0, 0.0), (1.1, 0.0, 0.5)], [(1.1, 0.0, 0.0), (1.2, 0.0, 0.0)]],
                        [(0.0, 0.0, 0.3), (0.1, 0.0, 0.0)])
    scores, illegal = critic.score(traj)
    assert scores[0] == pytest.approx(0.5) and illegal.tolist() == [0, 2]
    critic.reset()
    assert not critic.in_window


def test_rotate_to_goal_makes_a_moving_robot_slow_down_first():
    critic = RotateToGoal("RotateToGoal", 32.0, 5.0, -1.0)
    critic.prepare(context(free_costmap(), np.array([[1.0, 0.0]]), pose=(0.9, 0.0, 0.0), goal=(1.0, 0.0, 0.0),
                           velocity=(0.5, 0.0, 0.0)))
    assert critic.in_window and not critic.rotating
    traj = trajectories([[(0.9, 0.0, 0.0), (1.0, 0.0, 0.2)], [(0.9, 0.0, 0.0)]], [(0.2, 0.0, 0.1), (0.5, 0.0, 0.0)])
    scores, illegal = critic.score(traj)
    assert scores[0] == pytest.approx(0.04 * 5.0 + 0.2) and illegal.tolist() == [0, 1]


def test_rotate_to_goal_lookahead_time_interpolates_the_yaw():
    critic = RotateToGoal("RotateToGoal", 1.0, 5.0, 0.75)
    critic.prepare(context(free_costmap(), np.array([[0.0, 0.0]]), goal=(0.0, 0.0, 0.0)))
    traj = trajectories([[(0.0, 0.0, 0.0), (0.0, 0.0, 0.4), (0.0, 0.0, 0.8), (0.0, 0.0, 0.8)]], [(0.0, 0.0, 0.8)])
    traj = dataclasses.replace(traj, steps=np.array([2]))  # two 0.5 s steps, the last pose repeated
    assert critic.score(traj)[0] == pytest.approx([0.6])


def test_oscillation_rules_out_the_old_direction_after_a_reversal_until_the_robot_moves():
    critic = Oscillation("Oscillation", 1.0, 0.05, 0.2, -1.0, 0.05)
    costmap, plan = free_costmap(), np.array([[1.0, 0.0]])
    both = trajectories([[(0.0, 0.0, 0.0)]] * 2, [(0.2, 0.0, 0.0), (-0.2, 0.0, 0.0)])
    critic.prepare(context(costmap, plan))
    critic.debrief(np.array([0.2, 0.0, 0.0]))
    assert critic.score(both)[1].tolist() == [0, 0]
    critic.debrief(np.array([-0.2, 0.0, 0.0]))  # reversed: forward is now oscillating
    assert critic.score(both)[1].tolist() == [1, 0]
    critic.prepare(context(costmap, plan, pose=(-0.03, 0.0, 0.0)))
    critic.debrief(np.array([-0.2, 0.0, 0.0]))
    assert critic.score(both)[1].tolist() == [1, 0]  # 3 cm is not enough
    critic.prepare(context(costmap, plan, pose=(-0.06, 0.0, 0.0)))
    critic.debrief(np.array([-0.2, 0.0, 0.0]))
    assert critic.score(both)[1].tolist() == [0, 0]


def test_oscillation_resets_after_its_time_on_the_planner_clock():
    critic = Oscillation("Oscillation", 1.0, -1.0, -1.0, 0.5, 0.05)
    both = trajectories([[(0.0, 0.0, 0.0)]] * 2, [(0.0, 0.0, 0.5), (0.0, 0.0, -0.5)])
    for now_s, w in ((0.0, 0.5), (0.1, -0.5), (0.4, -0.5)):
        critic.prepare(context(free_costmap(), np.array([[1.0, 0.0]]), now_s=now_s))
        critic.debrief(np.array([0.0, 0.0, w]))
    assert critic.score(both)[1].tolist() == [1, 0]  # ω flipped at 0.1 s, 0.3 s ago
    critic.prepare(context(free_costmap(), np.array([[1.0, 0.0]]), now_s=0.7))
    critic.debrief(np.array([0.0, 0.0, -0.5]))
    assert critic.score(both)[1].tolist() == [0, 0]


def test_prefer_forward_and_twirling():
    traj = trajectories([[(0.0, 0.0, 0.0)]] * 3, [(-0.1, 0.0, 0.0), (0.05, 0.0, 0.1), (0.3, 0.0, -0.5)])
    assert PreferForward("PreferForward", 1.0, 1.0, 0.1, 0.2, 10.0).score(traj)[0] == pytest.approx([1.0, 1.0, 5.0])
    assert Twirling("Twirling", 1.0).score(traj)[0] == pytest.approx([0.0, 0.1, 0.5])


def test_plan_resolution_is_raised_as_nav2_does():
    dense = adjust_plan_resolution(np.array([[0.0, 0.0], [1.0, 0.0], [1.1, 0.0]]), 0.1)
    assert dense[:, 0] == pytest.approx([*np.linspace(0.0, 1.0, 8), 1.1])  # int(0.8 / 0.1) − 1 = 7 steps


# ------------------------------------------------------------------------------------ planner
def test_straight_path_from_rest_drives_straight_ahead():
    cmd = DWBLocalPlanner(DWBSettings()).compute((0.0, 0.0, 0.0), (0.0, 0.0), straight(), free_costmap(), DT)
    assert cmd.linear_mps > 0.2 and cmd.angular_radps == 0.0
    assert cmd.mode is ControlMode.TRACKING and cmd.curvature == 0.0


def test_limited_accel_generator_from_rest_is_limited_by_the_acceleration_in_one_period():
    s = dataclasses.replace(PPP, trajectory_generator_name=LIMITED_ACCEL_GENERATOR)
    cmd = ppp(s).compute((0.0, 0.0, 0.0), (0.0, 0.0), straight(), free_costmap(), DT)
    # Map-grid scores are whole cells: twists whose trajectories end in the same cells tie, and the
    # first sampled (lowest v, most negative ω) wins, so v is near the window's top and ω near 0.
    assert 0.8 * s.acc_lim_x * DT < cmd.linear_mps <= s.acc_lim_x * DT
    assert abs(cmd.angular_radps) < 0.1
    assert sample_twists(s, (0.0, 0.0, 0.0), DT)[:, 0].max() == pytest.approx(s.acc_lim_x * DT)


def test_commands_stay_within_what_one_period_can_reach_at_speed():
    s = dataclasses.replace(PPP, trajectory_generator_name=LIMITED_ACCEL_GENERATOR, decel_lim_x=-1.0)
    cmd = ppp(s).compute((0.0, 0.0, 0.0), (1.0, 0.3), straight(), free_costmap(), DT)
    assert 1.0 - 1.0 * DT - 1e-9 <= cmd.linear_mps <= 1.0 + 2.5 * DT + 1e-9
    assert abs(cmd.angular_radps - 0.3) <= 3.2 * DT + 1e-9


def test_no_twist_in_the_window_is_no_valid_trajectory():
    s = DWBSettings(max_vel_x=0.0, max_speed_xy=0.0, max_vel_theta=0.0)
    with pytest.raises(CollisionAhead, match="no twist in the dynamic window"):
        ppp(s).compute((0.0, 0.0, 0.0), (0.0, 0.0), straight(), free_costmap(), DT)


def test_path_turning_left_turns_left():
    th = np.linspace(0.0, math.pi / 2, 60)
    left = np.c_[np.sin(th), 1.0 - np.cos(th)]  # radius 1 m, centre (0, 1)
    cmd = ppp().compute((0.0, 0.0, 0.0), (0.5, 0.0), left, free_costmap(), DT)
    assert cmd.angular_radps > 0.0 and cmd.curvature > 0.0


def test_obstacle_on_the_line_is_avoided():
    costmap = with_obstacles(free_costmap(), [(0.6, 0.0)])
    planner = ppp(DWBSettings(critics=PPP.critics))
    cmd = planner.compute((0.0, 0.0, 0.0), (0.26, 0.0), straight(), costmap, DT)
    ahead = generate_trajectories(planner.settings, np.zeros(3), np.array([0.26, 0.0, 0.0]),
                                  np.array([[0.26, 0.0, 0.0]]))
    critic = BaseObstacle("BaseObstacle", 0.02, False)
    critic.prepare(context(costmap, straight()))
    assert critic.score(ahead)[1].tolist() == [2]  # straight on hits the inscribed zone
    chosen = planner.best_trajectory
    assert (costmap.cost_at(chosen[:, 0], chosen[:, 1], NO_INFORMATION) < INSCRIBED_INFLATED_OBSTACLE).all()
    assert (cmd.linear_mps, cmd.angular_radps) != (0.26, 0.0)


def test_robot_in_the_inscribed_zone_has_no_valid_trajectory():
    costmap = with_obstacles(free_costmap(), [(0.2, 0.0)])
    with pytest.raises(CollisionAhead, match="BaseObstacle/Trajectory Hits Obstacle"):
        ppp().compute((0.0, 0.0, 0.0), (0.0, 0.0), straight(), costmap, DT)


def test_boxed_in_at_speed_with_one_period_to_brake_has_no_valid_trajectory():
    wall = [(0.45, y) for y in np.arange(-1.0, 1.0, RES)]
    s = dataclasses.replace(PPP, trajectory_generator_name=LIMITED_ACCEL_GENERATOR)
    with pytest.raises(CollisionAhead, match="no valid trajectory among"):
        ppp(s).compute((0.0, 0.0, 0.0), (1.0, 0.0), straight(), with_obstacles(free_costmap(), wall), DT)


@pytest.mark.parametrize("goal_yaw", [math.pi / 2, -math.pi / 2])
def test_at_the_goal_with_the_wrong_heading_it_turns_in_place_towards_the_goal_yaw(goal_yaw):
    path = straight(1.0, yaw=goal_yaw)
    cmd = ppp().compute((1.0, 0.0, 0.0), (0.0, 0.0), path, free_costmap(), DT)
    assert cmd.linear_mps == 0.0 and cmd.mode is ControlMode.ROTATE_TO_GOAL
    assert math.copysign(1.0, cmd.angular_radps) == math.copysign(1.0, goal_yaw)


def test_ties_go_to_the_first_twist_in_sampling_order():
    s = DWBSettings(critics=("Twirling",), vx_samples=3)
    cmd = ppp(s).compute((0.0, 0.0, 0.0), (0.0, 0.0), straight(), free_costmap(), DT)
    assert (cmd.linear_mps, cmd.angular_radps) == (pytest.approx(0.13), 0.0)  # (0, 0) is never sampled


def test_plan_is_pruned_behind_the_robot_and_shortened_ahead():
    planner = ppp()
    path = straight(10.0)
    cmd = planner.compute((3.0, 0.1, 0.0), (0.0, 0.0), path, free_costmap(10.0, (3.0, 0.0)), DT)
    assert planner.progress_index == 21  # (1.05, 0): the first point within 2 m
    assert cmd.local_plan[0] == pytest.approx([1.05, 0.0]) and cmd.local_plan[-1] == pytest.approx([4.95, 0.0])
    assert cmd.lookahead == pytest.approx((4.95, 0.0)) and cmd.lookahead_dist_m == pytest.approx(math.hypot(1.95, 0.1))
    planner.compute((4.0, 0.0, 0.0), (0.0, 0.0), path, free_costmap(10.0, (4.0, 0.0)), DT)
    assert planner.progress_index == 41  # (2.05, 0)


def test_the_half_costmap_bounds_the_transformed_plan():
    cmd = ppp().compute((0.0, 0.0, 0.0), (0.0, 0.0), straight(), free_costmap(2.0), DT)
    assert cmd.local_plan[-1] == pytest.approx([1.0, 0.0])


def test_robot_far_from_the_path_is_an_error():
    path = np.c_[np.arange(0.0, 1.0, RES), np.full(20, 4.0)]
    with pytest.raises(ControllerError, match="no path point within"):
        ppp().compute((0.0, 0.0, 0.0), (0.0, 0.0), path, free_costmap(10.0), DT)


def test_costmap_frame_differs_from_the_paths():
    planner, shifted = ppp(), ppp()
    path = straight()
    same = planner.compute((0.5, 0.2, 0.1), (0.3, 0.0), path, free_costmap(5.0, (0.5, 0.2)), DT)
    other = shifted.compute((0.5, 0.2, 0.1), (0.3, 0.0), path, free_costmap(5.0, (-9.5, 20.2)), DT,
                            costmap_pose=(-9.5, 20.2, 0.1))
    assert (other.linear_mps, other.angular_radps) == pytest.approx((same.linear_mps, same.angular_radps))
    assert other.local_plan == pytest.approx(same.local_plan)
    assert shifted.best_trajectory == pytest.approx(planner.best_trajectory)


def test_new_path_resets_the_critics():
    planner = ppp()
    rotate = next(c for c in planner.critics if isinstance(c, RotateToGoal))
    planner.compute((1.0, 0.0, 0.0), (0.0, 0.0), straight(1.0, yaw=1.0), free_costmap(), DT)
    assert rotate.rotating
    planner.compute((1.0, 0.0, 0.0), (0.0, 0.0), straight(3.0, yaw=1.0), free_costmap(), DT)
    assert not rotate.in_window


@pytest.mark.parametrize(("args", "parameter"), [
    ({"pose": (0.0, math.nan, 0.0)}, "pose"),
    ({"speed": (0.0,)}, "speed"),
    ({"dt_s": 0.0}, "dt_s"),
    ({"costmap": None}, "costmap"),
    ({"path": np.empty((0, 2))}, "path"),
])
def test_bad_input_is_a_controller_error(args, parameter):
    call = {"pose": (0.0, 0.0, 0.0), "speed": (0.0, 0.0), "path": straight(), "costmap": free_costmap(), "dt_s": DT}
    with pytest.raises(ControllerError) as err:
        ppp().compute(**{**call, **args})
    assert err.value.parameter == parameter
