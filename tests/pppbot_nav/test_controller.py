"""Path-following core: Nav2's Regulated Pure Pursuit on a kinematic unicycle, and the goal and progress checkers."""
from __future__ import annotations

import dataclasses
import itertools
import math
from typing import Any

import numpy as np
import pytest

from pppbot_nav.controller.checkers import SimpleGoalChecker, SimpleProgressChecker
from pppbot_nav.controller.pure_pursuit import Command, ControlMode, PurePursuit, PurePursuitSettings
from pppbot_nav.costmap.costs import INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE, NO_INFORMATION
from pppbot_nav.costmap.grid import Costmap
from pppbot_nav.errors import CollisionAhead, ControllerError

DT = 0.05
RES = 0.05
DEFAULTS = PurePursuitSettings()


def straight(length_m: float = 5.0, yaw: float | None = None, step_m: float = 0.05) -> np.ndarray:
    """A path along +x from the origin, with a final yaw column when ``yaw`` is given."""
    xs = np.arange(0.0, length_m + 1e-9, step_m)
    path = np.c_[xs, np.zeros_like(xs)]
    return path if yaw is None else np.c_[path, np.full(len(xs), yaw)]


def arc(radius_m: float, sweep_rad: float, points: int = 200) -> np.ndarray:
    """A left turn from the origin heading +x, centre (0, radius)."""
    th = np.linspace(0.0, sweep_rad, points)
    return np.c_[radius_m * np.sin(th), radius_m * (1.0 - np.cos(th))]


def free_costmap(size_m: float = 5.0, centre: tuple[float, float] = (0.0, 0.0)) -> Costmap:
    cells = round(size_m / RES)
    return Costmap(np.zeros((cells, cells), np.uint8), RES, (centre[0] - size_m / 2, centre[1] - size_m / 2), "odom")


def drive(pp: PurePursuit, path: np.ndarray, pose: tuple[float, float, float], steps: int,
          costmap: Costmap | None = None, goal: SimpleGoalChecker | None = None
          ) -> tuple[np.ndarray, list[Command]]:
    """Unicycle: integrate each command as it is for DT; stop once ``goal`` says the path's end is reached
    (its yaw, or any yaw for an (N, 2) path). Returns the poses (steps + 1, 3 at most) and the commands."""
    state = np.array(pose, dtype=float)
    v = w = 0.0
    poses, commands = [state.copy()], []
    for _ in range(steps):
        end = (path[-1, 0], path[-1, 1], path[-1, 2] if path.shape[1] == 3 else state[2])
        if goal is not None and goal.is_goal_reached(state, end):
            break
        cmd = pp.compute(state, (v, w), path, costmap, DT)
        v, w = cmd.linear_mps, cmd.angular_radps
        state = state + DT * np.array([v * math.cos(state[2]), v * math.sin(state[2]), w])
        poses.append(state.copy())
        commands.append(cmd)
    return np.array(poses), commands


def assert_angular_accel_limited(commands: list[Command], modes: set[ControlMode]) -> None:
    w = np.array([0.0] + [c.angular_radps for c in commands])
    turning = np.array([c.mode in modes for c in commands])
    assert turning.any()
    assert np.all(np.abs(np.diff(w))[turning] <= DEFAULTS.max_angular_accel * DT + 1e-9)


# ------------------------------------------------------------------------------------ tracking
def test_straight_line_from_a_lateral_offset_converges_and_reaches_the_end():
    path = straight(5.0, yaw=0.0)
    goal = SimpleGoalChecker()
    poses, commands = drive(PurePursuit(DEFAULTS), path, (0.0, 0.2, 0.0), 400, goal=goal)
    assert goal.is_goal_reached(poses[-1], (5.0, 0.0, 0.0))
    assert np.max(np.abs(poses[poses[:, 0] > 2.0, 1])) < 0.05
    assert commands[0].mode is ControlMode.TRACKING and commands[0].curvature < 0.0  # turns right, towards it


