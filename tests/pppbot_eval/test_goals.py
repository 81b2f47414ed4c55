"""Random navigation goals, and each goal's outcome judged on ground truth."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

from pppbot_common.maps import FREE, OCCUPIED, OccupancyGrid
from pppbot_eval.errors import GoalSamplingError
from pppbot_eval.goals import reachable_region, sample_goals
from pppbot_eval.map_quality import cells_of
from pppbot_eval.scenarios import (
    BARN_ARRIVAL_M,
    GOAL_XY_TOLERANCE_M,
    GoalAnswer,
    GoalRecord,
    Recording,
    goal_outcome,
    navigation_metrics,
    shortest_path_m,
    turning_in_place_s,
)
from pppbot_eval.trajectory import PoseSeries

RES = 0.05


def two_rooms_and_a_closet() -> OccupancyGrid:
    """8 × 4 m walled; a wall at x = 4 m with a 1 m door (y 1.5…2.5 m); a closed 1 × 1 m closet in
    the east room's corner (x, y 6.5…7.5 m, 2.5…3.5 m), free inside."""
    data = np.full((80, 160), FREE, dtype=np.int8)
    data[[0, -1], :] = OCCUPIED
    data[:, [0, -1]] = OCCUPIED
    data[:30, 80:82] = OCCUPIED
    data[50:, 80:82] = OCCUPIED
    data[50:72, [130, 151]] = OCCUPIED
    data[[50, 71], 130:152] = OCCUPIED
    return OccupancyGrid(data, RES)


def test_goals_are_reachable_clear_of_walls_and_chained_apart():
    grid = two_rooms_and_a_closet()
    goals = sample_goals(grid, (1.0, 1.0), 40, np.random.default_rng(3), robot_radius_m=0.3, clearance_m=0.45,
                         min_distance_m=2.0)
    assert len(goals) == 40
    xy = np.array([g[:2] for g in goals])
    region = reachable_region(grid, (1.0, 1.0), 0.3)
    rows, cols = cells_of(grid, xy)
    assert region[rows, cols].all()
    # Nothing in the closet, although it is free and roomy: it cannot be reached.
    assert not ((xy[:, 0] > 6.5) & (xy[:, 0] < 7.6) & (xy[:, 1] > 2.5) & (xy[:, 1] < 3.6)).any()
    walls = ndimage.distance_transform_edt(grid.data != OCCUPIED, sampling=RES)
    assert (walls[rows, cols] - RES / 2 > 0.45 - 1e-9).all()  # to the nearest wall cell's edge
    steps = np.linalg.norm(np.diff(np.vstack([[1.0, 1.0], xy]), axis=0), axis=1)
    assert (steps >= 2.0).all()
    # Both rooms get goals; headings cover the circle.
    assert (xy[:, 0] < 4.0).any() and (xy[:, 0] > 4.1).any()
    yaws = np.array([g[2] for g in goals])
    assert (np.abs(yaws) <= math.pi).all() and yaws.min() < -2.0 and yaws.max() > 2.0


def test_the_same_seed_gives_the_same_goals():
    grid = two_rooms_and_a_closet()
    first = sample_goals(grid, (1.0, 1.0), 5, np.random.default_rng(7))
    assert first == sample_goals(grid, (1.0, 1.0), 5, np.random.default_rng(7))
    assert first != sample_goals(grid, (1.0, 1.0), 5, np.random.default_rng(8))


@pytest.mark.parametrize("start, kwargs, message", [
    ((4.05, 0.5), {}, r"start \(4.05, 0.5\) m is not in free space for a robot of radius 0.3 m"),
    ((1.0, 1.0), {"min_distance_m": 50.0}, "no goal candidate is 50.0 m from"),
    ((1.0, 1.0), {"clearance_m": 3.0}, "has 3.0 m of clearance"),
    ((1.0, 1.0), {"count": -1}, "count must be a non-negative number of goals, not -1"),
    ((1.0, 1.0), {"robot_radius_m": float("nan")}, "robot_radius_m must be a non-negative number, not nan"),
])
def test_impossible_requests_name_the_problem(start, kwargs, message):
    args = {"count": 3, **kwargs}
    with pytest.raises(GoalSamplingError, match=message):
        sample_goals(two_rooms_and_a_closet(), start, args.pop("count"), np.random.default_rng(0), **args)


