"""The live view's core: scans as points, grids as images, change detection, covariance
ellipses, the bounded trail, rate limits and poses from two clicks."""
from __future__ import annotations

import math

import numpy as np
import pytest
from pppbot_viz.visuals import (
    UNKNOWN_CELL,
    ChangeFilter,
    RateLimit,
    Trail,
    covariance_ellipse,
    grid_cells,
    grid_image,
    heading_arrows,
    pose_from_clicks,
    scan_points,
    transform_points,
)


def test_scan_points_keep_hits_in_range_only() -> None:
    ranges = [1.0, math.inf, 2.0, math.nan, 0.01, 30.0, 3.0]
    points = scan_points(ranges, angle_min=0.0, angle_increment=math.pi / 2, range_min=0.1, range_max=20.0)
    # beams 0, 2 and 6 (angles 0, pi, 3 pi): inf, NaN, too near and too far are left out
    np.testing.assert_allclose(points, [[1.0, 0.0, 0.0], [-2.0, 0.0, 0.0], [-3.0, 0.0, 0.0]], atol=1e-6)


def test_grid_cells_map_unknown_to_255_rows_from_origin() -> None:
    cells = grid_cells([-1, 0, 100, 50, -1, 0], width=3, height=2)
    assert cells.dtype == np.uint8 and cells.shape == (2, 3)
    assert cells.tolist() == [[UNKNOWN_CELL, 0, 100], [50, UNKNOWN_CELL, 0]]


def test_grid_image_puts_the_grids_origin_row_last_as_rerun_draws_a_picture() -> None:
    # row 0 of nav_msgs/OccupancyGrid lies at the origin (lowest y); rerun's GridMap draws an
    # image's first row at the top and its lower-left corner at the origin
    cells = grid_cells([100, 0, 0, 0, 0, -1], width=3, height=2)
    image = grid_image(cells)
    assert image.tolist() == [[0, 0, UNKNOWN_CELL], [100, 0, 0]]
    assert image.flags.c_contiguous


def test_grid_cells_reject_a_size_mismatch() -> None:
    with pytest.raises(ValueError, match="3x2 cells needs 6 values, got 5"):
        grid_cells([0] * 5, width=3, height=2)


def test_change_filter_passes_a_grid_only_when_it_changed() -> None:
    changes = ChangeFilter()
    cells = np.zeros((4, 4), dtype=np.uint8)
    origin = (0.0, 0.0, 0.0)
    assert changes.changed("map", cells, 0.05, origin, "map")
    assert not changes.changed("map", cells.copy(), 0.05, origin, "map")  # republished unchanged
    assert changes.changed("costmap", cells, 0.05, origin, "map")  # another name is another grid
    cells[1, 2] = 100
    assert changes.changed("map", cells, 0.05, origin, "map")
    assert changes.changed("map", cells, 0.05, (1.0, 0.0, 0.0), "map")  # moved
    assert changes.changed("map", cells, 0.1, (1.0, 0.0, 0.0), "map")  # rescaled
    assert changes.changed("map", cells, 0.1, (1.0, 0.0, 0.0), "odom")  # another frame


def test_covariance_ellipse_axes_and_angle() -> None:
    (major, minor), angle = covariance_ellipse(np.diag([0.04, 0.01]), sigmas=2.0)
    assert (major, minor) == pytest.approx((0.4, 0.2))
    assert math.sin(angle) == pytest.approx(0.0, abs=1e-9)
    # rotated by 30 degrees
    c, s = math.cos(math.pi / 6), math.sin(math.pi / 6)
    rotation = np.array([[c, -s], [s, c]])
    (major, minor), angle = covariance_ellipse(rotation @ np.diag([0.09, 0.01]) @ rotation.T, sigmas=1.0)
    assert (major, minor) == pytest.approx((0.3, 0.1))
    assert math.tan(angle) == pytest.approx(math.tan(math.pi / 6))


