"""The collision monitor without ROS: zone containment, the actions and their order, approach's
simulated stop short of an obstacle, scans as points, and how long a stop is repeated."""
from __future__ import annotations

import math

import numpy as np
import pytest

from pppbot_nav.collision_monitor import (
    INVALID_SOURCE,
    ActionType,
    CircleShape,
    PolygonShape,
    StopRepeat,
    Velocity,
    Zone,
    decide,
    describe,
    fresh,
    parse_points,
    points_in_polygon,
    scan_points,
    transformed,
)
from pppbot_nav.errors import CollisionMonitorError

SQUARE = np.array([[0.4, 0.3], [0.4, -0.3], [0.0, -0.3], [0.0, 0.3]])
FOOTPRINT = np.array([[0.3, 0.3], [0.3, -0.3], [-0.3, -0.3], [-0.3, 0.3]])
FORWARD = Velocity(0.5, 0.0, 0.4)


def cluster(x: float, y: float, n: int = 5) -> np.ndarray:
    """``n`` points within a centimetre of (x, y)."""
    return np.column_stack([np.full(n, x), y + np.linspace(-0.01, 0.01, n)])


def wall(x: float) -> np.ndarray:
    """A wall across the robot's path at ``x``: 41 points from y = -1 to 1."""
    return np.column_stack([np.full(41, x), np.linspace(-1.0, 1.0, 41)])


def zone(name: str, action: ActionType, shape: object = None, **settings: object) -> Zone:
    return Zone(name, shape or PolygonShape(SQUARE), action, **settings)  # type: ignore[arg-type]


# -------------------------------------------------------------- containment
def test_points_in_a_convex_polygon():
    inside = points_in_polygon(np.array([[0.2, 0.0], [0.5, 0.0], [0.2, 0.31], [-0.01, 0.0], [0.39, -0.29]]), SQUARE)
    assert inside.tolist() == [True, False, False, False, True]


def test_points_in_a_concave_polygon():
    ell = np.array([[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]], dtype=float)  # an L: (1.5, 1.5) is the notch
    inside = points_in_polygon(np.array([[0.5, 0.5], [1.5, 0.5], [0.5, 1.5], [1.5, 1.5]]), ell)
    assert inside.tolist() == [True, True, True, False]
    assert points_in_polygon(np.empty((0, 2)), ell).shape == (0,)


def test_circle_contains_points_within_its_radius():
    assert CircleShape(0.5).contains(np.array([[0.3, 0.3], [0.4, 0.4], [0.0, -0.49]])).tolist() == [True, False, True]


def test_points_are_read_as_jazzy_strings_or_flat_lists():
    from_string = parse_points("[[0.4, 0.3], [0.4, -0.3], [0.0, -0.3], [0.0, 0.3]]")
    from_list = parse_points([0.4, 0.3, 0.4, -0.3, 0.0, -0.3, 0.0, 0.3])
    assert np.array_equal(from_string, SQUARE) and np.array_equal(from_list, SQUARE)


@pytest.mark.parametrize("points, problem", [
    ("[[0.4, 0.3], [0.4]]", "form"), ("0.4, 0.3", "form"), ([0.1, 0.2, 0.3], "odd"),
    ([0.0, 0.0, 1.0, 1.0], "at least 3"), ("[[0, 0], [1, 0], [1, \"a\"]]", "not a number"),
])
def test_malformed_points_are_refused(points, problem):
    with pytest.raises(CollisionMonitorError, match=problem) as caught:
        parse_points(points)
    assert caught.value.parameter == "points"


# --------------------------------------------------------------- the actions
def test_stop_needs_min_points_inside():
    stop = zone("PolygonStop", ActionType.STOP, min_points=4)
    assert decide([stop], FORWARD, {"scan": cluster(0.2, 0.0, n=3)}).action is ActionType.DO_NOTHING
    decision = decide([stop], FORWARD, {"scan": cluster(0.2, 0.0, n=4)})
    assert decision.action is ActionType.STOP and decision.polygon_name == "PolygonStop"
    assert decision.velocity.is_zero()


def test_a_clear_zone_passes_the_command_unchanged():
    decision = decide([zone("PolygonStop", ActionType.STOP)], FORWARD, {"scan": cluster(2.0, 0.0)})
    assert decision.action is ActionType.DO_NOTHING and decision.velocity == FORWARD


def test_slowdown_scales_every_axis_by_the_ratio():
    decision = decide([zone("Slow", ActionType.SLOWDOWN, slowdown_ratio=0.3)], FORWARD, {"scan": cluster(0.2, 0.0)})
    assert decision.action is ActionType.SLOWDOWN
    assert (decision.velocity.x_mps, decision.velocity.yaw_radps) == pytest.approx((0.15, 0.12))


