"""Coverage routes: drive over all the free space of a world and come back, closing loops.

A coverage route starts at the spawn pose (0, 0, 0), visits a lattice of targets over
all the free space reachable with a clearance from the walls, nearest unvisited target
first (by path length through free space, so it revisits corridors and closes loops),
and comes back to the start, which closes the largest loop. Consecutive targets are
joined by the shortest path with line-of-sight shortcuts. No randomness: a world gives
one route. Used by ``tools/make_routes.py`` (the shipped worlds' routes) and the world
generator (``benchmarks/worldgen.py``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from shapely.geometry import LineString

from pppbot_common.maps import OccupancyGrid
from pppbot_eval.routes import Route
from pppbot_eval.scenarios import world_truth
from pppbot_eval.shortest_path import cell_centers_xy, cell_path, distances_from, free_space, string_pull

#: Douglas–Peucker tolerance of the final polyline (m).
SIMPLIFY_M = 0.03


@dataclass(frozen=True)
class Coverage:
    spacing_m: float  # lattice of targets, aligned with the origin
    clearance_m: float  # the route keeps at least this far from walls (robot centre)
    inset_m: float = 0.0  # keep targets this far inside the world's outer bounds (open worlds)
    resolution_m: float = 0.1  # of the ground-truth grid the paths are planned on
    #: a lattice point off the free space moves to the nearest reachable cell within half the
    #: spacing (so a corridor that lies between lattice lines still gets targets)
    snap: bool = False


def lattice_targets(grid: OccupancyGrid, reachable: np.ndarray, settings: Coverage) -> np.ndarray:
    """(K, 2) cells (row, col): one per lattice point whose cell is reachable."""
    x0, y0 = grid.origin[0] + settings.inset_m, grid.origin[1] + settings.inset_m
    x1 = grid.origin[0] + grid.width * grid.resolution - settings.inset_m
    y1 = grid.origin[1] + grid.height * grid.resolution - settings.inset_m
    s = settings.spacing_m
    xs = np.arange(math.ceil(x0 / s), math.floor(x1 / s) + 1) * s
    ys = np.arange(math.ceil(y0 / s), math.floor(y1 / s) + 1) * s
    reach = int(s / 2 / grid.resolution)
    cells: list[tuple[int, int]] = []
    off: list[tuple[int, int]] = []  # lattice points off the reachable space
    for y in ys:
        for x in xs:
            row, col = (int(v) for v in grid.cell_of(x, y))
            if 0 <= row < grid.height and 0 <= col < grid.width and reachable[row, col]:
                cells.append((row, col))
            else:
                off.append((row, col))
    if settings.snap:
        spacing_cells = s / grid.resolution
        for row, col in off:
            r0, c0 = max(row - reach, 0), max(col - reach, 0)
            window = reachable[r0:max(row + reach + 1, 0), c0:max(col + reach + 1, 0)]
            if not window.any():
                continue
            rows, cols = np.nonzero(window)
            k = int(np.argmin((rows + r0 - row) ** 2 + (cols + c0 - col) ** 2))
            cell = (int(rows[k] + r0), int(cols[k] + c0))
            # only where no target is near already: a corridor between lattice lines gets one
            # row of targets, not a zig-zag to every lattice point beside it
            if all((cell[0] - a) ** 2 + (cell[1] - b) ** 2 >= spacing_cells ** 2 for a, b in cells):
                cells.append(cell)
    unique = list(dict.fromkeys(cells))
    return np.array(unique, dtype=int).reshape(-1, 2)


def coverage_route(world_file: Path, settings: Coverage, name: str = "coverage") -> Route:
    """The coverage route of the world in ``world_file`` (start (0, 0, 0)).

    Raises:
        WorldError: the world cannot be loaded.
        ValueError: the world has nothing at the lidar's height to plan around.
    """
    grid = world_truth(world_file, resolution_m=settings.resolution_m)
    free = free_space(grid, settings.clearance_m)
    # Shortcuts are checked on a mask one cell stricter: a straight line between cells of
    # the free mask can cut the corner of a cell by up to half a cell's diagonal.
    sight = free_space(grid, settings.clearance_m + grid.resolution)
    start_row, start_col = (int(v) for v in grid.cell_of(0.0, 0.0))
    distance, _ = distances_from(free, (start_row, start_col), grid.resolution)
    targets = lattice_targets(grid, np.isfinite(distance), settings)
    remaining = {tuple(t) for t in targets.tolist()} - {(start_row, start_col)}
    current = (start_row, start_col)
    points: list[np.ndarray] = [np.zeros((1, 2))]
    while True:
        distance, predecessor = distances_from(free, current, grid.resolution)
        if remaining:
            goal = min(remaining, key=lambda cell: (distance[cell], cell))
            remaining.discard(goal)
        elif current != (start_row, start_col):
            goal = (start_row, start_col)
        else:
            break
        cells = cell_path(predecessor, goal)
        centres = cell_centers_xy(grid, cells[:, 0], cells[:, 1])
        if goal == (start_row, start_col):
            centres[-1] = (0.0, 0.0)
        pulled = string_pull(grid, sight, np.vstack([points[-1][-1:], centres[1:]]))
        points.append(pulled[1:])
        current = goal
    # Where the stricter mask refused shortcuts the path keeps every cell: simplify it
    # (Douglas–Peucker, at most SIMPLIFY_M off the path; the tests check the clearance).
    waypoints = np.asarray(LineString(np.vstack(points)).simplify(SIMPLIFY_M).coords)[1:]
    length_m = float(np.linalg.norm(np.diff(np.vstack([[0.0, 0.0], waypoints]), axis=0), axis=1).sum())
    description = (f"visits {len(targets)} targets {settings.spacing_m} m apart over the free space at least "
                   f"{settings.clearance_m} m from walls, nearest first, and returns to the start ({length_m:.0f} m)")
    return Route(name, (0.0, 0.0, 0.0), waypoints, description)
