"""Navigation metrics: footprint clearance on the truth grid, goal checks and the summary."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from pppbot_common.maps import FREE, OCCUPIED, OccupancyGrid
from pppbot_eval.navigation import (
    PPP_BOT_FOOTPRINT,
    Footprint,
    GoalOutcome,
    NavigationMetricError,
    barn_score,
    clearance_along,
    goal_reached,
    summarize_navigation,
)
from pppbot_eval.trajectory import PoseSeries

RES = 0.05


def wall_at_2_5m() -> OccupancyGrid:
    """3 m × 3 m at 5 cm; occupied for x >= 2.5 m."""
    data = np.full((60, 60), FREE, dtype=np.int8)
    data[:, 50:] = OCCUPIED
    return OccupancyGrid(data, RES)


def poses(*rows: tuple[float, float, float]) -> PoseSeries:
    return PoseSeries.from_rows([(float(i), *row) for i, row in enumerate(rows)])


def test_rectangle_perimeter_points_are_evenly_spaced_on_the_outline():
    points = Footprint.rectangle(0.0, 0.3, 0.0, 0.1).perimeter_points(spacing_m=0.05)
    assert points.shape == (16, 2)  # 6 + 2 + 6 + 2 steps
    assert np.allclose(np.linalg.norm(np.diff(np.vstack([points, points[:1]]), axis=0), axis=1), 0.05)
    on_edge = np.isclose(points[:, 0], 0.0) | np.isclose(points[:, 0], 0.3) \
        | np.isclose(points[:, 1], 0.0) | np.isclose(points[:, 1], 0.1)
    assert on_edge.all()


def test_circle_perimeter_is_on_the_circle():
    points = Footprint.circle(0.2).perimeter_points(spacing_m=0.01)
    assert np.allclose(np.linalg.norm(points, axis=1), 0.2, atol=1e-5)


def test_ppp_bot_footprint_is_its_chassis_and_wheels():
    vertices = PPP_BOT_FOOTPRINT.vertices_xy
    assert vertices.min(axis=0) == pytest.approx([-0.1, -0.195])
    assert vertices.max(axis=0) == pytest.approx([0.2, 0.195])
    # The wheels stick out of the chassis' sides between x = -0.05 and 0.05 only.
    corners = {(round(x, 3), round(y, 3)) for x, y in vertices}
    assert {(0.05, 0.195), (-0.05, -0.195), (0.2, 0.15), (-0.1, -0.15)} <= corners
    assert (0.2, 0.195) not in corners


@pytest.mark.parametrize("make", [lambda: Footprint.circle(0.0), lambda: Footprint.rectangle(0.2, 0.1, 0.0, 1.0),
                                  lambda: Footprint(np.zeros((2, 2)))])
def test_bad_footprints_are_refused(make):
    with pytest.raises(NavigationMetricError):
        make()


def test_clearance_of_a_circle_one_metre_from_a_wall():
    clearance = clearance_along(poses((1.5, 1.5, 0.0)), wall_at_2_5m(), Footprint.circle(0.2))
    assert clearance[0] == pytest.approx(0.8, abs=RES / 2)


def test_clearance_of_the_chassis_depends_on_heading():
    truth = wall_at_2_5m()
    clearance = clearance_along(poses((2.0, 1.5, 0.0), (2.0, 1.5, math.pi), (2.0, 1.5, math.pi / 2)), truth,
                                PPP_BOT_FOOTPRINT)
    # Facing the wall: the chassis front; away: its back; sideways: a wheel (0.195 m out).
    assert clearance == pytest.approx([0.3, 0.4, 0.305], abs=RES / 2)


def test_overlapping_a_wall_is_zero_clearance():
    truth = wall_at_2_5m()
    clearance = clearance_along(poses((2.45, 1.5, 0.0), (2.8, 1.5, 0.0)), truth, Footprint.circle(0.2))
    assert clearance.tolist() == [0.0, 0.0]


def test_clearance_without_walls_is_infinite():
    truth = OccupancyGrid(np.zeros((10, 10), dtype=np.int8), RES)
    assert clearance_along(poses((0.2, 0.2, 0.0)), truth, Footprint.circle(0.1)).tolist() == [math.inf]


@pytest.mark.parametrize(("final", "reached"), [
    ((1.2, 0.0, 0.2), True),
    ((1.0, 0.25, 0.0), True),  # tolerances are inclusive
    ((1.0, 0.26, 0.0), False),
    ((1.0, 0.0, 0.3), False),
])
def test_goal_reached_tolerances(final, reached):
    assert goal_reached(final, (1.0, 0.0, 0.0)) is reached


def test_goal_reached_wraps_yaw():
    assert goal_reached((0.0, 0.0, -math.pi + 0.1), (0.0, 0.0, math.pi))
    assert not goal_reached((0.0, 0.0, 0.0), (0.0, 0.0, 0.5), yaw_tolerance_rad=0.4)


def outcome(reached: bool, time_s: float, driven_m: float, shortest_m: float | None, error_m: float,
            collisions: int = 0, clearance_m: float = 0.3) -> GoalOutcome:
    return GoalOutcome(goal=(1.0, 2.0, 0.0), reached=reached, final_pose=(1.0, 2.0 + error_m, 0.0),
                       position_error_m=error_m, yaw_error_rad=0.0, time_s=time_s, path_length_m=driven_m,
                       shortest_path_m=shortest_m, collisions=collisions, min_clearance_m=clearance_m)


def test_summary_of_mixed_outcomes():
    outcomes = [
        outcome(True, time_s=20.0, driven_m=6.0, shortest_m=5.0, error_m=0.1),
        outcome(True, time_s=10.0, driven_m=2.0, shortest_m=2.0, error_m=0.2, clearance_m=0.05),
        outcome(False, time_s=60.0, driven_m=1.0, shortest_m=None, error_m=3.0, collisions=2),
    ]
    summary = summarize_navigation(outcomes, max_speed_mps=0.5)
    assert summary["goals"] == 3 and summary["successes"] == 2 and summary["collisions"] == 2
    assert summary["success_rate"] == pytest.approx(2 / 3)
    assert summary["mean_time_s"] == pytest.approx(15.0)
    assert summary["mean_path_ratio"] == pytest.approx((6 / 5 + 1.0) / 2)
    assert summary["mean_time_ratio"] == pytest.approx((20 / 10 + 10 / 4) / 2)
    assert summary["min_clearance_m"] == pytest.approx(0.05)
    assert summary["mean_position_error_m"] == pytest.approx(3.3 / 3)
    json.dumps(summary, allow_nan=False)


def test_barn_score_is_optimal_time_over_the_clipped_actual_time():
    # OT = 5 m / 0.5 m/s = 10 s: faster than 2·OT scores 0.5, between 2·OT and 8·OT it falls as OT/AT,
    # beyond 8·OT it stays at 1/8; a failure, a collision or no shortest path scores 0.
    assert barn_score(outcome(True, 12.0, 5.0, 5.0, 0.1), 0.5) == pytest.approx(0.5)
    assert barn_score(outcome(True, 40.0, 5.0, 5.0, 0.1), 0.5) == pytest.approx(10 / 40)
    assert barn_score(outcome(True, 200.0, 5.0, 5.0, 0.1), 0.5) == pytest.approx(1 / 8)
    assert barn_score(outcome(False, 40.0, 5.0, 5.0, 0.1), 0.5) == 0.0
    assert barn_score(outcome(True, 40.0, 5.0, 5.0, 0.1, collisions=1), 0.5) == 0.0
    assert barn_score(outcome(True, 40.0, 5.0, None, 0.1), 0.5) == 0.0
    summary = summarize_navigation([outcome(True, 40.0, 5.0, 5.0, 0.1), outcome(False, 9.0, 1.0, 5.0, 3.0)], 0.5)
    assert summary["barn_score"] == pytest.approx((0.25 + 0.0) / 2)


def test_summary_without_successes_or_goals_is_json_safe():
    failed = summarize_navigation([outcome(False, 60.0, 1.0, None, 2.0)], max_speed_mps=0.5)
    assert failed["success_rate"] == 0.0
    assert failed["mean_time_s"] is None and failed["mean_path_ratio"] is None and failed["mean_time_ratio"] is None
    nothing = summarize_navigation([], max_speed_mps=0.5)
    assert nothing["goals"] == 0 and nothing["success_rate"] is None and nothing["min_clearance_m"] is None
    json.dumps(failed, allow_nan=False)
    json.dumps(nothing, allow_nan=False)


def test_summary_needs_a_positive_speed():
    with pytest.raises(NavigationMetricError, match="max_speed_mps"):
        summarize_navigation([], max_speed_mps=0.0)