# --- outcomes -------------------------------------------------------------------------------------

def straight_drive(t0: float, t1: float, start: tuple[float, float, float], end: tuple[float, float, float],
                   n: int = 50) -> list[tuple[float, float, float, float]]:
    t = np.linspace(t0, t1, n)
    f = (t - t0) / (t1 - t0)
    return [(float(ti), start[0] + fi * (end[0] - start[0]), start[1] + fi * (end[1] - start[1]),
             start[2] + fi * (end[2] - start[2])) for ti, fi in zip(t, f, strict=True)]


def test_a_goal_counts_when_the_navigator_succeeds_and_the_truth_is_there():
    grid = two_rooms_and_a_closet()
    truth = PoseSeries.from_rows(straight_drive(10.0, 20.0, (1.0, 1.0, 0.0), (3.0, 1.0, 0.1)))
    shortest = shortest_path_m(grid, (1.0, 1.0), (3.1, 1.0))
    assert shortest == pytest.approx(2.1, abs=0.01)
    record = GoalRecord((3.1, 1.0, 0.0), 10.0, 20.0, GoalAnswer.SUCCEEDED, shortest_path_m=shortest)
    outcome = goal_outcome(record, truth, grid, collisions=[(15.0, 2.0, 1.0), (25.0, 0.0, 0.0)])
    assert outcome.reached and outcome.time_s == 10.0
    assert outcome.position_error_m == pytest.approx(0.1) and outcome.yaw_error_rad == pytest.approx(0.1)
    assert outcome.path_length_m == pytest.approx(2.0)
    assert outcome.collisions == 1  # the one during this goal
    assert outcome.min_clearance_m == pytest.approx(1.0 - 0.05 - 0.195, abs=0.03)  # south wall, wheel's side
    # The navigator said so, but the robot is not there: not reached.
    off = GoalRecord((3.0 + GOAL_XY_TOLERANCE_M + 0.05, 1.0, 0.0), 10.0, 20.0, GoalAnswer.SUCCEEDED)
    assert not goal_outcome(off, truth, grid, []).reached
    # There, but the navigator gave up: not reached.
    assert not goal_outcome(GoalRecord((3.0, 1.0, 0.1), 10.0, 20.0, GoalAnswer.ABORTED), truth, grid, []).reached


def test_without_a_map_a_goal_counts_within_a_metre_in_time_and_untouched_as_barn_judges():
    grid = two_rooms_and_a_closet()
    truth = PoseSeries.from_rows(straight_drive(10.0, 20.0, (1.0, 1.0, 0.0), (3.0, 1.0, 0.0), n=101))
    # 1.5 m past the end of the drive: within 1 m from x = 2.5 m on, at t = 17.5 s; the navigator aborted.
    record = GoalRecord((3.5, 1.0, 0.0), 10.0, 20.0, GoalAnswer.ABORTED, shortest_path_m=2.5)
    outcome = goal_outcome(record, truth, grid, [], arrival_m=BARN_ARRIVAL_M)
    assert outcome.reached and outcome.time_s == pytest.approx(7.5)
    assert outcome.path_length_m == pytest.approx(1.5) and outcome.position_error_m == pytest.approx(1.0)
    # A collision before arriving fails it; one after does not count against it.
    assert not goal_outcome(record, truth, grid, [(12.0, 1.2, 1.0)], arrival_m=BARN_ARRIVAL_M).reached
    assert goal_outcome(record, truth, grid, [(19.0, 3.0, 1.0)], arrival_m=BARN_ARRIVAL_M).reached
    # Arrived after its time limit (7.5 s in, 7 s given): not reached; within it, reached even though the
    # navigator, still turning to the goal's heading, timed out. Without a limit known: the answer says.
    late = GoalRecord((3.5, 1.0, 0.0), 10.0, 20.0, GoalAnswer.ABORTED, shortest_path_m=2.5, limit_s=7.0)
    assert not goal_outcome(late, truth, grid, [], arrival_m=BARN_ARRIVAL_M).reached
    canceled = GoalRecord((3.5, 1.0, 0.0), 10.0, 20.0, GoalAnswer.TIMEOUT, shortest_path_m=2.5, limit_s=8.0)
    assert goal_outcome(canceled, truth, grid, [], arrival_m=BARN_ARRIVAL_M).reached
    unknown = GoalRecord((3.5, 1.0, 0.0), 10.0, 20.0, GoalAnswer.TIMEOUT, shortest_path_m=2.5)
    assert not goal_outcome(unknown, truth, grid, [], arrival_m=BARN_ARRIVAL_M).reached
    far = GoalRecord((4.2, 1.0, 0.0), 10.0, 20.0, GoalAnswer.SUCCEEDED, shortest_path_m=3.2)
    assert not goal_outcome(far, truth, grid, [], arrival_m=BARN_ARRIVAL_M).reached


