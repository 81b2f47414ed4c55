"""The ``clutter`` family: a field of obstacles across a corridor, grown by a cellular automaton as in
BARN (Perille et al., "Benchmarking Metric Ground Navigation", SSRR 2020: 300 fields of 30 × 30
cells of 0.15 m), the robot at one end and its goal at the other.

The corridor is :data:`CORRIDOR_M` wide between its wall faces (BARN's 4.5 m, 30 cells) and closed
at both ends, 1 m behind the spawn (the origin, facing +x) and 1 m beyond the goal (x = 10 m, or
5.5 m when small; y drawn within ±1 m; yaw 0). The field fills the corridor from wall to wall
between x = 1.5 m and 8.4 m (small: 4.5 m): aprons keep the spawn and the goal clear. Each
world draws a fill probability from :data:`FILL_RANGE` and a number of smoothing iterations
from :data:`SMOOTHING_ITERATIONS` (BARN's ranges), fills cells at random, and smooths them with
BARN's rule: a cell with :data:`BIRTH` or more filled neighbours of its eight fills, one with
:data:`SURVIVAL` − 1 or fewer empties (the walls count as filled neighbours beyond the sides).
Each maximal block of equal runs of filled cells in consecutive rows becomes one box.

A field is kept only when the goal is reachable through space farther than :data:`CLEARANCE_M`
from every obstacle: ppp_bot's Nav2 robot radius (0.3 m) plus a margin of 0.1 m, so every gap
on the way is wider than 0.8 m. Clearance is measured from the centres of :data:`GRID_M` cells
aligned with the field's (exact to a face, within 0.01 m to a corner); as the obstacles lie on
the 0.15 m lattice, the narrowest gap that passes is 0.81 m (5 by 2 cells, corner to corner),
then 0.85 m (4 by 4) and 0.9 m (6 straight across). A rejected field is drawn again from the
same generator, up to :data:`MAX_DRAWS` times; then the fill is lowered step by step down to 0
(an empty field, always passable), so generation always ends (``tries`` counts the fields drawn).

The shortest passable path (8-connected Dijkstra on that grid, shortened by line-of-sight string
pulling, so within a grid cell or so of the geometric shortest path) gives the difficulty
measures: its length, its tortuosity (length over the straight distance), the mean clearance
along it, and the narrowest gap it threads: twice the largest clearance a route can keep while
staying within :data:`TUBE_M` of the path. (The path itself grazes obstacles at 0.4 m wherever
it bends, so its own smallest clearance says nothing; the gap is what lies between the obstacle
it grazes and the one across. Where it threads none, about 2 m.)
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage, sparse
from scipy.sparse import csgraph

from pppbot_sim.worldgen.sdf import WALL_T, Segment

#: Side of a field cell (m), as BARN's.
CELL_M = 0.15
#: Cells across the corridor; its clear width (m) between the wall faces.
FIELD_ROWS = 30
CORRIDOR_M = FIELD_ROWS * CELL_M
#: Where the field starts (m, x); cells along it, and the goal's x (m), by size (small or not).
FIELD_X0_M = 1.5
FIELD_COLUMNS = {False: 46, True: 20}
GOAL_X_M = {False: 10.0, True: 5.5}
#: The goal's y is drawn from ±this (m); the corridor's ends stand this far behind the spawn and beyond the goal.
GOAL_Y_M = 1.0
END_APRON_M = 1.0
#: Fill probability and smoothing iterations (inclusive) drawn per world: BARN's ranges.
FILL_RANGE = (0.15, 0.30)
SMOOTHING_ITERATIONS = (2, 4)
#: The automaton's rule: an empty cell fills with at least BIRTH filled neighbours, a filled one stays with SURVIVAL.
BIRTH = 5
SURVIVAL = 2
#: ppp_bot's Nav2 robot radius and the margin on it (m): every gap on the way is wider than twice their sum.
ROBOT_RADIUS_M = 0.3
MARGIN_M = 0.1
CLEARANCE_M = ROBOT_RADIUS_M + MARGIN_M
#: The passability grid's cell (m): a third of a field cell.
GRID_M = 0.05
#: Fields drawn at the drawn fill before thinning; thinning steps from it down to an empty field.
MAX_DRAWS = 20
THINNING_STEPS = 10
#: How far from the shortest path (m) the narrowest gap's route may stray.
TUBE_M = 0.6
#: Each box reaches this far (m) past its cells, so boxes that touch (or touch a wall) overlap and are one obstacle.
OVERLAP_M = 0.001

_PER_CELL = round(CELL_M / GRID_M)
_NEIGHBOURS = np.array([[1, 1, 1], [1, 0, 1], [1, 1, 1]])


@dataclass(frozen=True)
class Clutter:
    """A clutter world: wall centre lines, boxes (centre x, y, size x, size y; m), the goal (x, y, yaw),
    the shortest passable path from the spawn to it (m, world frame) and the generator's measures."""

    walls: tuple[Segment, ...]
    boxes: tuple[tuple[float, float, float, float], ...]
    goal: tuple[float, float, float]
    path: tuple[tuple[float, float], ...]
    parameters: dict[str, float]


