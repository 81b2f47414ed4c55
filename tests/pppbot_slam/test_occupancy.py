"""Log-odds occupancy grid from scans at poses (synthetic, seeded, no ROS)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from pppbot_common.maps import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from pppbot_common.se2 import se2_compose
from pppbot_slam.occupancy import (
    BLOCK_CELLS,
    GridCache,
    LogOddsGrid,
    OccupancyError,
    OccupancySettings,
    ScanRays,
)

RES = 0.05
WALL = 2.025  # walls of a square room at x, y = ±WALL: mid-cell, cells 40 and -41
RING = (-41, 40)  # world cell indices of the walls
ONE_MISS_FREE = OccupancySettings(miss_probability=0.2)  # one free observation reads free


def full_circle(beams: int) -> tuple[float, float]:
    return -math.pi, 2.0 * math.pi / beams


def room_ranges(pose, angle_min, increment, beams, half=WALL):
    """Exact ranges (m) from ``pose`` to the walls of the square room, for beams in the sensor frame."""
    a = pose[2] + angle_min + increment * np.arange(beams)
    dx, dy = np.cos(a), np.sin(a)
    with np.errstate(divide="ignore"):
        tx = np.where(dx == 0, math.inf, np.where(dx > 0, half - pose[0], -half - pose[0]) / dx)
        ty = np.where(dy == 0, math.inf, np.where(dy > 0, half - pose[1], -half - pose[1]) / dy)
    return np.minimum(tx, ty)


def room_scan(pose, beams=360, angle_min=None, increment=None):
    if angle_min is None or increment is None:
        angle_min, increment = full_circle(beams)
    return ScanRays.from_laser(angle_min, increment, room_ranges(pose, angle_min, increment, beams), 0.05, 10.0)


def world_cells(grid: OccupancyGrid, value: int) -> set[tuple[int, int]]:
    """World lattice indices (ix, iy) of cells holding ``value``."""
    rows, cols = np.nonzero(grid.data == value)
    ox, oy = round(grid.origin[0] / grid.resolution), round(grid.origin[1] / grid.resolution)
    return {(int(c) + ox, int(r) + oy) for r, c in zip(rows, cols, strict=True)}


def value_at(grid: OccupancyGrid, x, y) -> np.ndarray:
    row, col = grid.cell_of(np.asarray(x), np.asarray(y))
    return grid.data[row, col]


def on_ring(ix, iy) -> bool:
    return (ix in RING and RING[0] <= iy <= RING[1]) or (iy in RING and RING[0] <= ix <= RING[1])


def test_one_scan_marks_hit_walls_occupied_free_space_free_and_behind_unknown():
    grid = LogOddsGrid(ONE_MISS_FREE)
    pose = (0.0, 0.0, 0.0)
    scan = room_scan(pose)
    grid.add_scan(pose, scan)
    out = grid.to_occupancy_grid()
    hits = scan.directions * scan.ranges_m[:, None]
    assert np.all(value_at(out, hits[:, 0], hits[:, 1]) == OCCUPIED)
    cells = {(ix, iy): v for v in (FREE, OCCUPIED, UNKNOWN) for ix, iy in world_cells(out, v)}
    inside = [(ix, iy) for ix in range(-40, 40) for iy in range(-40, 40)]
    assert all(cells[c] == FREE for c in inside)
    behind = [c for c, v in cells.items() if c[0] > 40 or c[0] < -41 or c[1] > 40 or c[1] < -41]
    assert behind and all(cells[c] == UNKNOWN for c in behind)
    assert all(on_ring(*c) for c, v in cells.items() if v == OCCUPIED)


def test_defaults_need_three_free_observations_and_one_hit():
    grid = LogOddsGrid(OccupancySettings())
    pose = (0.3, -0.2, 0.0)
    for expected in (UNKNOWN, UNKNOWN, FREE):  # 1, 2, 3 misses: p = 0.4, 0.31, 0.23; free below 0.25
        grid.add_scan(pose, room_scan(pose))
        assert value_at(grid.to_occupancy_grid(), 0.5, 0.5) == expected
    assert value_at(grid.to_occupancy_grid(), WALL, -0.2) == OCCUPIED


def test_five_scans_put_every_occupied_cell_on_the_walls():
    poses = [(0.0, 0.0, 0.0), (0.7, 0.4, 0.3), (-0.8, 0.6, -1.0), (0.5, -0.9, 2.0), (-0.6, -0.5, 3.0)]
    grid = LogOddsGrid(OccupancySettings())
    for pose in poses:
        grid.add_scan(pose, room_scan(pose))
    occupied = world_cells(grid.to_occupancy_grid(), OCCUPIED)
    near_wall = {(ix + dx, iy + dy) for ix in range(-42, 42) for iy in range(-42, 42) if on_ring(ix, iy)
                 for dx in (-1, 0, 1) for dy in (-1, 0, 1)}
    assert occupied and occupied <= near_wall
    perimeter = {(ix, iy) for ix in range(-41, 41) for iy in range(-41, 41) if on_ring(ix, iy)}
    assert len(perimeter & occupied) > 0.9 * len(perimeter)


@pytest.mark.parametrize("range_max_m, max_range_m", [(3.0, 20.0), (10.0, 2.5)])
@pytest.mark.parametrize("no_return", [math.inf, 50.0])
def test_beams_without_a_return_clear_up_to_the_range_limit(range_max_m, max_range_m, no_return):
    settings = OccupancySettings(miss_probability=0.2, max_range_m=max_range_m)
    limit_m = min(range_max_m, max_range_m)
    grid = LogOddsGrid(settings)
    grid.add_scan((0.01, 0.02, 0.0), ScanRays.from_laser(*full_circle(720), np.full(720, no_return), 0.1, range_max_m))
    out = grid.to_occupancy_grid()
    assert not np.any(out.data == OCCUPIED)
    x, y = out.cell_centers()
    distance = np.hypot(x - 0.01, y - 0.02)
    assert np.all(out.data[distance < limit_m - RES] == FREE)
    assert np.all(out.data[distance > limit_m + RES] == UNKNOWN)


def test_negative_infinity_nan_and_too_short_beams_change_nothing():
    pose = (0.2, 0.1, 0.4)
    angle_min, increment = full_circle(360)
    ranges = room_ranges(pose, angle_min, increment, 360)
    bad = np.random.default_rng(3).choice(360, 60, replace=False)
    ranges_with_bad = ranges.copy()
    ranges_with_bad[bad[:20]], ranges_with_bad[bad[20:40]], ranges_with_bad[bad[40:]] = -math.inf, math.nan, 0.01
    with_bad, without = LogOddsGrid(), LogOddsGrid()
    with_bad.add_scan(pose, ScanRays.from_laser(angle_min, increment, ranges_with_bad, 0.05, 10.0))
    keep = np.setdiff1d(np.arange(360), bad)
    directions = ScanRays.from_laser(angle_min, increment, ranges, 0.05, 10.0).directions[keep]
    without.add_scan(pose, ScanRays(directions, ranges[keep], 0.05, 10.0))
    np.testing.assert_array_equal(with_bad.log_odds(), without.log_odds())
    nothing = LogOddsGrid()
    nothing.add_scan(pose, ScanRays.from_laser(0.0, 0.1, [-math.inf, math.nan, 0.01], 0.05, 10.0))
    assert nothing.scan_count == 1 and not nothing.observed.any()
    assert np.all(nothing.to_occupancy_grid().data == UNKNOWN)


def test_classify_follows_rep_117():
    scan = ScanRays.from_laser(0.0, 0.1, [1.0, 4.0, 5.0, math.inf, -math.inf, math.nan, 0.05, 0.1], 0.1, 5.0)
    used, hit, length_m = scan.classify(max_range_m=4.5)
    np.testing.assert_array_equal(used, [1, 1, 1, 1, 0, 0, 0, 1])
    np.testing.assert_array_equal(hit, [1, 1, 0, 0, 0, 0, 0, 1])
    np.testing.assert_allclose(length_m, [1.0, 4.0, 4.5, 4.5, 0.0, 0.0, 0.0, 0.1])


def test_a_hit_beyond_max_range_is_not_drawn():
    grid = LogOddsGrid(OccupancySettings(miss_probability=0.2, max_range_m=1.93))
    grid.add_scan((0.0, 0.0, 0.0), room_scan((0.0, 0.0, 0.0)))  # walls at 2.025 m and beyond
    out = grid.to_occupancy_grid()
    assert not np.any(out.data == OCCUPIED)
    assert value_at(out, 1.91, 0.01) == FREE and value_at(out, 0.01, -1.91) == FREE  # cells 38, -39
    assert value_at(out, 1.975, 0.01) == UNKNOWN and value_at(out, WALL, 0.01) == UNKNOWN


def one_beam(range_m: float) -> ScanRays:
    return ScanRays(np.array([[1.0, 0.0]]), np.array([range_m]), 0.1, 2.0)


SENSOR = (0.025, 0.025, 0.0)  # centre of cell (0, 0); a 1 m beam ends in the centre of cell (20, 0)


def test_repeated_scans_saturate_at_the_clamp():
    grid = LogOddsGrid(OccupancySettings(clamp_log_odds=3.0))
    for _ in range(12):
        grid.add_scan(SENSOR, one_beam(1.0))
    log_odds = grid.log_odds()
    row, col = grid.to_occupancy_grid().cell_of(np.array([1.025, 0.5]), np.array([0.025, 0.025]))
    assert log_odds[row[0], col[0]] == pytest.approx(3.0)
    assert log_odds[row[1], col[1]] == pytest.approx(-3.0)
    assert np.all(np.abs(log_odds) <= 3.0)


def test_a_free_cell_flips_to_occupied_after_the_computed_number_of_hits():
    settings = OccupancySettings()
    grid = LogOddsGrid(settings)
    for _ in range(20):  # 20 misses: clamped at -5
        grid.add_scan(SENSOR, one_beam(math.inf))
    hit, clamp = math.log(0.7 / 0.3), settings.clamp_log_odds
    needed = math.floor((math.log(0.65 / 0.35) + clamp) / hit) + 1  # first k with -5 + k·hit > logit(0.65)
    assert needed == 7
    for k in range(1, needed + 1):
        grid.add_scan(SENSOR, one_beam(1.0))
        out = grid.to_occupancy_grid()
        log_odds = -clamp + k * hit
        expected = (OCCUPIED if log_odds > math.log(0.65 / 0.35)
                    else FREE if log_odds < math.log(0.25 / 0.75) else UNKNOWN)
        assert (expected == OCCUPIED) == (k == needed)
        assert value_at(out, 1.025, 0.025) == expected
        assert grid.probabilities()[out.cell_of(1.025, 0.025)] == pytest.approx(
            1.0 / (1.0 + math.exp(clamp - k * hit)), rel=1e-5)


@pytest.mark.parametrize("far", [(30.0, 0.0), (-30.0, 0.0), (0.0, 25.0), (0.0, -25.0), (-20.0, -35.0)])
def test_growth_keeps_content_at_its_world_coordinates(far):
    grid = LogOddsGrid(ONE_MISS_FREE)
    grid.add_scan((0.1, 0.2, 0.3), room_scan((0.1, 0.2, 0.3)))
    before = grid.to_occupancy_grid()
    far_pose = (far[0] + 0.1, far[1] + 0.2, 1.0)
    grid.add_scan(far_pose, ScanRays.from_laser(*full_circle(360), np.full(360, 1.5), 0.05, 10.0))
    after = grid.to_occupancy_grid()
    assert after.height * after.width > before.height * before.width
    x0, y0, x1, y1 = grid.bounds_m
    assert x0 <= far_pose[0] - 1.5 and x1 >= far_pose[0] + 1.5 and y0 <= far_pose[1] - 1.5 and y1 >= far_pose[1] + 1.5
    for value in (OCCUPIED, FREE):
        assert world_cells(before, value) <= world_cells(after, value)
    assert len(world_cells(after, OCCUPIED)) > len(world_cells(before, OCCUPIED))
    for origin in (before.origin, after.origin):
        assert origin[0] / (RES * BLOCK_CELLS) == pytest.approx(round(origin[0] / (RES * BLOCK_CELLS)))
        assert origin[1] / (RES * BLOCK_CELLS) == pytest.approx(round(origin[1] / (RES * BLOCK_CELLS)))


def test_build_equals_incremental_integration_in_any_order():
    rng = np.random.default_rng(7)
    poses = np.array([[0.0, 0.0, 0.0], [-12.3, 4.1, 1.0], [7.7, -9.2, -2.0], [-3.3, -15.4, 2.5], [0.4, 0.3, 0.2]])
    scans = [ScanRays.from_laser(-2.0, 4.0 / 399, rng.uniform(0.5, 6.0, 400), 0.1, 8.0) for _ in poses]
    built = LogOddsGrid.build(OccupancySettings(), poses, scans)
    assert built.scan_count == len(scans)
    for order in ([0, 1, 2, 3, 4], [4, 3, 2, 1, 0], list(rng.permutation(5))):
        grid = LogOddsGrid(OccupancySettings())
        for k in order:
            grid.add_scan(poses[k], scans[k])
        a, b = built.to_occupancy_grid(), grid.to_occupancy_grid()
        assert a.origin == b.origin and grid.bounds_m == built.bounds_m
        np.testing.assert_array_equal(a.data, b.data)
        np.testing.assert_array_equal(grid.observed, built.observed)
        np.testing.assert_allclose(grid.log_odds(), built.log_odds(), atol=1e-5)


def test_the_cache_draws_only_new_scans_and_redraws_when_a_drawn_one_moves_half_a_cell_or_leaves():
    rng = np.random.default_rng(3)
    poses = rng.uniform(-3.0, 3.0, (6, 3))
    scans = [ScanRays.from_laser(-2.0, 4.0 / 199, rng.uniform(0.5, 6.0, 200), 0.1, 8.0) for _ in poses]
    reach = np.array([s.ranges_m.max() for s in scans])  # every beam ends in range
    cache, settings = GridCache(), OccupancySettings()

    def same_as_rebuild(grid, poses, scans):
        built = LogOddsGrid.build(settings, poses, scans)
        assert grid.bounds_m == built.bounds_m and grid.scan_count == len(scans)
        np.testing.assert_array_equal(grid.log_odds(), built.log_odds())
        np.testing.assert_array_equal(grid.observed, built.observed)

    for count in (1, 3, 3, 6):  # scans added (or none): drawn on top of the kept grid, as a rebuild
        same_as_rebuild(cache.update(settings, poses[:count], scans[:count]), poses[:count], scans[:count])
    assert cache.rebuilds == 1
    # A correction within half a cell at each scan's farthest end leaves the grid as it was drawn.
    nudged = poses.copy()
    nudged[2, 0] += 0.01
    nudged[4, 2] += 0.02 / reach[4]
    same_as_rebuild(cache.update(settings, nudged, scans), poses, scans)
    # Moves are measured from where each scan was drawn: two nudges together are a redraw.
    nudged[2, 0] += 0.01
    nudged[2, 2] += 0.006 / reach[2]
    same_as_rebuild(cache.update(settings, nudged, scans), nudged, scans)
    assert cache.rebuilds == 2
    turned = nudged.copy()
    turned[5, 2] += 0.03 / reach[5]  # 3 cm at its farthest beam end
    same_as_rebuild(cache.update(settings, turned, scans), turned, scans)
    assert cache.rebuilds == 3
    kept = [0, 1, 3, 4, 5]  # a keyframe left the map
    same_as_rebuild(cache.update(settings, turned[kept], [scans[k] for k in kept]), turned[kept],
                    [scans[k] for k in kept])
    assert cache.rebuilds == 4
    other = [ScanRays(s.directions, s.ranges_m, s.range_min_m, s.range_max_m) for s in scans]  # a new mapper's
    cache.update(settings, poses, other)
    coarse = OccupancySettings(resolution_m=0.1)
    assert cache.update(coarse, poses, other).settings == coarse
    assert cache.rebuilds == 6


def test_the_cache_redraws_a_large_map_over_updates_within_its_budget():
    rng = np.random.default_rng(4)
    poses = rng.uniform(-3.0, 3.0, (8, 3))
    scans = [ScanRays.from_laser(-2.0, 4.0 / 99, rng.uniform(0.5, 5.0, 100), 0.1, 8.0) for _ in poses]
    settings = OccupancySettings()
    cache = GridCache(redraw_per_update=3)

    def drawn_as(grid, poses, scans):
        return np.array_equal(grid.log_odds(), LogOddsGrid.build(settings, poses, scans).log_odds())

    cache.update(settings, poses[:6], scans[:6])  # the first build is whole at once
    assert (cache.rebuilds, cache.stale) == (1, 0)
    moved = poses.copy()
    moved[:2, 0] += 0.1  # a loop bent the map: two keyframes 10 cm off
    # Six scans to redraw, three per update: meanwhile the kept grid, with the moved scans where
    # they were drawn and a new one drawn at its pose.
    grid = cache.update(settings, moved[:6], scans[:6])
    assert (cache.rebuilds, cache.stale) == (1, 2) and drawn_as(grid, poses[:6], scans[:6])
    grid = cache.update(settings, moved[:7], scans[:7])
    assert (cache.rebuilds, cache.stale) == (1, 2) and drawn_as(grid, np.concatenate([poses[:6], moved[6:7]]),
                                                                scans[:7])
    # The redraw drew scans 0-2, then 3-5, now 6 and 7 (new) at their poses: it replaces the grid.
    grid = cache.update(settings, moved, scans)
    assert (cache.rebuilds, cache.stale) == (2, 0) and drawn_as(grid, moved, scans)
    # A redraw draws each scan at its pose when it gets to it: a later move is drawn again.
    moved[0, 0] += 0.1
    cache.update(settings, moved, scans)
    moved[7, 0] += 0.1
    cache.update(settings, moved, scans)
    grid = cache.update(settings, moved, scans)
    assert (cache.rebuilds, cache.stale) == (3, 0) and drawn_as(grid, moved, scans)
    # Other scans (a new mapper) are drawn whole at once.
    other = [ScanRays(s.directions, s.ranges_m, s.range_min_m, s.range_max_m) for s in scans]
    assert drawn_as(cache.update(settings, moved, other), moved, other) and cache.rebuilds == 4
    with pytest.raises(OccupancyError, match="redraw_per_update must be an integer >= 1, not 0"):
        GridCache(redraw_per_update=0)


def test_the_cache_measures_a_turn_across_pi_and_at_the_reach_of_beams_without_return():
    settings = OccupancySettings(max_range_m=4.0)
    ranges = np.full(90, np.inf)
    ranges[::3] = 1.5  # a third return at 1.5 m; the rest clear up to max_range_m (4 m), not range_max
    scan = ScanRays.from_laser(-1.0, 2.0 / 89, ranges, 0.1, 8.0)
    cache = GridCache()
    cache.update(settings, [[1.0, 2.0, math.pi - 0.001]], [scan])
    turned = [[1.0, 2.0, -math.pi + 0.001 + 0.01 / 4.0]]  # 0.0045 rad across ±pi: 1.8 cm at 4 m
    cache.update(settings, turned, [scan])
    assert cache.rebuilds == 1
    turned = [[1.0, 2.0, math.pi - 0.001 + 0.03 / 4.0]]  # 3 cm at 4 m (though only 1.1 cm at 1.5 m)
    cache.update(settings, turned, [scan])
    assert cache.rebuilds == 2


def test_a_failed_update_is_drawn_again_whole(monkeypatch):
    rng = np.random.default_rng(5)
    poses = rng.uniform(-2.0, 2.0, (3, 3))
    scans = [ScanRays.from_laser(-2.0, 4.0 / 99, rng.uniform(0.5, 4.0, 100), 0.1, 8.0) for _ in poses]
    cache, settings = GridCache(), OccupancySettings()
    cache.update(settings, poses[:1], scans[:1])
    real, calls = LogOddsGrid.add_scan, []

    def fails_second(self, pose, rays):
        calls.append(1)
        if len(calls) == 2:
            raise MemoryError("no room")
        real(self, pose, rays)
    monkeypatch.setattr(LogOddsGrid, "add_scan", fails_second)
    with pytest.raises(MemoryError):
        cache.update(settings, poses, scans)  # scan 1 drawn, scan 2 failed
    monkeypatch.undo()
    grid = cache.update(settings, poses, scans)
    assert cache.rebuilds == 2  # not scan 1 twice
    np.testing.assert_array_equal(grid.log_odds(), LogOddsGrid.build(settings, poses, scans).log_odds())


def test_build_composes_the_sensor_mount():
    base_poses = np.array([[0.0, 0.0, 0.5], [0.4, -0.3, 1.5]])
    mount = (0.2, 0.05, 0.1)
    scans = [room_scan((0.0, 0.0, 0.0)), room_scan((0.4, -0.3, 1.0))]
    with_mount = LogOddsGrid.build(OccupancySettings(), base_poses, scans, sensor_in_base_xyyaw=mount)
    sensor_poses = LogOddsGrid.build(OccupancySettings(), se2_compose(base_poses, mount), scans)
    np.testing.assert_array_equal(with_mount.log_odds(), sensor_poses.log_odds())


def test_a_rotated_pose_gives_the_map_of_the_rotated_ranges():
    beams, shift = 360, 37
    angle_min, increment = full_circle(beams)
    yaw = shift * increment
    position = (0.113, -0.271)
    ranges = room_ranges((*position, 0.0), angle_min, increment, beams)  # in world directions
    rotated, straight = LogOddsGrid(), LogOddsGrid()
    rotated.add_scan((*position, yaw), ScanRays.from_laser(angle_min, increment, np.roll(ranges, -shift), 0.05, 10.0))
    straight.add_scan((*position, 0.0), ScanRays.from_laser(angle_min, increment, ranges, 0.05, 10.0))
    a, b = rotated.to_occupancy_grid(), straight.to_occupancy_grid()
    assert a.origin == b.origin
    np.testing.assert_array_equal(a.data, b.data)
    np.testing.assert_allclose(rotated.log_odds(), straight.log_odds(), atol=1e-6)


@pytest.mark.parametrize("beams, angle_min, increment", [
    (90, *full_circle(90)), (640, *full_circle(640)), (1081, -3 * math.pi / 4, 1.5 * math.pi / 1080),
])
def test_any_beam_count_maps_the_walls_it_sees(beams, angle_min, increment):
    pose = (0.3, -0.4, 0.6)
    scan = room_scan(pose, beams, angle_min, increment)
    grid = LogOddsGrid()
    grid.add_scan(pose, scan)
    out = grid.to_occupancy_grid()
    hits = scan.directions * scan.ranges_m[:, None]
    c, s = math.cos(pose[2]), math.sin(pose[2])
    hx, hy = pose[0] + c * hits[:, 0] - s * hits[:, 1], pose[1] + s * hits[:, 0] + c * hits[:, 1]
    assert np.all(value_at(out, hx, hy) == OCCUPIED)
    assert all(on_ring(*cell) for cell in world_cells(out, OCCUPIED))


def test_an_empty_grid_is_empty_and_unobserved_cells_are_even_odds():
    grid = LogOddsGrid()
    assert grid.shape == (0, 0) and grid.bounds_m == (0.0, 0.0, 0.0, 0.0)
    assert grid.to_occupancy_grid().data.shape == (0, 0)
    grid.add_scan((0.0, 0.0, 0.0), one_beam(1.0))
    probabilities, observed = grid.probabilities(), grid.observed
    assert probabilities.shape == observed.shape == grid.shape
    assert np.all(probabilities[~observed] == 0.5) and observed.sum() == 21


@pytest.mark.parametrize("field, value", [
    ("resolution_m", 0.0), ("resolution_m", -0.05), ("max_range_m", 0.0), ("max_range_m", math.nan),
    ("hit_probability", 0.5), ("hit_probability", 1.0), ("miss_probability", 0.5), ("miss_probability", 0.0),
    ("clamp_log_odds", 0.0), ("occupied_threshold", 1.2), ("free_threshold", 0.7), ("free_threshold", 0.0),
])
def test_bad_settings_name_the_field(field, value):
    with pytest.raises(OccupancyError, match=field):
        OccupancySettings(**{field: value})


def test_bad_scans_and_poses_are_refused():
    with pytest.raises(OccupancyError, match="directions"):
        ScanRays(np.zeros((3, 2)), np.zeros(4))
    with pytest.raises(OccupancyError, match="range_max_m"):
        ScanRays.from_laser(0.0, 0.1, [1.0], 2.0, 1.0)
    with pytest.raises(OccupancyError, match="range_min_m"):
        ScanRays.from_laser(0.0, 0.1, [1.0], -0.1, 1.0)
    with pytest.raises(OccupancyError, match="sensor pose"):
        LogOddsGrid().add_scan((0.0, math.nan, 0.0), one_beam(1.0))
    with pytest.raises(OccupancyError, match="poses"):
        LogOddsGrid.build(OccupancySettings(), np.zeros((2, 3)), [one_beam(1.0)])
    assert isinstance(OccupancyError("x"), ValueError)
    with pytest.raises(OccupancyError, match="unit vectors"):
        ScanRays(np.array([[2.0, 0.0]]), np.array([1.0]))
    assert LogOddsGrid.build(OccupancySettings(), [], []).shape == (0, 0)