def test_limit_clamps_speed_and_turn_rate_keeping_the_curvature():
    limit = zone("Limit", ActionType.LIMIT, linear_limit_mps=0.4, angular_limit_radps=0.2)
    decision = decide([limit], FORWARD, {"scan": cluster(0.2, 0.0)})
    assert decision.action is ActionType.LIMIT
    # The turn rate is furthest over (0.4 → 0.2): both halved.
    assert (decision.velocity.x_mps, decision.velocity.yaw_radps) == pytest.approx((0.25, 0.2))


def test_a_stop_wins_over_a_slowdown_listed_before_it():
    zones = [zone("Slow", ActionType.SLOWDOWN, PolygonShape(SQUARE * 2)), zone("Stop", ActionType.STOP)]
    decision = decide(zones, FORWARD, {"scan": cluster(0.2, 0.0)})
    assert (decision.action, decision.polygon_name) == (ActionType.STOP, "Stop")


def test_the_slowest_of_the_triggered_zones_is_chosen():
    zones = [zone("Limit", ActionType.LIMIT, linear_limit_mps=0.4, angular_limit_radps=1.0),
             zone("Slow", ActionType.SLOWDOWN, slowdown_ratio=0.5), zone("Slower", ActionType.SLOWDOWN,
                                                                         slowdown_ratio=0.2)]
    decision = decide(zones, FORWARD, {"scan": cluster(0.2, 0.0)})
    assert decision.polygon_name == "Slower" and decision.velocity.x_mps == pytest.approx(0.1)
    decision = decide(zones[:2], FORWARD, {"scan": cluster(0.2, 0.0)})
    assert decision.polygon_name == "Slow"  # 0.25 m/s is slower than the limit's 0.4


def test_disabled_zones_and_other_sources_points_do_not_count():
    off = zone("Stop", ActionType.STOP, enabled=False)
    assert decide([off], FORWARD, {"scan": cluster(0.2, 0.0)}).action is ActionType.DO_NOTHING
    front_only = zone("Stop", ActionType.STOP, sources=("front",))
    assert decide([front_only], FORWARD, {"rear": cluster(0.2, 0.0)}).action is ActionType.DO_NOTHING
    assert decide([front_only], FORWARD, {"front": cluster(0.2, 0.0)}).action is ActionType.STOP


def test_an_invalid_source_stops_the_robot():
    decision = decide([zone("Stop", ActionType.STOP)], FORWARD, {"scan": np.empty((0, 2))}, invalid_sources=["scan"])
    assert (decision.action, decision.polygon_name) == (ActionType.STOP, INVALID_SOURCE)
    assert decision.velocity.is_zero()
    assert "invalid source" in describe(decision, [])


def test_the_log_lines_use_nav2s_words():
    stop = decide([zone("FootprintApproach", ActionType.STOP)], FORWARD, {"scan": cluster(0.2, 0.0)})
    assert describe(stop, []) == "Robot to stop due to FootprintApproach polygon"


# ------------------------------------------------------------------ approach
def approach(**settings: object) -> Zone:
    return zone("FootprintApproach", ActionType.APPROACH, PolygonShape(FOOTPRINT), **settings)


def test_approach_scales_by_the_time_left_before_a_collision():
    footprint = approach(time_before_collision_s=2.0, simulation_time_step_s=0.1)
    straight = Velocity(0.5, 0.0, 0.0)
    # The wall is 0.72 m ahead of the footprint's front: hit in the 15th step (0.75 m), the last free pose at 1.4 s.
    assert footprint.collision_time(wall(1.02), straight) == pytest.approx(1.4)
    decision = decide([footprint], straight, {"scan": wall(1.02)})
    assert decision.action is ActionType.APPROACH
    assert decision.velocity.x_mps == pytest.approx(0.5 * 1.4 / 2.0)
    # Beyond the horizon (2 s at 0.5 m/s: 1 m): no action.
    assert decide([footprint], straight, {"scan": wall(1.5)}).action is ActionType.DO_NOTHING
    # Turning in place never reaches a wall ahead.
    assert footprint.collision_time(wall(0.5), Velocity(0.0, 0.0, 1.0)) is None


def test_approach_stops_the_robot_short_of_a_box():
    """Drive at the wall with the approach's command each step: the robot slows and stops within
    one simulation step's travel of it, and never touches it."""
    footprint = approach(time_before_collision_s=2.0, simulation_time_step_s=0.1)
    command, dt, box_x = Velocity(0.5, 0.0, 0.0), 0.1, 1.5
    x = 0.0
    for _ in range(2000):
        decision = decide([footprint], command, {"scan": wall(box_x - x)})  # the box as the robot sees it
        if decision.velocity.is_zero():
            break
        x += decision.velocity.x_mps * dt
    else:
        pytest.fail(f"the robot never stopped (at x = {x:.3f} m)")
    gap = box_x - (x + 0.3)
    assert 0.0 < gap <= command.x_mps * footprint.simulation_time_step_s + 1e-9