@dataclass(frozen=True, eq=False)
class Crossing:
    """The shortest passable path from the spawn to the goal, (K, 2) m in the world frame, and its measures (m)."""

    path: np.ndarray
    path_length_m: float
    tortuosity: float
    mean_clearance_m: float
    narrowest_gap_m: float


def _r(value: float) -> float:
    return round(float(value), 3)


def smooth(field: np.ndarray) -> np.ndarray:
    """One round of the automaton on a (rows, columns) bool field, rows along y: the walls beyond its
    first and last rows count as filled neighbours, the open ends beyond its columns as empty."""
    padded = np.pad(field, ((1, 1), (0, 0)), constant_values=True)
    count = ndimage.convolve(padded.astype(np.int8), _NEIGHBOURS, mode="constant", cval=0)[1:-1]
    return np.asarray((count >= BIRTH) | (field & (count >= SURVIVAL)))


def grow_field(rng: np.random.Generator, rows: int, columns: int, fill: float, iterations: int) -> np.ndarray:
    """(rows, columns) bool field: cells filled with probability ``fill``, then ``iterations`` rounds of
    :func:`smooth`."""
    field = rng.random((rows, columns)) < fill
    for _ in range(iterations):
        field = smooth(field)
    return field


def field_boxes(field: np.ndarray, x0: float, y0: float) -> list[tuple[float, float, float, float]]:
    """The filled cells of ``field`` (cell (0, 0)'s corner at (x0, y0) m) as boxes (centre x, y, size x, size y):
    each row's runs, equal runs in consecutive rows merged, each :data:`OVERLAP_M` larger on every side."""
    open_runs: dict[tuple[int, int], int] = {}  # (first column, past last) → first row
    blocks: list[tuple[int, int, int, int]] = []
    for row in range(field.shape[0] + 1):
        line = np.concatenate([[False], field[row] if row < field.shape[0] else [], [False]]).astype(np.int8)
        edges = np.flatnonzero(np.diff(line))
        runs = set(zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True))
        for run in sorted(set(open_runs) - runs):
            blocks.append((*run, open_runs.pop(run), row))
        for run in runs - set(open_runs):
            open_runs[run] = row
    return [(_r(x0 + CELL_M * (c0 + c1) / 2), _r(y0 + CELL_M * (r0 + r1) / 2),
             _r(CELL_M * (c1 - c0) + 2 * OVERLAP_M), _r(CELL_M * (r1 - r0) + 2 * OVERLAP_M))
            for c0, c1, r0, r1 in sorted(blocks, key=lambda b: (b[2], b[0]))]


def clearance_grid(field: np.ndarray, x_min: float, x_max: float) -> np.ndarray:
    """Clearance (m) from each :data:`GRID_M` cell's centre of the corridor's clear space (x from ``x_min``
    to ``x_max``, y across :data:`CORRIDOR_M`; rows along y) to the nearest box or wall face."""
    columns = round((x_max - x_min) / GRID_M)
    occupied = np.zeros((FIELD_ROWS * _PER_CELL, columns), dtype=bool)
    first = round((FIELD_X0_M - x_min) / GRID_M)
    cells = np.kron(field, np.ones((_PER_CELL, _PER_CELL), dtype=bool))
    occupied[:, first:first + cells.shape[1]] = cells
    distance = ndimage.distance_transform_edt(~np.pad(occupied, 1, constant_values=True))[1:-1, 1:-1]
    return np.asarray(distance * GRID_M - GRID_M / 2 - OVERLAP_M)


