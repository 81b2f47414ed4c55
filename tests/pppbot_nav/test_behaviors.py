"""Nav2's behaviours without ROS: what each commands, when it ends, and when it must stop short."""
from __future__ import annotations

import math

import numpy as np
import pytest

from pppbot_common.maps import OccupancyGrid
from pppbot_nav.behaviors import (
    INSCRIBED_OCCUPANCY,
    Behavior,
    DriveOnHeading,
    Outcome,
    Spin,
    Wait,
    assisted,
    back_up,
    collision_ahead,
    drive_on_heading_problem,
)

DT = 0.05


def run(behavior: Behavior, pose: tuple[float, float, float], limit_s: float = 30.0
        ) -> tuple[list[tuple[float, float]], tuple[float, float, float], float, Outcome | None]:
    """Integrates the commands from ``pose`` until the behaviour ends: the commands, the end pose,
    time, and how it ended."""
    behavior.start(pose, 0.0)
    x, y, yaw = pose
    commands = []
    t = 0.0
    outcome = None
    while t < limit_s:
        command = behavior.step((x, y, yaw), t)
        if isinstance(command, Outcome):
            outcome = command
            break
        commands.append(command)
        v, w = command
        x, y, yaw = x + v * DT * math.cos(yaw), y + v * DT * math.sin(yaw), yaw + w * DT
        t += DT
    return commands, (x, y, yaw), t, outcome


@pytest.mark.parametrize("spin_dist", [1.57, -1.57, 3.5])
def test_spin_turns_its_distance_on_the_spot_and_slows_towards_the_end(spin_dist: float):
    commands, (x, y, yaw), _, outcome = run(Spin(spin_dist_rad=spin_dist), (1.0, 2.0, 3.0))
    assert outcome is Outcome.DONE
    assert (x, y) == (1.0, 2.0)
    assert yaw - 3.0 == pytest.approx(spin_dist, abs=0.06)  # within a period's turn at the slowest
    speeds = [abs(w) for _, w in commands]
    assert all(np.sign(w) == np.sign(spin_dist) for _, w in commands)
    assert max(speeds) == pytest.approx(1.0) and speeds[-1] < 0.7


def test_spin_gives_up_after_its_time_allowance():
    spin = Spin(spin_dist_rad=1.57, time_allowance_s=2.0)
    spin.start((0.0, 0.0, 0.0), 0.0)
    assert spin.step((0.0, 0.0, 0.0), 1.9) == (0.0, 1.0)
    assert spin.step((0.0, 0.0, 0.0), 2.1) is Outcome.TIMEOUT  # the robot is stuck: no turn in 2 s


@pytest.mark.parametrize("distance, speed", [(0.3, 0.1), (-0.3, 0.1), (0.3, -0.1)])
def test_backup_drives_backwards_its_distance_at_its_speed_whatever_the_signs(distance: float, speed: float):
    commands, (x, y, _), t, outcome = run(back_up(distance, speed), (0.0, 0.0, math.pi / 2))
    assert outcome is Outcome.DONE
    assert all(c == (-0.1, 0.0) for c in commands)
    assert x == pytest.approx(0.0, abs=1e-9) and y == pytest.approx(-0.3, abs=0.006)
    assert t == pytest.approx(3.0, abs=0.1)


def test_drive_on_heading_drives_forward_and_reports_its_progress():
    drive = DriveOnHeading(distance_m=0.5, speed=0.25)
    commands, (x, y, _), _, outcome = run(drive, (1.0, 1.0, 0.0))
    assert outcome is Outcome.DONE and set(commands) == {(0.25, 0.0)}
    assert x == pytest.approx(1.5, abs=0.013) and y == 1.0
    assert drive.progress == pytest.approx(0.5, abs=0.013) and drive.remaining == 0.0


def test_drive_on_heading_times_out_when_the_robot_does_not_move():
    drive = DriveOnHeading(distance_m=0.5, speed=0.25, time_allowance_s=1.0)
    drive.start((0.0, 0.0, 0.0), 0.0)
    assert drive.step((0.0, 0.0, 0.0), 0.9) == (0.25, 0.0)
    assert drive.step((0.0, 0.0, 0.0), 1.1) is Outcome.TIMEOUT


@pytest.mark.parametrize("distance, speed, problem", [
    (0.5, 0.0, "speed is 0"), (0.5, -0.1, "signs"), (-0.5, 0.1, "signs"), (math.nan, 0.1, "finite"),
    (0.5, 0.1, None), (-0.5, -0.1, None)])
def test_drive_on_heading_refuses_what_nav2_calls_invalid_input(distance: float, speed: float, problem: str | None):
    found = drive_on_heading_problem(distance, speed)
    assert (found is None) == (problem is None)
    if problem is not None:
        assert found is not None and problem in found


def test_wait_stands_still_for_its_duration():
    wait = Wait(wait_duration_s=2.0)
    commands, _, t, outcome = run(wait, (0.0, 0.0, 0.0))
    assert outcome is Outcome.DONE and wait.remaining == 0.0
    assert set(commands) == {(0.0, 0.0)} and t == pytest.approx(2.0, abs=DT)