def test_circular_arc_is_tracked_closely():
    path = arc(2.0, math.pi)
    poses, commands = drive(PurePursuit(DEFAULTS), path, (0.0, 0.0, 0.0), 400,
                            goal=SimpleGoalChecker(xy_goal_tolerance=0.25))
    radius_error = np.hypot(poses[:, 0], poses[:, 1] - 2.0) - 2.0
    assert np.sqrt(np.mean(radius_error ** 2)) < 0.05
    assert np.hypot(*(poses[-1, :2] - path[-1])) < 0.25
    assert all(c.mode is ControlMode.TRACKING for c in commands)
    assert commands[len(commands) // 2].linear_mps == pytest.approx(DEFAULTS.desired_linear_vel)  # r > 0.9 m


def test_path_behind_turns_in_place_first_within_the_angular_acceleration_limit():
    path = np.c_[-straight(3.0)[:, 0], np.zeros(len(straight(3.0)))]
    poses, commands = drive(PurePursuit(DEFAULTS), path, (0.0, 0.0, 0.0), 200)
    for pose, cmd in zip(poses[:-1], commands, strict=True):  # each command and the pose it came from
        to_carrot = math.atan2(cmd.lookahead[1] - pose[1], cmd.lookahead[0] - pose[0])
        if abs(math.remainder(to_carrot - pose[2], 2.0 * math.pi)) > DEFAULTS.rotate_to_heading_min_angle:
            assert cmd.linear_mps == 0.0 and cmd.mode is ControlMode.ROTATE_TO_PATH
    assert commands[0].mode is ControlMode.ROTATE_TO_PATH
    assert any(c.mode is ControlMode.TRACKING and c.linear_mps > 0.0 for c in commands)
    assert_angular_accel_limited(commands, {ControlMode.ROTATE_TO_PATH})
    assert poses[-1, 0] < -1.0


def test_tight_arc_slows_down_but_not_below_the_regulated_minimum():
    path = arc(0.5, 1.5 * math.pi, 300)
    _, commands = drive(PurePursuit(DEFAULTS), path, (0.0, 0.0, 0.0), 200)
    tracking = [c for c in commands if c.mode is ControlMode.TRACKING
                and np.hypot(*(np.asarray(c.lookahead) - path[-1])) > 0.1]  # not approaching the end
    assert len(tracking) > 20
    v = np.array([c.linear_mps for c in tracking])
    assert np.all(v < DEFAULTS.desired_linear_vel - 0.1)
    assert np.all(v >= DEFAULTS.regulated_linear_scaling_min_speed - 1e-12)
    assert np.allclose([c.angular_radps for c in tracking], v * np.array([c.curvature for c in tracking]))


def test_angular_velocity_cap_keeps_the_arc():
    settings = dataclasses.replace(DEFAULTS, max_angular_vel=0.5, use_regulated_linear_velocity_scaling=False)
    path = np.c_[straight(3.0)[:, 0], np.full(len(straight(3.0)), 0.3)]
    cmd = PurePursuit(settings).compute((0.0, 0.0, 0.0), (0.0, 0.0), path, None, DT)
    assert cmd.curvature == pytest.approx(2.0 * 0.3 / 0.6 ** 2)
    assert cmd.angular_radps == pytest.approx(0.5)
    assert cmd.linear_mps == pytest.approx(0.5 / cmd.curvature)


def test_high_inflated_cost_at_the_robot_slows_it():
    path = straight(3.0)
    free = PurePursuit(DEFAULTS).compute((0.5, 0.0, 0.0), (0.5, 0.0), path, free_costmap(), DT)
    near = free_costmap()
    row, col = near.cell_of(0.5, 0.0)
    near.costs[int(row) - 3:int(row) + 4, int(col) - 3:int(col) + 4] = 200
    slowed = PurePursuit(DEFAULTS).compute((0.5, 0.0, 0.0), (0.5, 0.0), path, near, DT)
    assert free.linear_mps == pytest.approx(DEFAULTS.desired_linear_vel)
    obstacle_m = -math.log(200 / 252) / DEFAULTS.inflation_cost_scaling_factor + DEFAULTS.robot_radius
    assert slowed.linear_mps == pytest.approx(DEFAULTS.desired_linear_vel * obstacle_m / DEFAULTS.cost_scaling_dist)
    assert DEFAULTS.regulated_linear_scaling_min_speed <= slowed.linear_mps < free.linear_mps
    unregulated = dataclasses.replace(DEFAULTS, use_cost_regulated_linear_velocity_scaling=False)
    assert PurePursuit(unregulated).compute((0.5, 0.0, 0.0), (0.5, 0.0), path, near, DT).linear_mps == free.linear_mps


# ----------------------------------------------------------------------------------- collision
def wall_at(x_m: float, value: int) -> Costmap:
    costmap = free_costmap()
    _, col = costmap.cell_of(x_m, 0.0)
    costmap.costs[:, int(col)] = value
    return costmap


def test_lethal_wall_ahead_raises_collision_ahead_naming_the_pose():
    with pytest.raises(CollisionAhead, match=r"would reach \(0\.3[0-5]\d, 0\.000\).*lethal"):
        wall = wall_at(0.32, LETHAL_OBSTACLE)  # cells 0.30…0.35 m
        PurePursuit(DEFAULTS).compute((0.0, 0.0, 0.0), (0.5, 0.0), straight(3.0), wall, DT)


@pytest.mark.parametrize("costmap, settings", [
    (free_costmap(), DEFAULTS),
    (wall_at(0.3, NO_INFORMATION), DEFAULTS),  # unknown is not a collision
    (wall_at(0.3, LETHAL_OBSTACLE), dataclasses.replace(DEFAULTS, use_collision_detection=False)),
    (wall_at(1.0, LETHAL_OBSTACLE), DEFAULTS),  # beyond the carrot (0.6 m)
], ids=["free", "unknown-wall", "detection-off", "wall-beyond-carrot"])
def test_no_collision_raised(costmap: Costmap, settings: PurePursuitSettings):
    cmd = PurePursuit(settings).compute((0.0, 0.0, 0.0), (0.5, 0.0), straight(3.0), costmap, DT)
    assert cmd.linear_mps == pytest.approx(0.5)


def test_a_robot_inside_the_inscribed_zone_may_leave_it_but_not_hit_a_lethal_cell():
    from pppbot_nav.costmap.costs import INSCRIBED_INFLATED_OBSTACLE
    costmap = free_costmap()
    row, col = costmap.cell_of(0.0, 0.0)
    costmap.costs[:, : int(col) + 3] = INSCRIBED_INFLATED_OBSTACLE  # the robot stands in the zone
    cmd = PurePursuit(DEFAULTS).compute((0.0, 0.0, 0.0), (0.3, 0.0), straight(3.0), costmap, DT)
    assert cmd.linear_mps > 0.0  # driving out of it is allowed
    costmap.costs[:, int(col) + 3] = LETHAL_OBSTACLE
    with pytest.raises(CollisionAhead, match="lethal"):
        PurePursuit(DEFAULTS).compute((0.0, 0.0, 0.0), (0.3, 0.0), straight(3.0), costmap, DT)
    # Turning in place sweeps nothing new (a circular footprint), even on an inscribed cell.
    behind = straight(3.0)
    behind[:, 0] *= -1.0
    turn = PurePursuit(DEFAULTS).compute((0.0, 0.0, 0.0), (0.0, 0.0), behind, costmap, DT)
    assert turn.linear_mps == 0.0 and turn.angular_radps != 0.0


def wall_along_x(y_m: float) -> Costmap:
    """A lethal wall along x at ``y_m`` with its inscribed zone (cell centres within 0.3 m)."""
    costmap = free_costmap()
    _, ys = costmap.cell_centres()
    row, _ = costmap.cell_of(0.0, y_m)
    wall_y = ys[int(row), 0]
    costmap.costs[np.abs(ys - wall_y) < DEFAULTS.robot_radius] = INSCRIBED_INFLATED_OBSTACLE
    costmap.costs[int(row), :] = LETHAL_OBSTACLE
    return costmap


@pytest.mark.parametrize("slope, allowed", [(0.0, True), (-0.2, True), (0.2, False)],
                         ids=["along-the-wall", "away-from-it", "towards-it"])
def test_inside_the_inscribed_zone_the_robot_never_drives_nearer_the_obstacle(slope: float, allowed: bool):
    costmap = wall_along_x(0.26)  # the robot at y = 0 is 0.26 m from the wall's cells: in the zone
    path = straight(3.0)
    path[:, 1] = slope * path[:, 0]  # the line meets the wall at x = 1.3 m, beyond the check's reach
    pp = PurePursuit(DEFAULTS)
    if allowed:
        assert pp.compute((0.0, 0.0, math.atan(slope)), (0.3, 0.0), path, costmap, DT).linear_mps > 0.0
    else:
        with pytest.raises(CollisionAhead, match=r"inside the inscribed zone, would come nearer an obstacle: "
                                                 r"0\.2\d\d → 0\.2\d\d m"):
            pp.compute((0.0, 0.0, math.atan(slope)), (0.3, 0.0), path, costmap, DT)


# ---------------------------------------------------------------------------- approach and goal
def test_approaching_the_end_slows_down_to_no_less_than_the_approach_minimum():
    path = straight(2.0)
    poses, commands = drive(PurePursuit(DEFAULTS), path, (0.0, 0.0, 0.0), 400, goal=SimpleGoalChecker())
    v = np.array([c.linear_mps for c in commands])
    to_end = 2.0 - poses[:-1, 0]
    approach = to_end < DEFAULTS.approach_velocity_scaling_dist
    assert approach.sum() > 10
    assert np.all(np.diff(v[approach]) <= 1e-12)
    assert v[approach][-1] < 0.5 * DEFAULTS.desired_linear_vel
    assert np.all(v >= DEFAULTS.min_approach_linear_velocity)
    at_the_end = PurePursuit(DEFAULTS).compute((1.98, 0.0, 0.0), (0.1, 0.0), path, None, DT)
    assert at_the_end.linear_mps == pytest.approx(DEFAULTS.min_approach_linear_velocity)
    assert np.all(v[to_end > DEFAULTS.approach_velocity_scaling_dist + 0.05] == pytest.approx(0.5))


@pytest.mark.parametrize("start_yaw, goal_yaw, sign", [(0.0, math.pi / 2, 1.0), (-3.0, 3.0, -1.0)],
                         ids=["left", "across-pi"])
def test_inside_the_goal_tolerance_it_turns_in_place_to_the_goal_yaw(start_yaw: float, goal_yaw: float, sign: float):
    path = straight(2.0, yaw=goal_yaw)
    goal = SimpleGoalChecker()
    poses, commands = drive(PurePursuit(DEFAULTS), path, (1.9, 0.05, start_yaw), 200, goal=goal)
    assert all(c.mode is ControlMode.ROTATE_TO_GOAL and c.linear_mps == 0.0 for c in commands)
    assert math.copysign(1.0, commands[0].angular_radps) == sign
    assert goal.is_goal_reached(poses[-1], (2.0, 0.0, goal_yaw))
    assert_angular_accel_limited(commands, {ControlMode.ROTATE_TO_GOAL})


def test_without_a_goal_yaw_it_does_not_turn_to_one():
    cmd = PurePursuit(DEFAULTS).compute((1.9, 0.0, 0.0), (0.1, 0.0), straight(2.0), None, DT)
    assert cmd.mode is ControlMode.TRACKING and cmd.linear_mps > 0.0


# ------------------------------------------------------------------------ path handling details
def test_carrot_is_interpolated_onto_the_lookahead_circle():
    path = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    cmd = PurePursuit(DEFAULTS).compute((0.0, 0.0, 0.0), (0.0, 0.0), path, None, DT)
    assert cmd.lookahead == pytest.approx((0.6, 0.0))
    assert cmd.curvature == 0.0
    short = PurePursuit(DEFAULTS).compute((0.0, 0.0, 0.0), (0.0, 0.0), np.array([[0.3, 0.1]]), None, DT)
    assert short.lookahead == pytest.approx((0.3, 0.1))  # the last point when none is far enough


@pytest.mark.parametrize("v, expected", [(0.4, 0.6), (0.1, 0.3), (1.0, 0.9), (-0.4, 0.6)])
def test_velocity_scaled_lookahead_is_clamped(v: float, expected: float):
    settings = dataclasses.replace(DEFAULTS, use_velocity_scaled_lookahead_dist=True)
    cmd = PurePursuit(settings).compute((0.0, 0.0, 0.0), (v, 0.0), straight(3.0), None, DT)
    assert cmd.lookahead_dist_m == pytest.approx(expected)


def test_progress_does_not_jump_back_where_the_path_crosses_itself():
    corners = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [1.0, 1.0], [1.0, -1.5]])
    path = np.concatenate([np.linspace(a, b, 21)[:-1] for a, b in itertools.pairwise(corners)] + [corners[-1:]])
    pp = PurePursuit(DEFAULTS)
    poses, commands = drive(pp, path, (0.0, 0.0, 0.0), 600, goal=SimpleGoalChecker())
    local_starts = [len(path) - len(c.local_plan) for c in commands]  # no costmap: the plan runs to the end
    assert np.all(np.diff(local_starts) >= 0)
    assert np.hypot(*(poses[-1, :2] - corners[-1])) < 0.25  # it went round the loop, not down the crossing
    done = pp.progress_index
    assert done > 60
    pp.compute((0.0, 0.0, 0.0), (0.0, 0.0), path.copy(), None, DT)  # the same path in a new array: progress kept
    assert pp.progress_index == done
    pp.compute((0.0, 0.0, 0.0), (0.0, 0.0), path + [0.0, 0.01], None, DT)  # a new path: progress starts over
    assert pp.progress_index == 0