def _predecessors(free: np.ndarray, start: tuple[int, int]) -> np.ndarray:
    """Predecessor of each cell (flat index, negative when unreached) on the shortest 8-connected paths from
    ``start`` through ``free``; diagonal steps only past two free cells."""
    height, width = free.shape
    padded = np.pad(free, 1)
    index = np.arange(free.size).reshape(free.shape)
    heads, tails, weights = [], [], []
    for d_row, d_col in ((0, 1), (1, 0), (1, 1), (1, -1)):
        ok = free & padded[1 + d_row:height + 1 + d_row, 1 + d_col:width + 1 + d_col]
        if d_col and d_row:
            ok &= padded[1 + d_row:height + 1 + d_row, 1:-1] & padded[1:-1, 1 + d_col:width + 1 + d_col]
        heads.append(index[ok])
        tails.append(index[ok] + d_row * width + d_col)
        weights.append(np.full(int(ok.sum()), math.hypot(d_row, d_col)))
    graph = sparse.csr_matrix((np.concatenate(weights), (np.concatenate(heads), np.concatenate(tails))),
                              shape=(free.size, free.size))
    _, predecessor = csgraph.dijkstra(graph, directed=False, indices=start[0] * width + start[1],
                                      return_predecessors=True)
    return np.asarray(predecessor)


def _samples(points: np.ndarray) -> np.ndarray:
    """Points every half grid cell or closer along a polyline (K, 2) in grid units, ends included."""
    parts = [points[:1]]
    for a, b in zip(points[:-1], points[1:], strict=True):
        count = max(1, math.ceil(2 * float(np.hypot(*(b - a)))))
        parts.append(a + np.linspace(0.0, 1.0, count + 1)[1:, None] * (b - a))
    return np.vstack(parts)


def _sees(free: np.ndarray, a: np.ndarray, b: np.ndarray) -> bool:
    cells = np.floor(_samples(np.vstack([a, b]))).astype(int)
    return bool(free[cells[:, 1], cells[:, 0]].all())


def _string_pull(free: np.ndarray, points: np.ndarray) -> np.ndarray:
    """From each kept point of a polyline (K, 2; grid units, x then y), the farthest later one it sees."""
    kept, i = [0], 0
    while i < len(points) - 1:
        i = next(j for j in range(len(points) - 1, i, -1) if j == i + 1 or _sees(free, points[i], points[j]))
        kept.append(i)
    return points[kept]


def _narrowest_gap(clearance: np.ndarray, path_cells: np.ndarray) -> float:
    """Twice the largest clearance (m) a route from the path's first cell to its last keeps within
    :data:`TUBE_M` of the path (cells (K, 2), row then column)."""
    on_path = np.zeros(clearance.shape, dtype=bool)
    on_path[path_cells[:, 0], path_cells[:, 1]] = True
    tube = ndimage.distance_transform_edt(~on_path) * GRID_M <= TUBE_M
    levels = np.unique(clearance[tube & (clearance >= clearance[on_path].min())])
    (r0, c0), (r1, c1) = path_cells[0], path_cells[-1]
    low, high = 0, len(levels) - 1  # levels[low] connects them; find the last level that does
    while low < high:
        middle = (low + high + 1) // 2
        labels, _ = ndimage.label(tube & (clearance >= levels[middle]), structure=np.ones((3, 3)))
        low, high = (middle, high) if labels[r0, c0] and labels[r0, c0] == labels[r1, c1] else (low, middle - 1)
    return 2 * float(levels[low])


