"""Recovery behaviours without ROS: what each commands, when it ends, and when it must stop short."""
from __future__ import annotations

import math

import numpy as np
import pytest

from pppbot_common.maps import OccupancyGrid
from pppbot_nav.behaviors import (
    INSCRIBED_OCCUPANCY,
    BackUp,
    Recovery,
    RecoveryRoundRobin,
    Spin,
    Wait,
    collision_ahead,
)

DT = 0.05


def run(behavior: Spin | BackUp | Wait, pose: tuple[float, float, float], limit_s: float = 30.0
        ) -> tuple[list[tuple[float, float]], tuple[float, float, float], float]:
    """Integrates the commands from ``pose`` until the behaviour ends: the commands, the end pose, time."""
    behavior.start(pose, 0.0)
    x, y, yaw = pose
    commands = []
    t = 0.0
    while t < limit_s:
        command = behavior.step((x, y, yaw), t)
        if command is None:
            break
        commands.append(command)
        v, w = command
        x, y, yaw = x + v * DT * math.cos(yaw), y + v * DT * math.sin(yaw), yaw + w * DT
        t += DT
    return commands, (x, y, yaw), t


@pytest.mark.parametrize("spin_dist", [1.57, -1.57, 3.5])
def test_spin_turns_its_distance_on_the_spot_and_slows_towards_the_end(spin_dist: float):
    commands, (x, y, yaw), _ = run(Spin(spin_dist_rad=spin_dist), (1.0, 2.0, 3.0))
    assert (x, y) == (1.0, 2.0)
    assert yaw - 3.0 == pytest.approx(spin_dist, abs=0.06)  # within a period's turn at the slowest
    speeds = [abs(w) for _, w in commands]
    assert all(np.sign(w) == np.sign(spin_dist) for _, w in commands)
    assert max(speeds) == pytest.approx(1.0) and speeds[-1] < 0.7


def test_spin_gives_up_after_its_time_allowance():
    spin = Spin(spin_dist_rad=1.57, time_allowance_s=2.0)
    spin.start((0.0, 0.0, 0.0), 0.0)
    assert spin.step((0.0, 0.0, 0.0), 1.9) is not None
    assert spin.step((0.0, 0.0, 0.0), 2.1) is None  # the robot is stuck: no turn in 2 s


def test_backup_drives_backwards_its_distance_at_its_speed():
    commands, (x, y, _), t = run(BackUp(backup_dist_m=0.3, backup_speed=0.1), (0.0, 0.0, math.pi / 2))
    assert all(c == (-0.1, 0.0) for c in commands)
    assert x == pytest.approx(0.0, abs=1e-9) and y == pytest.approx(-0.3, abs=0.006)
    assert t == pytest.approx(3.0, abs=0.1)


def test_wait_stands_still_for_its_duration():
    commands, _, t = run(Wait(wait_duration_s=2.0), (0.0, 0.0, 0.0))
    assert set(commands) == {(0.0, 0.0)} and t == pytest.approx(2.0, abs=DT)


def test_round_robin_cycles_in_nav2_order_and_resets():
    robin = RecoveryRoundRobin()
    order = [robin.next() for _ in range(5)]
    assert order == [Recovery.CLEAR_COSTMAPS, Recovery.SPIN, Recovery.WAIT, Recovery.BACKUP, Recovery.CLEAR_COSTMAPS]
    robin.reset()
    assert robin.next() is Recovery.CLEAR_COSTMAPS


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
    reason = collision_ahead(Spin(), costmap_with_wall(0.475), (robot_x, 0.0, 0.0))
    assert (reason is not None) == stops
    if reason is not None:
        assert "collision ahead" in reason and f"({robot_x:.2f}, 0.00)" in reason


@pytest.mark.parametrize("yaw, stops", [(0.0, False), (math.pi, True)], ids=["wall-ahead", "wall-behind"])
def test_backing_up_stops_only_with_the_zone_just_behind(yaw: float, stops: bool):
    # The robot's cell is 0.35 m from the wall (free); the cell 0.1 m behind it, towards the wall
    # when the robot faces away from it, is 0.25 m from it (inscribed).
    reason = collision_ahead(BackUp(), costmap_with_wall(0.475), (0.1, 0.0, yaw))
    assert (reason is not None) == stops
    if reason is not None:
        assert "0.1 m behind the robot" in reason and "inscribed" in reason


@pytest.mark.parametrize("pose", [(-1.8, 1.8, 0.0), (5.0, 0.0, 0.0)], ids=["unknown-cell", "off-the-costmap"])
def test_unknown_and_off_map_cells_and_waiting_never_stop_a_behaviour(pose: tuple[float, float, float]):
    costmap = costmap_with_wall(0.475)
    assert collision_ahead(Spin(), costmap, pose) is None
    assert collision_ahead(Spin(), None, (0.48, 0.0, 0.0)) is None
    assert collision_ahead(Wait(), costmap, (0.48, 0.0, 0.0)) is None
