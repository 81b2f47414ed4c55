"""Nav2's simple smoother on given paths (the smoother_server's plugin), without ROS."""
from __future__ import annotations

import math
from collections.abc import Callable, Iterator

import numpy as np
import pytest

from pppbot_common.maps import OccupancyGrid
from pppbot_common.params import ParameterError
from pppbot_nav.errors import SmootherError, SmootherTimedOut
from pppbot_nav.planner.simple_smoother import (
    MIN_SEGMENT_POSES,
    SimpleSmootherSettings,
    SmoothedPath,
    blocked_cells,
    directional_segments,
    first_collision,
    smooth_path,
)

SETTINGS = SimpleSmootherSettings()


def staircase(n: int = 41, step_m: float = 0.05) -> np.ndarray:
    """(n, 2) points of a 45° line drawn as grid steps: right, up, right, up..."""
    moves = np.array([[step_m, 0.0], [0.0, step_m]])[np.arange(n - 1) % 2]
    return np.vstack([[0.0, 0.0], np.cumsum(moves, axis=0)])


def headings(points: np.ndarray) -> np.ndarray:
    d = np.diff(points, axis=0)
    along = np.arctan2(d[:, 1], d[:, 0])
    return np.append(along, along[-1])


def roughness(points: np.ndarray) -> float:
    """Sum of squared second differences: 0 for evenly spaced points on a line."""
    return float((np.diff(points, 2, axis=0) ** 2).sum())


def frozen_clock() -> float:
    return 0.0


def smooth(points: np.ndarray, settings: SimpleSmootherSettings = SETTINGS, *,
           blocked: Callable[[np.ndarray], np.ndarray] | None = None,
           clock_s: Callable[[], float] = frozen_clock, max_duration_s: float = 1.0) -> SmoothedPath:
    return smooth_path(points, headings(points), settings, clock_s=clock_s, max_duration_s=max_duration_s,
                       blocked=blocked)


def test_a_staircase_comes_out_smoother_with_its_ends_fixed():
    points = staircase()
    out = smooth(points)
    assert out.completed
    smoothed = out.points_xy
    assert roughness(smoothed) < 0.2 * roughness(points)
    np.testing.assert_allclose(smoothed[[0, -1]], points[[0, -1]])
    # each pose but the last faces the next point
    d = np.diff(smoothed, axis=0)
    np.testing.assert_allclose(out.yaws_rad[:-1], np.arctan2(d[:, 1], d[:, 0]))


def test_a_path_too_short_to_smooth_comes_back_unchanged():
    points = staircase(MIN_SEGMENT_POSES)
    out = smooth(points)
    np.testing.assert_array_equal(out.points_xy, points)
    np.testing.assert_array_equal(out.yaws_rad, headings(points))


def test_refinement_smooths_further():
    points = staircase()
    once = smooth(points, SimpleSmootherSettings(do_refinement=False)).points_xy
    refined = smooth(points, SimpleSmootherSettings(refinement_num=2)).points_xy
    assert roughness(refined) < roughness(once)


def test_max_its_stops_a_segment_before_it_converges():
    out = smooth(staircase(), SimpleSmootherSettings(max_its=3))
    assert not out.completed
    assert roughness(out.points_xy) < roughness(staircase())  # the two sweeps made are kept


def test_a_sweep_that_would_enter_an_inscribed_cell_is_not_taken():
    points = staircase()
    # Mark inscribed every cell the fully smoothed path would newly enter (cells of the staircase stay free).
    grid = OccupancyGrid(np.zeros((40, 40), dtype=np.int8), 0.05, (-0.5, -0.5, 0.0))
    free = smooth(points).points_xy
    rows, cols = grid.cell_of(free[:, 0], free[:, 1])
    grid.data[rows, cols] = 99
    rows, cols = grid.cell_of(points[:, 0], points[:, 1])
    grid.data[rows, cols] = 0
    out = smooth(points, blocked=blocked_cells(grid))
    assert not out.completed
    assert first_collision(grid, out.points_xy[1:-1]) is None


def test_a_cusp_splits_the_path_into_directional_segments():
    forward = np.column_stack([np.linspace(0.0, 1.0, 11), np.zeros(11)])
    back = np.column_stack([np.linspace(0.9, 0.0, 10), np.full(10, 0.1)])
    points = np.vstack([forward, back])
    assert directional_segments(points, np.zeros(len(points))) == [(0, 10), (10, 20)]
    spot = np.vstack([forward, forward[-1:]])  # a turn on the spot at the end
    yaws = np.append(np.zeros(11), math.pi / 2)
    assert directional_segments(spot, yaws) == [(0, 10), (10, 11)]


def test_running_out_of_time_raises_timed_out():
    times: Iterator[float] = iter(np.arange(0.0, 100.0, 0.1))
    with pytest.raises(SmootherTimedOut, match="0.25 s"):
        smooth(staircase(), clock_s=lambda: float(next(times)), max_duration_s=0.25)


def test_bad_paths_and_settings_are_refused_naming_them():
    with pytest.raises(SmootherError, match="empty"):
        smooth_path(np.zeros((0, 2)), np.zeros(0), SETTINGS, clock_s=frozen_clock, max_duration_s=1.0)
    with pytest.raises(SmootherError, match="non-finite"):
        smooth_path(np.array([[0.0, math.nan]]), np.zeros(1), SETTINGS, clock_s=frozen_clock, max_duration_s=1.0)
    with pytest.raises(ParameterError, match="simple_smoother.w_smooth"):
        SimpleSmootherSettings(w_smooth=0.7).validate()
    with pytest.raises(ParameterError, match="simple_smoother.max_its"):
        SimpleSmootherSettings(max_its=0).validate()


def test_first_collision_finds_inscribed_lethal_and_off_map_poses_not_unknown_ones():
    data = np.zeros((10, 10), dtype=np.int8)
    data[5, 5], data[5, 6], data[5, 7], data[5, 8] = 98, -1, 99, 100
    grid = OccupancyGrid(data, 0.1, (0.0, 0.0, 0.0))
    y = 0.55
    assert first_collision(grid, np.array([[0.55, y], [0.65, y]])) is None  # 98 and unknown
    assert first_collision(grid, np.array([[0.55, y], [0.75, y]])) == 1  # inscribed
    assert first_collision(grid, np.array([[0.85, y]])) == 0  # lethal
    assert first_collision(grid, np.array([[0.5, y], [1.5, y]])) == 1  # off the map