def crossing(field: np.ndarray, goal: tuple[float, float], x_min: float, x_max: float) -> Crossing | None:
    """The shortest passable path from the origin to ``goal`` (m) through the corridor with ``field``
    (:func:`clearance_grid`), or None when there is none."""
    clearance = clearance_grid(field, x_min, x_max)
    free = clearance > CLEARANCE_M
    origin = np.array([x_min, -CORRIDOR_M / 2])
    start_xy, goal_xy = (np.zeros(2) - origin) / GRID_M, (np.array(goal) - origin) / GRID_M  # grid units
    (c0, r0), (c1, r1) = np.floor(start_xy).astype(int), np.floor(goal_xy).astype(int)
    predecessor = _predecessors(free, (r0, c0))
    flat = [r1 * free.shape[1] + c1]
    while predecessor[flat[-1]] >= 0:
        flat.append(int(predecessor[flat[-1]]))
    if flat[-1] != r0 * free.shape[1] + c0:
        return None
    rows, columns = np.divmod(np.array(flat[::-1]), free.shape[1])
    centres = np.column_stack([columns + 0.5, rows + 0.5])
    pulled = _string_pull(free, np.vstack([start_xy, centres[1:-1], goal_xy]))
    samples = np.floor(_samples(pulled)).astype(int)
    path = pulled * GRID_M + origin
    length = float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())
    return Crossing(path, length, length / math.hypot(*goal), float(clearance[samples[:, 1], samples[:, 0]].mean()),
                    _narrowest_gap(clearance, samples[:, ::-1]))


def clutter(rng: np.random.Generator, small: bool) -> Clutter:
    """A clutter world drawn from ``rng`` (module docstring); ``small``: the goal at 5.5 m instead of 10 m.

    Its parameters: ``fill`` (drawn), ``fill_used`` (lower when thinned), ``smoothing_iterations``,
    ``tries`` (fields drawn), ``boxes``, ``density`` (the fraction of field cells filled) and the
    path's ``narrowest_gap_m``, ``path_length_m``, ``tortuosity`` and ``mean_clearance_m``.
    """
    fill = float(rng.uniform(*FILL_RANGE))
    iterations = int(rng.integers(SMOOTHING_ITERATIONS[0], SMOOTHING_ITERATIONS[1] + 1))
    goal = (GOAL_X_M[small], _r(rng.uniform(-GOAL_Y_M, GOAL_Y_M)))
    x_min, x_max = -END_APRON_M, goal[0] + END_APRON_M
    fills = [fill] * MAX_DRAWS + [fill * (1 - k / THINNING_STEPS) for k in range(1, THINNING_STEPS + 1)]
    found, tries = None, 0
    while found is None:
        if tries == len(fills):  # a generator bug: the last fill is 0, and an empty field is passable
            raise AssertionError(f"no passable clutter field, not even an empty one (fill {fill}, goal {goal})")
        used = fills[tries]
        field = grow_field(rng, FIELD_ROWS, FIELD_COLUMNS[small], used, iterations)
        found = crossing(field, goal, x_min, x_max)
        tries += 1
    y = CORRIDOR_M / 2 + WALL_T / 2  # the side walls' centre lines
    ends = (x_min - WALL_T / 2, x_max + WALL_T / 2)
    walls: tuple[Segment, ...] = ((ends[0], -y, ends[1], -y), (ends[1], -y, ends[1], y),
                                  (ends[1], y, ends[0], y), (ends[0], y, ends[0], -y))
    boxes = field_boxes(field, FIELD_X0_M, -CORRIDOR_M / 2)
    parameters = {"fill": _r(fill), "fill_used": _r(used), "smoothing_iterations": iterations, "tries": tries,
                  "boxes": len(boxes), "density": _r(field.mean()),
                  "narrowest_gap_m": _r(found.narrowest_gap_m), "path_length_m": _r(found.path_length_m),
                  "tortuosity": _r(found.tortuosity), "mean_clearance_m": _r(found.mean_clearance_m)}
    path = ((0.0, 0.0), *((_r(x), _r(y)) for x, y in found.path[1:-1]), goal)
    return Clutter(walls=walls, boxes=tuple(boxes), goal=(goal[0], goal[1], 0.0), path=path, parameters=parameters)
