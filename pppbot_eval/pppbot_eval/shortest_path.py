"""The shortest collision-free path of a disc robot on an occupancy grid.

The robot's centre may be in a cell whose centre is farther than the robot's radius
from every obstacle cell (:func:`free_space`). Paths are searched on the 8-connected
graph of those cells (Dijkstra, scipy.sparse.csgraph), with diagonal moves only when
both orthogonal cells they cut past are free, then shortened by greedy line-of-sight
string pulling (as in Theta*-style post-smoothing: from each kept point, jump to the
farthest later point it sees through free cells). The result is within a fraction of a
cell of the true shortest path in free space, and never shorter than straight-line.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import ndimage, sparse
from scipy.sparse import csgraph

from pppbot_common.maps import OccupancyGrid
from pppbot_eval.errors import GoalBlocked, NoPath, PathError, StartBlocked
from pppbot_eval.map_quality import cell_centers_xy, cells_of, free_cells, in_grid, occupied_cells

#: Samples along a line-of-sight check are at most this many cells apart.
SIGHT_STEP_CELLS = 0.5
#: Upper bound on the points sampled in one batch of line-of-sight checks.
_SIGHT_BATCH_POINTS = 2_000_000






@dataclass(frozen=True, eq=False)
class GridPath:
    """A path in the grid's world frame: ``points_xy`` (K, 2) m, start first, goal last."""

    points_xy: np.ndarray
    length_m: float


def _check_radius(robot_radius_m: float) -> None:
    if not (math.isfinite(robot_radius_m) and robot_radius_m >= 0):
        raise PathError(f"robot_radius_m must be a non-negative number, not {robot_radius_m}")


def free_space(grid: OccupancyGrid, robot_radius_m: float, unknown_is_free: bool = False) -> np.ndarray:
    """(height, width) bool mask of the cells the robot's centre may occupy.

    A cell is free space when its centre is farther than ``robot_radius_m`` from every
    obstacle cell: occupied cells and, unless ``unknown_is_free``, unknown ones. The
    distance to an obstacle cell is taken as centre-to-centre minus half a cell (its near
    edge, exact for the usual axis-aligned walls), so a gap of n free cells lets through a
    robot narrower than n cells. Cells outside the grid are not obstacles.

    Raises:
        PathError: ``robot_radius_m`` is negative or not finite.
    """
    _check_radius(robot_radius_m)
    obstacles = occupied_cells(grid) if unknown_is_free else ~free_cells(grid)
    if not obstacles.any():
        return np.ones(obstacles.shape, dtype=bool)
    clearance_m = ndimage.distance_transform_edt(~obstacles, sampling=grid.resolution) - grid.resolution / 2.0
    return np.asarray(clearance_m > robot_radius_m)


# --- the grid graph ---------------------------------------------------------------------------

_MOVES = ((0, 1), (1, 0), (1, 1), (1, -1))  # (d_row, d_col): each undirected edge once


def grid_graph(free: np.ndarray, resolution_m: float) -> tuple[sparse.csr_matrix, np.ndarray]:
    """The 8-connected graph over the True cells of ``free``: (edge weights in m, node → flat cell index).

    Orthogonal edges weigh ``resolution_m``, diagonal ones ``resolution_m·√2`` and exist only
    when both orthogonal cells they cut past are free. Each edge is stored once (use the
    graph as undirected).
    """
    cells = np.flatnonzero(free)
    rows, cols = np.divmod(cells, free.shape[1])
    rows, cols = rows + 1, cols + 1  # indices into the padded mask, whose False border needs no bounds checks
    padded = np.pad(free, 1)
    node_of = np.full(padded.shape, -1, dtype=np.int64)
    nodes = np.arange(cells.size)
    node_of[rows, cols] = nodes
    heads, tails, weights = [], [], []
    for d_row, d_col in _MOVES:
        ok = padded[rows + d_row, cols + d_col]
        if d_row and d_col:
            ok &= padded[rows + d_row, cols] & padded[rows, cols + d_col]
        heads.append(nodes[ok])
        tails.append(node_of[rows[ok] + d_row, cols[ok] + d_col])
        weights.append(np.full(int(ok.sum()), resolution_m * math.hypot(d_row, d_col)))
    graph = sparse.csr_matrix((np.concatenate(weights), (np.concatenate(heads), np.concatenate(tails))),
                              shape=(cells.size, cells.size))
    return graph, cells


