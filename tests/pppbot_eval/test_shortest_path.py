"""Shortest collision-free paths of a disc robot on occupancy grids."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.sparse.csgraph import dijkstra

from pppbot_common.maps import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from pppbot_eval.shortest_path import (
    GoalBlocked,
    NoPath,
    PathError,
    StartBlocked,
    cell_path,
    distances_from,
    free_space,
    segments_free,
    shortest_path,
)

RES = 0.1


def empty(height: int = 50, width: int = 50, origin=(0.0, 0.0, 0.0)) -> OccupancyGrid:
    return OccupancyGrid(np.full((height, width), FREE, dtype=np.int8), RES, origin)


def wall_with_gap() -> OccupancyGrid:
    """80×60 cells; a wall along row 30 (y 3.0..3.1 m) with a gap at cols 30..37 (x 3.0..3.8 m)."""
    data = np.full((60, 80), FREE, dtype=np.int8)
    data[30, :] = OCCUPIED
    data[30, 30:38] = FREE
    return OccupancyGrid(data, RES)


def enclosed_goal() -> OccupancyGrid:
    grid = empty()
    grid.data[20:31, 20] = grid.data[20:31, 30] = OCCUPIED
    grid.data[20, 20:31] = grid.data[30, 20:31] = OCCUPIED
    return grid


def assert_polyline_in_free_space(grid: OccupancyGrid, free: np.ndarray, points: np.ndarray, skip_first: bool = False):
    for a, b in zip(points[int(skip_first):-1], points[int(skip_first) + 1:], strict=True):
        assert segments_free(grid, free, a, b[None, :])[0], f"segment {a} → {b} leaves free space"


def test_free_space_keeps_the_radius_from_walls_and_unknown():
    grid = empty(10, 10)
    grid.data[:, 0] = OCCUPIED
    grid.data[:, 9] = UNKNOWN
    free = free_space(grid, 0.16)
    # clearance of a cell = centre distance − half a cell: col 1 → 0.05, col 2 → 0.15, col 3 → 0.25
    assert np.flatnonzero(free[0]).tolist() == [3, 4, 5, 6]
    assert np.flatnonzero(free_space(grid, 0.16, unknown_is_free=True)[0]).tolist() == [3, 4, 5, 6, 7, 8, 9]
    assert free_space(empty(3, 3), 5.0).all()  # cells outside the grid are not obstacles


def test_empty_grid_gives_the_straight_line():
    grid = empty(origin=(-1.0, -2.0, 0.0))
    start, goal = (-0.53, -1.61), (2.87, 1.22)
    path = shortest_path(grid, start, goal, robot_radius_m=0.2)
    assert path.length_m == pytest.approx(math.dist(start, goal), abs=1e-9)
    assert path.points_xy[0].tolist() == list(start) and path.points_xy[-1].tolist() == list(goal)


def test_rotated_grid_is_searched_in_its_own_frame():
    grid = empty(20, 20, origin=(5.0, 5.0, math.pi / 2))  # covers x 3..5, y 5..7
    path = shortest_path(grid, (4.9, 5.1), (3.1, 6.9), 0.0)
    assert path.length_m == pytest.approx(math.dist((4.9, 5.1), (3.1, 6.9)), abs=1e-9)
    with pytest.raises(GoalBlocked, match="outside the grid"):
        shortest_path(grid, (4.9, 5.1), (5.5, 6.0), 0.0)


def test_path_goes_through_the_gap():
    grid = wall_with_gap()
    start, goal, radius = (2.0, 1.0), (7.0, 5.0), 0.15
    path = shortest_path(grid, start, goal, radius)
    corner = (3.8 - radius, 3.05)  # the robot passes the gap's right edge at its radius
    analytic = math.dist(start, corner) + math.dist(corner, goal)
    assert analytic - 0.01 <= path.length_m <= analytic + RES
    for y in (3.0, 3.1):  # where the path crosses the wall's faces: inside the gap, clear of its edges
        i = int(np.flatnonzero(path.points_xy[1:, 1] >= y)[0])
        (x0, y0), (x1, y1) = path.points_xy[i], path.points_xy[i + 1]
        assert 3.0 + radius <= x0 + (y - y0) / (y1 - y0) * (x1 - x0) <= 3.8 - radius
    assert_polyline_in_free_space(grid, free_space(grid, radius), path.points_xy)


def test_dijkstra_matches_a_brute_force_dense_graph():
    rng = np.random.default_rng(3)
    free = rng.random((9, 11)) > 0.3
    free[0, 0] = True
    height, width = free.shape
    dense = np.zeros((free.size, free.size))
    for r in range(height):
        for c in range(width):
            for dr in (-1, 0, 1):
                for dc in (-1, 0, 1):
                    rr, cc = r + dr, c + dc
                    if (dr, dc) == (0, 0) or not (0 <= rr < height and 0 <= cc < width):
                        continue
                    if free[r, c] and free[rr, cc] and (dr == 0 or dc == 0 or (free[r, cc] and free[rr, c])):
                        dense[r * width + c, rr * width + cc] = math.hypot(dr, dc) * 0.5
    expected = dijkstra(dense, indices=0).reshape(free.shape)
    distance, predecessor = distances_from(free, (0, 0), resolution_m=0.5)
    assert np.allclose(distance, expected)
    far = np.unravel_index(np.argmax(np.where(np.isfinite(distance), distance, -1)), free.shape)
    cells = cell_path(predecessor, (int(far[0]), int(far[1])))
    steps = np.abs(np.diff(cells, axis=0))
    assert cells[0].tolist() == [0, 0] and steps.max() == 1
    assert 0.5 * np.hypot(steps[:, 0], steps[:, 1]).sum() == pytest.approx(distance[far])


def test_diagonal_moves_do_not_cut_corners():
    free = np.ones((3, 3), dtype=bool)
    free[1, 1] = False
    distance, _ = distances_from(free, (0, 0), resolution_m=1.0)
    assert distance[2, 2] == 4.0
    assert distance[1, 2] == 3.0


def test_blocked_goal():
    grid = wall_with_gap()
    with pytest.raises(GoalBlocked, match=r"goal \(1.05, 3.05\) m"):
        shortest_path(grid, (1.0, 1.0), (1.05, 3.05), 0.1)
    with pytest.raises(GoalBlocked):  # free cell, but within the radius of the wall
        shortest_path(grid, (1.0, 1.0), (1.05, 3.25), 0.2)


def test_enclosed_goal_has_no_path():
    with pytest.raises(NoPath, match=r"from \(1.0, 1.0\) m to \(2.5, 2.5\) m"):
        shortest_path(enclosed_goal(), (1.0, 1.0), (2.5, 2.5), 0.1)


def test_robot_wider_than_the_gap_has_no_path():
    shortest_path(wall_with_gap(), (2.0, 1.0), (7.0, 5.0), 0.35)  # 0.8 m gap, 0.7 m robot: fits
    with pytest.raises(NoPath):
        shortest_path(wall_with_gap(), (2.0, 1.0), (7.0, 5.0), 0.45)


def test_start_near_a_wall_snaps_to_free_space():
    grid = wall_with_gap()
    start = (1.0, 2.9)  # 0.1 m below the wall: inside the 0.2 m radius
    path = shortest_path(grid, start, (1.0, 1.0), 0.2)
    assert path.points_xy[0].tolist() == list(start)
    assert 1.9 - 1e-9 <= path.length_m <= 1.9 + 2 * 0.2
    assert_polyline_in_free_space(grid, free_space(grid, 0.2), path.points_xy, skip_first=True)


def test_start_deep_in_a_wall_is_blocked():
    grid = empty()
    grid.data[10:40, 10:40] = OCCUPIED
    with pytest.raises(StartBlocked, match=r"start \(2.5, 2.5\) m"):
        shortest_path(grid, (2.5, 2.5), (0.5, 0.5), 0.2)
    assert issubclass(StartBlocked, PathError) and issubclass(PathError, ValueError)


@pytest.mark.parametrize("radius", [-0.1, math.inf])
def test_bad_radius_is_refused(radius):
    with pytest.raises(PathError, match="robot_radius_m"):
        shortest_path(empty(), (0.5, 0.5), (1.0, 1.0), radius)