def test_local_plan_is_cropped_to_the_costmap_half_extent():
    cmd = PurePursuit(DEFAULTS).compute((0.0, 0.0, 0.0), (0.0, 0.0), straight(10.0), free_costmap(2.0), DT)
    assert cmd.local_plan.shape[1] == 2
    assert np.all(np.hypot(*cmd.local_plan.T) <= 1.0 + 1e-9) and cmd.local_plan[-1, 0] > 0.9


def test_random_poses_near_a_path_give_bounded_commands():
    rng = np.random.default_rng(7)
    path = arc(1.5, math.pi, 150)
    for _ in range(200):
        pose = (*(path[rng.integers(len(path))] + rng.normal(0.0, 0.3, 2)), rng.uniform(-math.pi, math.pi))
        speed = (rng.uniform(0.0, 0.5), rng.uniform(-2.0, 2.0))
        cmd = PurePursuit(DEFAULTS).compute(pose, speed, path, None, DT)
        assert 0.0 <= cmd.linear_mps <= DEFAULTS.desired_linear_vel
        assert abs(cmd.angular_radps) <= DEFAULTS.max_angular_vel + 1e-12
        assert np.isfinite(cmd.curvature)


# ------------------------------------------------------------------------------------ checkers
def test_goal_checker_is_stateful_and_wraps_yaw():
    checker = SimpleGoalChecker()
    assert not checker.is_goal_reached((0.2, 0.0, 1.0), (0.0, 0.0, 0.0))  # xy inside, yaw not
    assert checker.is_goal_reached((0.4, 0.0, 0.1), (0.0, 0.0, 0.0))  # xy stays inside: stateful
    checker.reset()
    assert not checker.is_goal_reached((0.4, 0.0, 0.1), (0.0, 0.0, 0.0))
    stateless = SimpleGoalChecker(stateful=False)
    assert not stateless.is_goal_reached((0.2, 0.0, 1.0), (0.0, 0.0, 0.0))
    assert not stateless.is_goal_reached((0.4, 0.0, 0.1), (0.0, 0.0, 0.0))
    assert SimpleGoalChecker().is_goal_reached((0.0, 0.1, 3.1), (0.0, 0.0, -3.1))  # 0.08 rad across ±π
    assert not SimpleGoalChecker().is_goal_reached((0.0, 0.1, 2.8), (0.0, 0.0, -2.8))  # 0.68 rad