def test_covariance_ellipse_of_a_broken_covariance_is_empty() -> None:
    assert covariance_ellipse(np.array([[math.nan, 0.0], [0.0, 1.0]])) == ((0.0, 0.0), 0.0)
    (major, minor), _ = covariance_ellipse(np.diag([-1.0, 0.25]), sigmas=1.0)
    assert (major, minor) == pytest.approx((0.5, 0.0))


def test_heading_arrows() -> None:
    origins, vectors = heading_arrows(np.array([[1.0, 2.0, 0.0], [0.0, 0.0, math.pi / 2]]), length=0.5)
    np.testing.assert_allclose(origins, [[1, 2, 0], [0, 0, 0]])
    np.testing.assert_allclose(vectors, [[0.5, 0, 0], [0, 0.5, 0]], atol=1e-7)


def test_trail_spacing_and_bounded_length() -> None:
    trail = Trail(spacing_m=0.1, max_points=10, segment_points=4)
    assert trail.slots == 3
    assert trail.add(0.0, 0.0)
    assert not trail.add(0.05, 0.0)  # too near the last
    assert not trail.add(math.nan, 0.0)
    slots = []
    for i in range(1, 1000):
        assert trail.add(0.15 * i, 0.0)
        slot, segment = trail.newest()
        slots.append(slot)
        assert 2 <= len(segment) <= 4 or i < 4  # only the newest segment is sent: a few points
        assert segment[-1, 0] == pytest.approx(0.15 * i, abs=1e-3)
    assert set(slots) == {0, 1, 2}  # slots reused in turn: bounded however long the drive
    points = trail.points()
    assert 8 <= len(points) <= 12
    assert points[-1, 0] == pytest.approx(149.85, abs=1e-3)  # the newest position ...
    assert np.all(np.diff(points[:, 0]) > 0)  # ... one line, oldest first, each point once


def test_trail_segments_join_into_one_line() -> None:
    trail = Trail(spacing_m=0.1, max_points=100, segment_points=3)
    for i in range(7):
        trail.add(float(i), 0.0)
    np.testing.assert_allclose(trail.points()[:, 0], range(7))
    slot, segment = trail.newest()
    # segments [0 1 2] [2 3 4] [4 5 6]: the third starts at the second's last point
    assert slot == 2 and segment[:, 0].tolist() == [4.0, 5.0, 6.0]
    with pytest.raises(ValueError, match="segment_points"):
        Trail(segment_points=1)


def test_rate_limit_on_message_time() -> None:
    limit = RateLimit(max_hz=2.0)
    assert [limit.due(t) for t in (0.0, 0.2, 0.49, 0.5, 0.6, 1.0)] == [True, False, False, True, False, True]
    assert limit.due(0.1)  # time went back (a bag played again): start over
    assert all(RateLimit(0.0).due(t) for t in (0.0, 0.0, 0.001))
    with pytest.raises(ValueError, match="max_hz"):
        RateLimit(-1.0)


def test_transform_points_rotates_then_translates() -> None:
    quarter_turn = (0.0, 0.0, math.sin(math.pi / 4), math.cos(math.pi / 4))
    moved = transform_points(np.array([[1.0, 0.0, 0.0]]), (1.0, 2.0, 3.0), quarter_turn)
    np.testing.assert_allclose(moved, [[1.0, 3.0, 3.0]], atol=1e-6)


def test_pose_from_two_clicks() -> None:
    assert pose_from_clicks([1.0, 2.0, 0.0], [1.0, 3.0, 0.0]) == pytest.approx((1.0, 2.0, math.pi / 2))
    assert pose_from_clicks([1.0, 2.0], [0.0, 2.0]) == pytest.approx((1.0, 2.0, math.pi))
    assert pose_from_clicks([1.0, 2.0], [1.0, 2.0]) == (1.0, 2.0, 0.0)  # no heading given