# ------------------------------------------------------------------------------- collision gate
def costmap_with_wall(wall_x_m: float) -> OccupancyGrid:
    """A 4 × 4 m costmap (0.05 m cells, origin (−2, −2)): a lethal wall along y at ``wall_x_m`` with
    inscribed cells (centres) within 0.3 m of it, unknown in the top-left corner."""
    data = np.zeros((80, 80), dtype=np.int8)
    xs = -2.0 + (np.arange(80) + 0.5) * 0.05
    distance = np.abs(xs - wall_x_m)
    data[:, distance < 0.3 - 1e-9] = INSCRIBED_OCCUPANCY
    data[:, distance < 0.025] = 100
    data[70:, :10] = -1
    return OccupancyGrid(data=data, resolution=0.05, origin=(-2.0, -2.0, 0.0))


@pytest.mark.parametrize("robot_x, stops", [(0.0, False), (0.14, False), (0.25, True), (0.48, True)],
                         ids=["far", "just-outside-the-zone", "in-the-zone", "on-the-wall"])
def test_a_spin_is_refused_where_the_footprint_circle_touches_an_obstacle(robot_x: float, stops: bool):
    reason = collision_ahead(Spin(), costmap_with_wall(0.475), (robot_x, 0.0, 0.0), (0.0, 1.0))
    assert (reason is not None) == stops
    if reason is not None:
        assert "collision ahead" in reason and f"({robot_x:.2f}, 0.00)" in reason


@pytest.mark.parametrize("yaw, stops", [(0.0, False), (math.pi, True)], ids=["wall-ahead", "wall-behind"])
def test_backing_up_stops_when_the_simulated_motion_reaches_the_zone_behind(yaw: float, stops: bool):
    # Backing at 0.05 m/s for 2 s simulates 0.1 m: from x = 0.12 the inscribed cells (x >= 0.2)
    # are within it when the robot faces away from the wall.
    behavior = back_up(0.3, 0.05)
    reason = collision_ahead(behavior, costmap_with_wall(0.475), (0.12, 0.0, yaw), (-0.05, 0.0))
    assert (reason is not None) == stops
    if reason is not None:
        assert "m behind" in reason and "inscribed" in reason


def test_the_check_looks_no_further_than_the_behaviour_still_has_to_go():
    # Driving 0.5 m/s towards the zone 0.4 m ahead: 2 s ahead reaches it, but 0.2 m left to go does not.
    costmap = costmap_with_wall(0.475)
    far = DriveOnHeading(distance_m=1.0, speed=0.5)
    near = DriveOnHeading(distance_m=0.2, speed=0.5)
    for drive in (far, near):
        drive.start((-0.25, 0.0, 0.0), 0.0)
    assert collision_ahead(far, costmap, (-0.25, 0.0, 0.0), (0.5, 0.0)) is not None
    assert collision_ahead(near, costmap, (-0.25, 0.0, 0.0), (0.5, 0.0)) is None
    assert collision_ahead(far, costmap, (-0.25, 0.0, 0.0), (0.5, 0.0), simulate_ahead_time_s=0.5) is None


@pytest.mark.parametrize("pose", [(-1.8, 1.8, 0.0), (5.0, 0.0, 0.0)], ids=["unknown-cell", "off-the-costmap"])
def test_unknown_and_off_map_cells_and_waiting_never_stop_a_behaviour(pose: tuple[float, float, float]):
    costmap = costmap_with_wall(0.475)
    assert collision_ahead(Spin(), costmap, pose, (0.0, 1.0)) is None
    assert collision_ahead(Spin(), None, (0.48, 0.0, 0.0), (0.0, 1.0)) is None
    assert collision_ahead(Wait(), costmap, (0.48, 0.0, 0.0), (0.0, 0.0)) is None


# ----------------------------------------------------------------------------- assisted teleop
@pytest.mark.parametrize("x, expected", [(-1.5, (0.5, 0.0)), (-0.12, (0.35, 0.0)), (0.16, (0.0, 0.0))],
                         ids=["clear-for-the-projection", "collides-in-0.7-s", "collides-in-one-step"])
def test_assisted_teleop_scales_a_command_by_how_soon_it_would_collide(x: float, expected: tuple[float, float]):
    # The inscribed cells start at x = 0.2: from x = -0.12 at 0.5 m/s the projection reaches them
    # in its 0.7 s step (0.35 m/s); from x = 0.16 in the first step (stop); from x = -1.5 never in 1 s.
    v, w = assisted((0.5, 0.0), (x, 0.0, 0.0), costmap_with_wall(0.475), projection_time_s=1.0,
                    simulation_time_step_s=0.1)
    assert (v, w) == pytest.approx(expected)


def test_assisted_teleop_passes_commands_away_from_obstacles_and_without_a_costmap():
    costmap = costmap_with_wall(0.475)
    assert assisted((-0.5, 0.3), (0.0, 0.0, 0.0), costmap) == (-0.5, 0.3)
    assert assisted((0.5, 0.0), (0.1, 0.0, 0.0), None) == (0.5, 0.0)