def test_navigation_metrics_summarize_the_goals_and_plot_them(tmp_path: Path):
    grid = two_rooms_and_a_closet()
    rows = straight_drive(0.0, 10.0, (1.0, 1.0, 0.0), (3.0, 1.0, 0.0)) + \
        straight_drive(10.5, 30.0, (3.0, 1.0, 0.0), (3.0, 3.0, 1.5))[1:]
    recording = Recording(truth_rows=rows, start_sim_s=0.0, end_sim_s=30.0)
    recording.edge_rows = {("map", "odom"): [(0.0, 0.0, 0.0, 0.0), (30.0, 0.0, 0.0, 0.0)],
                           ("odom", "base_link"): [(t, x + 0.02, y, yaw) for t, x, y, yaw in rows]}
    recording.goals = [GoalRecord((3.0, 1.0, 0.0), 0.0, 10.0, GoalAnswer.SUCCEEDED, shortest_path_m=2.0),
                       GoalRecord((3.0, 3.0, 1.5), 10.0, 30.0, GoalAnswer.SUCCEEDED, shortest_path_m=2.0),
                       GoalRecord((7.0, 3.0, 0.0), 30.0, 30.0, GoalAnswer.ABORTED, 208, "no path", 6, None)]
    metrics = navigation_metrics(recording, grid, (0.0, 0.0, 0.0), 0.5, tmp_path, "test")
    assert metrics["goals"] == 3 and metrics["successes"] == 2 and metrics["success_rate"] == pytest.approx(2 / 3)
    assert metrics["mean_time_ratio"] == pytest.approx((10 / 4 + 20 / 4) / 2)
    assert metrics["total_time_ratio"] == pytest.approx(30 / 8)
    assert metrics["recoveries"] == 6 and metrics["collisions"] == 0
    # The second goal turned while it drove (not on the spot): no time taken off.
    assert metrics["turning_in_place_s"] == 0.0 and metrics["total_time_ratio_without_turning"] == pytest.approx(30 / 8)
    assert metrics["ate_rms_m"] == pytest.approx(0.02, abs=1e-6)
    results = metrics["goal_results"]
    assert [r["status"] for r in results] == ["succeeded", "succeeded", "aborted"]
    assert results[2] == {**results[2], "reached": False, "error_code": 208, "shortest_path_m": None}
    assert (tmp_path / "trajectory.png").stat().st_size > 10_000


def test_turning_in_place_is_timed_apart_from_standing_and_driving():
    rows = [(t, 0.0, 0.0, 0.0) for t in np.arange(0.0, 1.0, 0.1)]                    # standing
    rows += [(1.0 + t, 0.0, 0.0, t) for t in np.arange(0.0, 2.0, 0.1)]              # 1 rad/s on the spot
    rows += [(3.0 + t, 0.5 * t, 0.0, 2.0) for t in np.arange(0.0, 2.01, 0.1)]       # 0.5 m/s
    assert turning_in_place_s(PoseSeries.from_rows(rows)) == pytest.approx(2.0, abs=0.11)
    assert turning_in_place_s(PoseSeries.from_rows(rows[:1])) == 0.0
