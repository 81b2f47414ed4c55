#!/usr/bin/env python3
"""Generate the evaluation routes of pppbot's worlds (run: ./pppbot env python tools/make_routes.py [world ...]).

The outputs (``worlds/<world>.routes.yaml``) are committed; this script documents
how they were made and remakes them identically (no randomness). A ``coverage``
route starts at the spawn pose (0, 0, 0), visits a lattice of targets over all
the free space reachable with a clearance from the walls, nearest unvisited
target first (by path length through free space, so it revisits corridors and
closes loops), and comes back to the start, which closes the largest loop.
Consecutive targets are joined by the shortest path with line-of-sight
shortcuts. The empty world gets a square.
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from shapely.geometry import LineString

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT / "pppbot_bringup"), str(ROOT / "pppbot_common"), str(ROOT / "pppbot_sim"),
                str(ROOT / "pppbot_description")]

from pppbot_bringup.eval.routes import Route, routes_file, save_routes  # noqa: E402
from pppbot_bringup.eval.scenarios import world_truth  # noqa: E402
from pppbot_common.maps import OccupancyGrid  # noqa: E402
from pppbot_bringup.eval.shortest_path import (  # noqa: E402
    cell_centers_xy,
    cell_path,
    distances_from,
    free_space,
    string_pull,
)
from pppbot_sim.worlds import find_world  # noqa: E402

WORLDS = ROOT / "worlds"
SIMPLIFY_M = 0.03


@dataclass(frozen=True)
class Coverage:
    spacing_m: float  # lattice of targets, aligned with the origin
    clearance_m: float  # the route keeps at least this far from walls (robot centre)
    inset_m: float = 0.0  # keep targets this far inside the world's outer bounds (open worlds)
    resolution_m: float = 0.1  # of the ground-truth grid the paths are planned on


SETTINGS = {
    "maze": Coverage(1.4, 0.4),
    "room": Coverage(1.0, 0.3, resolution_m=0.05),  # through 0.9 m doors
    "office": Coverage(3.0, 0.35),
    "cones": Coverage(2.5, 0.6, inset_m=1.5),
}


def lattice_targets(grid: OccupancyGrid, reachable: np.ndarray, settings: Coverage) -> np.ndarray:
    """(K, 2) cells (row, col): one per lattice point whose cell is reachable."""
    x0, y0 = grid.origin[0] + settings.inset_m, grid.origin[1] + settings.inset_m
    x1 = grid.origin[0] + grid.width * grid.resolution - settings.inset_m
    y1 = grid.origin[1] + grid.height * grid.resolution - settings.inset_m
    s = settings.spacing_m
    xs = np.arange(math.ceil(x0 / s), math.floor(x1 / s) + 1) * s
    ys = np.arange(math.ceil(y0 / s), math.floor(y1 / s) + 1) * s
    cells = []
    for y in ys:
        for x in xs:
            row, col = grid.cell_of(x, y)
            if 0 <= row < grid.height and 0 <= col < grid.width and reachable[row, col]:
                cells.append((int(row), int(col)))
    return np.array(cells, dtype=int).reshape(-1, 2)


def coverage_route(world: str, settings: Coverage) -> Route:
    grid = world_truth(find_world(world, WORLDS), resolution_m=settings.resolution_m)
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
    return Route("coverage", (0.0, 0.0, 0.0), waypoints, description)


def main(worlds: list[str]) -> int:
    for world in worlds or [*SETTINGS, "empty"]:
        if world == "empty":
            routes = [Route("square", (0.0, 0.0, 0.0), np.array([[3.0, 0.0], [3.0, 3.0], [0.0, 3.0], [0.0, 0.0]]),
                            "a 3 m square, back to the start (12 m)")]
        else:
            routes = [coverage_route(world, SETTINGS[world])]
        path = routes_file(find_world(world, WORLDS))
        save_routes(path, world, routes, "Generated by tools/make_routes.py; edit that script, not this file.")
        print(f"{path}: " + ", ".join(f"{r.name} ({len(r.waypoints)} waypoints, {r.length_m:.1f} m)" for r in routes))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