def test_progress_checker_fails_when_stuck_and_rebases_when_moving():
    checker = SimpleProgressChecker()
    assert all(checker.check((0.1 * t, 0.0), t) for t in np.arange(0.0, 30.0, 0.5))  # moving at 0.1 m/s
    checker.reset()
    assert all(checker.check((0.0, 0.0), t) for t in np.arange(0.0, 10.01, 0.5))
    assert not checker.check((0.0, 0.0, 1.0), 10.5)  # stuck for over 10 s (a yaw is ignored)
    assert checker.check((0.6, 0.0), 11.0)  # moved far enough: a new baseline
    assert checker.check((0.7, 0.0), 20.0)
    assert not checker.check((0.7, 0.0), 21.5)
    checker.reset()
    assert checker.check((0.7, 0.0), 22.0)


# ----------------------------------------------------------------------------------- bad values
@pytest.mark.parametrize("parameter, value", [
    ("desired_linear_vel", 0.0), ("desired_linear_vel", math.nan), ("lookahead_dist", math.inf),
    ("lookahead_time", -1.0), ("min_lookahead_dist", 1.0), ("regulated_linear_scaling_min_speed", 0.6),
    ("min_approach_linear_velocity", -0.1), ("cost_scaling_gain", 1.5), ("rotate_to_heading_min_angle", 4.0),
    ("use_collision_detection", "yes"), ("robot_radius", 0.0), ("max_angular_accel", 0.0),
    ("goal_dist_tol", -0.25), ("max_allowed_time_to_collision_up_to_carrot", 0.0),
])
def test_bad_settings_name_the_parameter_and_value(parameter: str, value: Any):
    with pytest.raises(ControllerError) as caught:
        PurePursuit(dataclasses.replace(DEFAULTS, **{parameter: value}))
    assert caught.value.parameter == parameter
    assert parameter in str(caught.value) and repr(value).strip("'") in str(caught.value)