def distances_from(free: np.ndarray, start_cell: tuple[int, int],
                   resolution_m: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Shortest 8-connected grid distances from ``start_cell`` (row, col) over the True cells of ``free``.

    Returns (distance, predecessor), both shaped like ``free``: the distance in m
    (``resolution_m`` per orthogonal step; inf where unreachable or not free) and the
    flat index (``row * width + col``) of the previous cell on a shortest path (−1 at the
    start and where unreachable). Reuse them for many goals with :func:`cell_path`.

    Raises:
        StartBlocked: ``start_cell`` is outside the mask or not free.
    """
    row, col = int(start_cell[0]), int(start_cell[1])
    if not (0 <= row < free.shape[0] and 0 <= col < free.shape[1]) or not free[row, col]:
        raise StartBlocked(f"start cell ({row}, {col}) is not a free cell of the {free.shape} mask")
    graph, cells = grid_graph(free, resolution_m)
    start_node = int(np.searchsorted(cells, row * free.shape[1] + col))
    dist, pred = csgraph.dijkstra(graph, directed=False, indices=start_node, return_predecessors=True)
    distance = np.full(free.shape, np.inf)
    distance.flat[cells] = dist
    predecessor = np.full(free.shape, -1, dtype=np.int64)
    predecessor.flat[cells] = np.where(pred >= 0, cells[np.maximum(pred, 0)], -1)
    return distance, predecessor


def cell_path(predecessor: np.ndarray, goal_cell: tuple[int, int]) -> np.ndarray:
    """(K, 2) (row, col) cells from the start to ``goal_cell``, following :func:`distances_from`'s predecessors.

    A goal that was not reached gives just itself.
    """
    flat = [int(goal_cell[0]) * predecessor.shape[1] + int(goal_cell[1])]
    while predecessor.flat[flat[-1]] >= 0:
        flat.append(int(predecessor.flat[flat[-1]]))
    return np.column_stack(np.divmod(np.array(flat[::-1]), predecessor.shape[1]))


# --- line of sight ------------------------------------------------------------------------------


def segments_free(grid: OccupancyGrid, free: np.ndarray, a_xy: np.ndarray, b_xy: np.ndarray) -> np.ndarray:
    """(M,) bool: whether each segment from ``a_xy`` (2,) to ``b_xy[m]`` (M, 2) stays in free cells.

    Each segment is sampled at most :data:`SIGHT_STEP_CELLS` cells apart, ends included.
    """
    a_xy, b_xy = np.asarray(a_xy, dtype=float), np.asarray(b_xy, dtype=float).reshape(-1, 2)
    lengths = np.linalg.norm(b_xy - a_xy, axis=1)
    samples = np.maximum(2, np.ceil(lengths / (grid.resolution * SIGHT_STEP_CELLS)).astype(np.int64) + 1)
    segment = np.repeat(np.arange(b_xy.shape[0]), samples)
    first = np.repeat(np.cumsum(samples) - samples, samples)
    fraction = (np.arange(segment.size) - first) / np.repeat(samples - 1, samples)
    points = a_xy + fraction[:, None] * (b_xy - a_xy)[segment]
    rows, cols = cells_of(grid, points)
    inside = in_grid(grid, rows, cols)
    ok = np.zeros(segment.size, dtype=bool)
    ok[inside] = free[rows[inside], cols[inside]]
    return np.bincount(segment, weights=~ok, minlength=b_xy.shape[0]) == 0


def string_pull(grid: OccupancyGrid, free: np.ndarray, points_xy: np.ndarray) -> np.ndarray:
    """Greedy line-of-sight shortening of a polyline (K, 2) whose consecutive points see each other.

    From each kept point, the next kept point is the farthest later one visible through
    ``free`` cells; the first and last points are kept.
    """
    points_xy = np.asarray(points_xy, dtype=float)
    kept, i = [0], 0
    last = points_xy.shape[0] - 1
    while i < last:
        i = _farthest_visible(grid, free, points_xy, i)
        kept.append(i)
    return points_xy[kept]


def _farthest_visible(grid: OccupancyGrid, free: np.ndarray, points_xy: np.ndarray, i: int) -> int:
    candidates = np.arange(points_xy.shape[0] - 1, i, -1)
    batch = max(1, _SIGHT_BATCH_POINTS // max(1, int(2 * grid.height + 2 * grid.width)))
    for start in range(0, candidates.size, batch):
        chunk = candidates[start:start + batch]
        visible = segments_free(grid, free, points_xy[i], points_xy[chunk])
        if visible.any():
            return int(chunk[int(np.argmax(visible))])
    return i + 1


# --- the path -----------------------------------------------------------------------------------


def _point(xy: Sequence[float], name: str) -> np.ndarray:
    point = np.asarray(xy, dtype=float)
    if point.shape != (2,) or not np.isfinite(point).all():
        raise PathError(f"{name} must be a finite (x, y), not {xy!r}")
    return point


def _start_cell(grid: OccupancyGrid, free: np.ndarray, start: np.ndarray,
                robot_radius_m: float) -> tuple[tuple[int, int], bool]:
    """(start cell, whether it was snapped): the start's own cell, or the nearest free one within 2·radius."""
    row, col = (int(v) for v in cells_of(grid, start))
    if in_grid(grid, np.array(row), np.array(col)) and free[row, col]:
        return (row, col), False
    reach_m = 2.0 * robot_radius_m
    n = int(math.ceil(reach_m / grid.resolution)) + 1
    rows, cols = np.mgrid[max(0, row - n):min(grid.height, row + n + 1), max(0, col - n):min(grid.width, col + n + 1)]
    rows, cols = rows[free[rows, cols]], cols[free[rows, cols]]
    distance = np.linalg.norm(cell_centers_xy(grid, rows, cols) - start, axis=-1)
    if not distance.size or distance.min() > reach_m:
        raise StartBlocked(f"start ({start[0]}, {start[1]}) m is not in free space and no free cell centre "
                           f"lies within {reach_m} m (2 × robot radius)")
    best = int(np.argmin(distance))
    return (int(rows[best]), int(cols[best])), True


def _goal_cell(grid: OccupancyGrid, free: np.ndarray, goal: np.ndarray) -> tuple[int, int]:
    row, col = (int(v) for v in cells_of(grid, goal))
    if not in_grid(grid, np.array(row), np.array(col)):
        raise GoalBlocked(f"goal ({goal[0]}, {goal[1]}) m is outside the grid")
    if not free[row, col]:
        raise GoalBlocked(f"goal ({goal[0]}, {goal[1]}) m is not in free space (cell ({row}, {col}) holds "
                          f"{grid.data[row, col]}, or an obstacle is within the robot radius)")
    return row, col


def polyline_length_m(points_xy: np.ndarray) -> float:
    """Length (m) of a polyline (K, 2)."""
    return float(np.linalg.norm(np.diff(np.asarray(points_xy, dtype=float), axis=0), axis=1).sum())


def shortest_path(grid: OccupancyGrid, start_xy: Sequence[float], goal_xy: Sequence[float], robot_radius_m: float,
                  unknown_is_free: bool = False) -> GridPath:
    """The shortest path of a disc of ``robot_radius_m`` from ``start_xy`` to ``goal_xy`` (world m).

    A start that is not in free space (e.g. closer than the radius to a wall) is snapped
    to the nearest free cell centre within 2·``robot_radius_m``: the path then runs
    straight from the start to that centre first.

    Raises:
        StartBlocked: the start is not in free space and cannot be snapped.
        GoalBlocked: the goal is outside the grid or not in free space.
        NoPath: the goal is not reachable from the start.
        PathError: a malformed point or radius.
    """
    start, goal = _point(start_xy, "start_xy"), _point(goal_xy, "goal_xy")
    free = free_space(grid, robot_radius_m, unknown_is_free)
    goal_cell = _goal_cell(grid, free, goal)
    start_cell, snapped = _start_cell(grid, free, start, robot_radius_m)
    distance, predecessor = distances_from(free, start_cell, grid.resolution)
    if not math.isfinite(distance[goal_cell]):
        raise NoPath(f"no path for a robot of radius {robot_radius_m} m from ({start[0]}, {start[1]}) m "
                     f"to ({goal[0]}, {goal[1]}) m")
    cells = cell_path(predecessor, goal_cell)
    centres = cell_centers_xy(grid, cells[:, 0], cells[:, 1])
    if snapped:
        points = np.vstack([start, string_pull(grid, free, np.vstack([centres, goal]))])
    else:
        points = string_pull(grid, free, np.vstack([start, centres[1:-1], goal]))
    return GridPath(points, polyline_length_m(points))
