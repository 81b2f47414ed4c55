"""How well an estimated occupancy grid matches the simulator's ground-truth grid.

Cells are classified with Nav2's trinary thresholds in percent: occupied when the value
is at least :data:`OCCUPIED_MIN` (occupied_thresh 0.65), free when 0 <= value <
:data:`FREE_BELOW` (free_thresh 0.25), unknown otherwise (−1 and the values between).

A grid's cell (row, col) has its centre at ``origin ∘ ((col + ½)·res, (row + ½)·res)`` in
the grid's frame; a point lies in the cell its grid coordinates floor to. Every lookup
goes through world positions, so the estimate and the truth may differ in resolution,
origin and yaw; a coarser estimate is judged at the truth's resolution (each estimated
cell counts once, at its centre).

Walls are scored as in occupancy-map benchmarks (e.g. the precision / recall of wall
cells within a tolerance in Hess et al.'s Cartographer evaluation): precision is the
fraction of estimated occupied cells near a true wall, recall the fraction of the true
walls' free-facing cells near an estimated occupied cell.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from pppbot_common.maps import OccupancyGrid
from pppbot_common.se2 import PoseLike, finite_pose, se2_apply, se2_compose, se2_inverse
from pppbot_eval.errors import MapQualityError

#: A cell is occupied when its value (percent) is at least this (Nav2's occupied_thresh 0.65).
OCCUPIED_MIN = 65
#: A cell is free when 0 <= value (percent) < this (Nav2's free_thresh 0.25).
FREE_BELOW = 25
#: 8-connectivity: the eight neighbours of a cell and the cell itself.
EIGHT_CONNECTED = np.ones((3, 3), dtype=bool)



# --- cells of a grid --------------------------------------------------------------------------


def occupied_cells(grid: OccupancyGrid) -> np.ndarray:
    """(height, width) bool mask of occupied cells (value >= :data:`OCCUPIED_MIN`)."""
    return grid.data >= OCCUPIED_MIN


def free_cells(grid: OccupancyGrid) -> np.ndarray:
    """(height, width) bool mask of free cells (0 <= value < :data:`FREE_BELOW`)."""
    return (grid.data >= 0) & (grid.data < FREE_BELOW)


def grid_pose(grid: OccupancyGrid, map_to_world: PoseLike = (0.0, 0.0, 0.0)) -> np.ndarray:
    """The pose of cell (0, 0)'s corner in the world: ``map_to_world ∘ grid.origin``."""
    return se2_compose(np.asarray(map_to_world, dtype=float), np.asarray(grid.origin, dtype=float))


def cell_centers_xy(grid: OccupancyGrid, rows: np.ndarray, cols: np.ndarray,
                    map_to_world: PoseLike = (0.0, 0.0, 0.0)) -> np.ndarray:
    """World positions (..., 2) in m of the centres of cells ``(rows, cols)``."""
    local = np.stack([(np.asarray(cols) + 0.5) * grid.resolution, (np.asarray(rows) + 0.5) * grid.resolution], -1)
    return se2_apply(grid_pose(grid, map_to_world), local)