def nan_row(path: np.ndarray, row: int) -> np.ndarray:
    path = path.copy()
    path[row, 1] = math.nan
    return path


@pytest.mark.parametrize("pose, speed, path, dt_s, parameter, words", [
    ((0, 0, 0), (0, 0), np.empty((0, 2)), DT, "path", "empty"),
    ((0, 0, 0), (0, 0), nan_row(straight(1.0), 3), DT, "path", "point 3"),
    ((0, 0, 0), (0, 0), np.zeros((4, 4)), DT, "path", "shape (4, 4)"),
    ((0, 0, 0), (0, 0), [1.0, 2.0], DT, "path", "shape (2,)"),
    ((0, math.nan, 0), (0, 0), straight(1.0), DT, "pose", "nan"),
    ((0, 0), (0, 0), straight(1.0), DT, "pose", "3 numbers"),
    ((0, 0, 0), (math.inf, 0), straight(1.0), DT, "speed", "inf"),
    ((0, 0, 0), (0, 0), straight(1.0), 0.0, "dt_s", "0.0"),
])
def test_bad_inputs_raise_controller_error(pose, speed, path, dt_s, parameter, words):
    with pytest.raises(ControllerError, match=words.replace("(", r"\(").replace(")", r"\)")) as caught:
        PurePursuit(DEFAULTS).compute(pose, speed, path, None, dt_s)
    assert caught.value.parameter == parameter