def test_bad_zone_settings_name_the_parameter():
    with pytest.raises(CollisionMonitorError, match="slowdown_ratio") as caught:
        zone("Slow", ActionType.SLOWDOWN, slowdown_ratio=1.5).validate()
    assert caught.value.parameter == "slowdown_ratio"
    with pytest.raises(CollisionMonitorError) as caught:
        zone("Circle", ActionType.STOP, CircleShape(0.0)).validate()
    assert caught.value.parameter == "radius"
    with pytest.raises(CollisionMonitorError) as caught:
        approach(simulation_time_step_s=0.0).validate()
    assert caught.value.parameter == "simulation_time_step"


# ------------------------------------------------------------------- sources
def test_scan_returns_within_range_become_points():
    points = scan_points([1.0, math.inf, 0.05, math.nan, 2.0], -math.pi / 2, math.pi / 4, 0.1, 10.0)
    assert points == pytest.approx(np.array([[0.0, -1.0], [0.0, 2.0]]), abs=1e-12)  # at -90° and +90°
    moved = transformed(points, (0.1, 0.0, math.pi / 2))  # a sensor 0.1 m ahead, facing left
    assert moved == pytest.approx(np.array([[1.1, 0.0], [-1.9, 0.0]]), abs=1e-12)


def test_data_older_than_the_timeout_is_stale_unless_the_timeout_is_zero():
    assert fresh(10.0, 10.9, 1.0) and not fresh(10.0, 11.1, 1.0) and fresh(10.0, 99.0, 0.0)


def test_a_stop_is_repeated_for_stop_pub_timeout_then_no_longer():
    repeat = StopRepeat(2.0)
    assert repeat.allow(Velocity(0.2), 0.0)
    assert repeat.allow(Velocity(), 1.0) and repeat.allow(Velocity(), 3.0)
    assert not repeat.allow(Velocity(), 3.1)
    assert repeat.allow(Velocity(0.1), 4.0) and repeat.allow(Velocity(), 5.0)  # moving again: a new stop counts


def _collision_time_pose_by_pose(zone: Zone, points: np.ndarray, command: Velocity) -> float | None:
    """Nav2's approach check as written down: every point, one simulated pose after the other."""
    if zone.shape.contains(points).sum() >= zone.min_points:
        return 0.0
    x = y = yaw = 0.0
    step = zone.simulation_time_step_s
    for k in range(int(math.floor(zone.time_before_collision_s / step + 1e-9)) + 1):
        x += (command.x_mps * math.cos(yaw) - command.y_mps * math.sin(yaw)) * step
        y += (command.x_mps * math.sin(yaw) + command.y_mps * math.cos(yaw)) * step
        yaw += command.yaw_radps * step
        c, s = math.cos(yaw), math.sin(yaw)
        dx, dy = points[:, 0] - x, points[:, 1] - y
        if zone.shape.contains(np.column_stack([c * dx + s * dy, -s * dx + c * dy])).sum() >= zone.min_points:
            return k * step
    return None


@pytest.mark.parametrize("shape", [PolygonShape(FOOTPRINT), PolygonShape(SQUARE), CircleShape(0.35)])
def test_approach_tests_only_reachable_points_and_answers_as_pose_by_pose(shape: PolygonShape | CircleShape) -> None:
    """The approach check skips points the moved footprint cannot reach and tests every pose at
    once: on random scans and commands it answers exactly as the pose-by-pose check."""
    rng = np.random.default_rng(52)
    zone = Zone("approach", shape, ActionType.APPROACH, min_points=3, time_before_collision_s=1.5,
                simulation_time_step_s=0.1)
    met = set()
    for _ in range(300):
        points = rng.uniform(-3.0, 3.0, size=(int(rng.integers(0, 400)), 2))
        command = Velocity(float(rng.uniform(-0.5, 1.0)), float(rng.uniform(-0.2, 0.2)), float(rng.uniform(-1.5, 1.5)))
        expected = _collision_time_pose_by_pose(zone, points, command)
        assert zone.collision_time(points, command) == expected
        assert zone.triggered(points) == (zone.shape.contains(points).sum() >= zone.min_points)
        met.add("free" if expected is None else "hit later" if expected > 0 else "hit now")
    assert met == {"free", "hit later", "hit now"}