def grid_coordinates(grid: OccupancyGrid, xy: np.ndarray,
                     map_to_world: PoseLike = (0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Continuous (row, col) of world points ``xy`` (..., 2): cell (r, c) spans [r, r+1) × [c, c+1)."""
    local = se2_apply(se2_inverse(grid_pose(grid, map_to_world)), np.asarray(xy, dtype=float)) / grid.resolution
    return local[..., 1], local[..., 0]


def cells_of(grid: OccupancyGrid, xy: np.ndarray,
             map_to_world: PoseLike = (0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Integer (row, col) of the cells containing world points ``xy`` (..., 2); may be out of range."""
    row, col = grid_coordinates(grid, xy, map_to_world)
    return np.floor(row).astype(np.int64), np.floor(col).astype(np.int64)


def in_grid(grid: OccupancyGrid, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Bool mask: which ``(rows, cols)`` index a cell of ``grid``."""
    return (rows >= 0) & (rows < grid.height) & (cols >= 0) & (cols < grid.width)


def near(mask: np.ndarray, tolerance_cells: int) -> np.ndarray:
    """Cells within Chebyshev distance ``tolerance_cells`` of a True cell of ``mask``."""
    if tolerance_cells == 0:
        return mask.copy()
    square = np.ones((2 * tolerance_cells + 1,) * 2, dtype=bool)
    return ndimage.binary_dilation(mask, structure=square)


# --- the comparison ---------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class MapQuality:
    """Scores of an estimated grid against the truth, and masks (in the truth grid) for plots.

    ``mean_wall_distance_m`` and ``wall_distance_p95_m`` are None when no estimated
    occupied cell lies inside the truth grid.
    """

    precision: float
    recall: float
    f1: float
    free_coverage: float
    mean_wall_distance_m: float | None
    wall_distance_p95_m: float | None
    estimated_occupied_cells: int
    outside_occupied_cells: int  # estimated occupied cells outside the truth grid (false walls)
    reference_wall_cells: int
    reference_free_cells: int
    true_walls: np.ndarray  # reference walls
    matched_walls: np.ndarray  # truth cells hit by estimated occupied cells within tolerance of a wall
    false_walls: np.ndarray  # truth cells hit by estimated occupied cells not within tolerance

    def as_dict(self) -> dict[str, float | int | None]:
        """The scalars with JSON-friendly names (``map_`` prefix); None stays None."""
        return {"map_precision": self.precision, "map_recall": self.recall, "map_f1": self.f1,
                "map_free_coverage": self.free_coverage, "map_mean_wall_distance_m": self.mean_wall_distance_m,
                "map_wall_distance_p95_m": self.wall_distance_p95_m,
                "map_occupied_cells": self.estimated_occupied_cells,
                "map_reference_wall_cells": self.reference_wall_cells}


def _check_tolerance(tolerance_cells: int) -> int:
    if isinstance(tolerance_cells, bool) or not isinstance(tolerance_cells, (int, np.integer)) or tolerance_cells < 0:
        raise MapQualityError(f"tolerance_cells must be a non-negative integer, not {tolerance_cells!r}")
    return int(tolerance_cells)


def _check_pose(map_to_world: PoseLike) -> None:
    finite_pose(map_to_world, "map_to_world", MapQualityError)


def reference_free(truth: OccupancyGrid, reachable_from: Sequence[float] | None = None) -> np.ndarray:
    """Truth free cells; with ``reachable_from`` (world x, y in m) only its 8-connected free component.

    Raises:
        MapQualityError: ``reachable_from`` is not in a free truth cell.
    """
    free = free_cells(truth)
    if reachable_from is None:
        return free
    point = np.asarray(reachable_from, dtype=float)
    if point.shape != (2,) or not np.isfinite(point).all():
        raise MapQualityError(f"reachable_from must be a finite (x, y), not {reachable_from!r}")
    row, col = cells_of(truth, point)
    if not in_grid(truth, row, col):
        raise MapQualityError(f"reachable_from ({point[0]}, {point[1]}) m is outside the truth grid")
    if not free[row, col]:
        raise MapQualityError(f"reachable_from ({point[0]}, {point[1]}) m is not in a free truth cell: "
                              f"cell ({row}, {col}) holds {truth.data[row, col]}")
    labels, _ = ndimage.label(free, structure=EIGHT_CONNECTED)
    return np.asarray(labels == labels[row, col])


def reference_walls(truth: OccupancyGrid, free: np.ndarray) -> np.ndarray:
    """Occupied truth cells that are 8-neighbours of a cell of ``free``."""
    return occupied_cells(truth) & ndimage.binary_dilation(free, structure=EIGHT_CONNECTED)


def _f1(precision: float, recall: float) -> float:
    total = precision + recall
    return 0.0 if total == 0 else 2.0 * precision * recall / total


def _free_coverage(estimate: OccupancyGrid, truth: OccupancyGrid, ref_free: np.ndarray,
                   map_to_world: PoseLike) -> float:
    rows, cols = np.nonzero(ref_free)
    e_rows, e_cols = cells_of(estimate, cell_centers_xy(truth, rows, cols), map_to_world)
    inside = in_grid(estimate, e_rows, e_cols)
    covered = free_cells(estimate)[e_rows[inside], e_cols[inside]].sum()
    return float(covered) / rows.size


def compare_maps(estimate: OccupancyGrid, truth: OccupancyGrid, map_to_world: PoseLike = (0.0, 0.0, 0.0),
                 reachable_from: Sequence[float] | None = None, tolerance_cells: int = 1) -> MapQuality:
    """Score ``estimate`` (in its map frame) against ``truth`` (in the world).

    ``map_to_world`` is the estimate's map frame in the world (x, y, yaw); ``reachable_from``
    (world x, y) restricts the reference to the free space the robot can reach, so the
    outer faces of outer walls and solid interiors don't count. Wall matches are allowed
    ``tolerance_cells`` truth cells of Chebyshev distance.

    * precision: estimated occupied cells near any truth occupied cell / all estimated
      occupied cells (those outside the truth grid count as wrong); 0 when the estimate
      has no occupied cell, and then recall and f1 are 0 too.
    * recall: reference wall cells near an estimated occupied cell / reference wall cells.
    * free_coverage: reference free cells whose centre lands on an estimated free cell.
    * wall distance: from the truth cell each estimated occupied cell lands in to the
      nearest truth occupied cell centre (m; 0 on a truth wall), mean and 95th percentile;
      cells outside the truth grid are left out (``outside_occupied_cells`` counts them).

    Raises:
        MapQualityError: ``reachable_from`` not in a free truth cell, a bad ``tolerance_cells``
            or ``map_to_world``, or a truth without any occupied cell next to (reachable) free space.
    """
    tolerance = _check_tolerance(tolerance_cells)
    _check_pose(map_to_world)
    truth_occupied = occupied_cells(truth)
    ref_free = reference_free(truth, reachable_from)
    true_walls = reference_walls(truth, ref_free)
    if not true_walls.any():
        raise MapQualityError(f"the truth grid ({truth.height}×{truth.width} cells) has no occupied cell next to "
                              f"free space (reachable_from {reachable_from!r})")
    near_truth = near(truth_occupied, tolerance)

    rows, cols = np.nonzero(occupied_cells(estimate))
    t_rows, t_cols = cells_of(truth, cell_centers_xy(estimate, rows, cols, map_to_world))
    inside = in_grid(truth, t_rows, t_cols)
    t_rows, t_cols = t_rows[inside], t_cols[inside]
    hit = np.zeros(truth.data.shape, dtype=bool)
    hit[t_rows, t_cols] = True
    correct = near_truth[t_rows, t_cols]

    precision = float(correct.sum()) / rows.size if rows.size else 0.0
    recall = float(near(hit, tolerance)[true_walls].mean()) if rows.size else 0.0
    distance = ndimage.distance_transform_edt(~truth_occupied, sampling=truth.resolution)[t_rows, t_cols]
    return MapQuality(
        precision=precision, recall=recall, f1=_f1(precision, recall),
        free_coverage=_free_coverage(estimate, truth, ref_free, map_to_world),
        mean_wall_distance_m=float(distance.mean()) if distance.size else None,
        wall_distance_p95_m=float(np.percentile(distance, 95)) if distance.size else None,
        estimated_occupied_cells=int(rows.size), outside_occupied_cells=int((~inside).sum()),
        reference_wall_cells=int(true_walls.sum()), reference_free_cells=int(ref_free.sum()),
        true_walls=true_walls, matched_walls=hit & near_truth, false_walls=hit & ~near_truth)