@pytest.mark.parametrize("make, parameter", [
    (lambda: SimpleGoalChecker(xy_goal_tolerance=0.0), "xy_goal_tolerance"),
    (lambda: SimpleGoalChecker(yaw_goal_tolerance=-0.1), "yaw_goal_tolerance"),
    (lambda: SimpleGoalChecker(stateful="true"), "stateful"),  # type: ignore[arg-type]
    (lambda: SimpleProgressChecker(required_movement_radius=math.nan), "required_movement_radius"),
    (lambda: SimpleProgressChecker(movement_time_allowance=0.0), "movement_time_allowance"),
    (lambda: SimpleGoalChecker().is_goal_reached((0.0, math.nan, 0.0), (0.0, 0.0, 0.0)), "pose"),
    (lambda: SimpleProgressChecker().check((0.0, 0.0), math.nan), "now_s"),
])
def test_bad_checker_values_raise_controller_error(make, parameter: str):
    with pytest.raises(ControllerError) as caught:
        make()
    assert caught.value.parameter == parameter and isinstance(caught.value, ValueError)


def test_a_carrot_that_cuts_a_corner_into_an_obstacle_is_brought_closer():
    # The path runs along x to (0.5, 0), then turns left up x = 0.5; the corner's inside is an
    # inscribed block (x 0.2…0.42, y 0.15…1.0) that the path itself clears.
    path = np.vstack([straight(0.5), np.column_stack([np.full(40, 0.5), np.linspace(0.05, 2.0, 40)])])
    costmap = free_costmap()
    rows, cols = costmap.cell_of(np.array([0.2, 0.42]), np.array([0.15, 1.0]))
    costmap.costs[rows[0]:rows[1] + 1, cols[0]:cols[1] + 1] = INSCRIBED_INFLATED_OBSTACLE
    pose, speed = (0.2, 0.0, 0.6), (0.3, 0.0)
    # At the usual 0.6 m the arc to the carrot on the upward leg cuts through the block; at the
    # closest lookahead the carrot is the corner and the arc stays clear.
    free = PurePursuit(DEFAULTS).compute(pose, speed, path, free_costmap(), DT)
    assert free.lookahead_dist_m == DEFAULTS.lookahead_dist and free.angular_radps > 0
    cmd = PurePursuit(DEFAULTS).compute(pose, speed, path, costmap, DT)
    assert cmd.mode is ControlMode.TRACKING
    assert cmd.lookahead_dist_m == DEFAULTS.min_lookahead_dist and cmd.angular_radps < 0
    # Were the corner itself blocked, closer carrots would not help: still a collision.
    rows, cols = costmap.cell_of(np.array([0.4, 0.6]), np.array([-0.1, 0.1]))
    costmap.costs[rows[0]:rows[1] + 1, cols[0]:cols[1] + 1] = INSCRIBED_INFLATED_OBSTACLE
    with pytest.raises(CollisionAhead):
        PurePursuit(DEFAULTS).compute(pose, speed, path, costmap, DT)
