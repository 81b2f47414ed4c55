"""A 2D costmap: uint8 costs on a grid in a frame, static or rolling with the robot."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pppbot_common.maps import OccupancyGrid
from pppbot_nav.costmap.costs import to_occupancy
from pppbot_nav.errors import CostmapError


@dataclass
class Costmap:
    """``costs[row, col]``, row 0 at ``origin`` y (the bottom), as nav_msgs/OccupancyGrid lays cells out."""

    costs: np.ndarray  # uint8 (height, width)
    resolution: float  # m per cell
    origin: tuple[float, float]  # x, y of cell (0, 0)'s corner in frame_id
    frame_id: str = "map"

    def __post_init__(self) -> None:
        self.costs = np.asarray(self.costs, dtype=np.uint8)
        if self.costs.ndim != 2 or min(self.costs.shape) < 1:
            raise CostmapError(f"costmap cells must be a non-empty 2D array, not shape {self.costs.shape}")
        if not (math.isfinite(self.resolution) and self.resolution > 0):
            raise CostmapError(f"costmap resolution must be a positive number of metres, not {self.resolution}")

    @classmethod
    def filled(cls, width_m: float, height_m: float, resolution: float, origin: tuple[float, float],
               value: int, frame_id: str = "map") -> Costmap:
        """A costmap of ``width_m`` × ``height_m`` (rounded to whole cells) with every cell ``value``.

        Raises:
            CostmapError: a size or resolution that is not a positive number.
        """
        if not (resolution > 0 and width_m > 0 and height_m > 0):
            raise CostmapError(f"costmap size {width_m} × {height_m} m at {resolution} m must be positive")
        shape = (max(1, round(height_m / resolution)), max(1, round(width_m / resolution)))
        return cls(np.full(shape, value, dtype=np.uint8), resolution, origin, frame_id)

    @property
    def height(self) -> int:
        return int(self.costs.shape[0])

    @property
    def width(self) -> int:
        return int(self.costs.shape[1])

    def cell_of(self, x: np.ndarray | float, y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """(row, col) of points; may be outside the grid."""
        col = np.floor((np.asarray(x, dtype=float) - self.origin[0]) / self.resolution).astype(int)
        row = np.floor((np.asarray(y, dtype=float) - self.origin[1]) / self.resolution).astype(int)
        return row, col

    def inside(self, row: np.ndarray, col: np.ndarray) -> np.ndarray:
        return (row >= 0) & (row < self.height) & (col >= 0) & (col < self.width)

    def cell_centres(self) -> tuple[np.ndarray, np.ndarray]:
        """x and y of every cell centre, each (height, width)."""
        xs = self.origin[0] + (np.arange(self.width) + 0.5) * self.resolution
        ys = self.origin[1] + (np.arange(self.height) + 0.5) * self.resolution
        return np.meshgrid(xs, ys)

    def cost_at(self, x: np.ndarray | float, y: np.ndarray | float, outside: int) -> np.ndarray:
        """Costs at points; ``outside`` for points off the grid."""
        row, col = self.cell_of(x, y)
        ok = self.inside(row, col)
        return np.where(ok, self.costs[np.where(ok, row, 0), np.where(ok, col, 0)], outside).astype(np.uint8)

    def recentre(self, x: float, y: float, fill: int) -> None:
        """Move a rolling window so that (x, y) is at its centre, snapped to whole cells: cells still
        inside keep their costs, cells that come in get ``fill``."""
        res = self.resolution
        new_col0 = math.floor((x - self.width * res / 2.0) / res + 1e-9)
        new_row0 = math.floor((y - self.height * res / 2.0) / res + 1e-9)
        old_col0 = round(self.origin[0] / res)
        old_row0 = round(self.origin[1] / res)
        dc, dr = new_col0 - old_col0, new_row0 - old_row0
        if dc == 0 and dr == 0:
            return
        moved = np.full_like(self.costs, fill)
        h, w = self.costs.shape
        if abs(dr) < h and abs(dc) < w:
            src = self.costs[max(dr, 0):h + min(dr, 0), max(dc, 0):w + min(dc, 0)]
            moved[max(-dr, 0):h + min(-dr, 0), max(-dc, 0):w + min(-dc, 0)] = src
        self.costs = moved
        self.origin = (new_col0 * res, new_row0 * res)

    def to_occupancy_grid(self) -> OccupancyGrid:
        """The costmap as a nav_msgs/OccupancyGrid is published (Nav2's cost translation)."""
        return OccupancyGrid(to_occupancy(self.costs), self.resolution, (self.origin[0], self.origin[1], 0.0),
                             self.frame_id)
