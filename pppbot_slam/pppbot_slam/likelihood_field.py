"""The likelihood grid a scan is scored on, and the surface normals that split it by facing.

A :class:`LikelihoodField` holds ``exp(-d² / 2σ²)`` around map points, per surface-normal
class when the points have normals, with the lookups the matcher's search makes: single
cells, the maximum of a block of cells (branch and bound's bound) and cubic-spline
interpolation between cell centres (Gauss-Newton's smooth response). No ROS here.
"""
from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from pppbot_slam.errors import MatcherError

#: Branch and bound bounds shifts in blocks of BLOCK × BLOCK cells (:attr:`LikelihoodField.block_max`).
BLOCK = 4
#: Surface-normal classes: a scan point is scored only against map points whose surface
#: faces the same way (normals within ±90° of its class's direction), so the two faces of
#: a thin wall, seen from either side, are never matched onto each other.
NORMAL_CLASSES = 4
#: Rows of zeros around each class's grid in the spline coefficients: a clipped point's
#: cubic support (two cells either side) stays inside its own class.
SPLINE_BORDER = 3


def normal_classes(normals_xy: np.ndarray) -> np.ndarray:
    """The class (0 … NORMAL_CLASSES−1) of each unit normal: the nearest of the class directions."""
    angle = np.arctan2(normals_xy[..., 1], normals_xy[..., 0])
    return np.asarray(np.round(angle / (2 * np.pi / NORMAL_CLASSES)).astype(np.int64) % NORMAL_CLASSES)


def scan_normals(points_xy: np.ndarray, sensor_xy: np.ndarray | None = None, max_gap_m: float = 0.3) -> np.ndarray:
    """Unit surface normals of consecutive scan points (in scan order), facing the sensor.

    Each point's tangent runs between its neighbours; where a neighbour is more than
    ``max_gap_m`` away (an edge, a gap), the normal falls back to the direction to the sensor.
    """
    points = np.asarray(points_xy, dtype=float).reshape(-1, 2)
    sensor = np.zeros(2) if sensor_xy is None else np.asarray(sensor_xy, dtype=float)
    to_sensor = sensor - points
    view = to_sensor / np.maximum(np.linalg.norm(to_sensor, axis=1, keepdims=True), 1e-9)
    if len(points) < 3:
        return view
    before = np.vstack([points[:1], points[:-1]])
    after = np.vstack([points[1:], points[-1:]])
    gaps = np.maximum(np.linalg.norm(points - before, axis=1), np.linalg.norm(after - points, axis=1))
    tangent = after - before
    normal = np.stack([-tangent[:, 1], tangent[:, 0]], axis=1)
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    normal = np.where(length > 1e-9, normal / np.maximum(length, 1e-9), view)
    normal *= np.where((normal * view).sum(axis=1) < 0, -1.0, 1.0)[:, None]
    return np.asarray(np.where((gaps > max_gap_m)[:, None], view, normal))


def rotate(vectors: np.ndarray, yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.stack([c * vectors[..., 0] - s * vectors[..., 1], s * vectors[..., 0] + c * vectors[..., 1]], axis=-1)


class LikelihoodField:
    """``exp(-d²/2σ²)`` on a grid of ``resolution_m`` around map points (world frame).

    With the map points' surface ``normals_xy``, there is one field per normal class:
    class ``j`` keeps a cell's value only where the nearest map point faces within
    ±90° of class ``j``'s direction, and is 0 elsewhere.
    """

    def __init__(self, points_xy: np.ndarray, resolution_m: float, smear_m: float, margin_m: float,
                 normals_xy: np.ndarray | None = None) -> None:
        points = np.asarray(points_xy, dtype=float).reshape(-1, 2)
        finite = np.isfinite(points).all(axis=1)
        points = points[finite]
        if not len(points):
            raise MatcherError("no map points to match against")
        self.resolution_m = resolution_m
        self.smear_m = smear_m
        self.origin = np.floor((points.min(axis=0) - margin_m) / resolution_m) * resolution_m
        shape = np.ceil((points.max(axis=0) + margin_m - self.origin) / resolution_m).astype(int) + 1
        cells = np.floor((points - self.origin) / resolution_m).astype(int)
        height, width = shape[1], shape[0]  # [row = y, col = x]
        flat = cells[:, 1] * width + cells[:, 0]
        count = np.bincount(flat, minlength=height * width)
        hit = (count > 0).reshape(height, width)
        # Each hit cell keeps the mean of its points, and distances are measured to that
        # point, not to the cell: rasterising alone would shift walls by up to half a cell.
        mean = np.stack([np.bincount(flat, points[:, k], height * width) for k in (0, 1)], axis=-1)
        has = count > 0
        mean[has] = mean[has] / count[has, None]
        nearest = ndimage.distance_transform_edt(~hit, return_distances=False, return_indices=True)
        near_flat = (nearest[0] * width + nearest[1]).ravel()
        dx = (self.origin[0] + (np.arange(width) + 0.5) * resolution_m)[None, :] - \
            mean[near_flat, 0].reshape(height, width)
        dy = (self.origin[1] + (np.arange(height) + 0.5) * resolution_m)[:, None] - \
            mean[near_flat, 1].reshape(height, width)
        values = np.exp((dx * dx + dy * dy) * (-0.5 / (smear_m * smear_m)))
        if normals_xy is None:
            self.values = values[None]
        else:
            normals = np.asarray(normals_xy, dtype=float).reshape(-1, 2)[finite]
            summed = np.stack([np.bincount(flat, normals[:, k], height * width) for k in (0, 1)], axis=-1)
            # the nearest map point's normal (summed over its cell)
            nx, ny = summed[near_flat, 0].reshape(height, width), summed[near_flat, 1].reshape(height, width)
            angles = np.arange(NORMAL_CLASSES) * (2 * np.pi / NORMAL_CLASSES)
            self.values = np.stack([values * ((nx * math.cos(a) + ny * math.sin(a)) > 0) for a in angles])
        self.height, self.width = height, width
        # Lookups gather from one flat array: each class's grid inside a border of zeros, so
        # a cell index clipped to the border reads 0 (outside the grid) without masking.
        self._cells = _with_zero_border(self.values, 1).ravel()
        self._spline: np.ndarray | None = None
        self._block_max: np.ndarray | None = None

    @property
    def spline(self) -> np.ndarray:
        """Cubic B-spline coefficients (made on first use) of the classes' grids stacked along
        the rows, each inside SPLINE_BORDER rows of zeros, so one ``map_coordinates`` call
        samples points of every class: a smooth response whose peak can lie between cell
        centres (bilinear interpolation peaks only at them, biasing by up to half a cell)."""
        if self._spline is None:
            tiles = np.pad(self.values, ((0, 0), (SPLINE_BORDER, SPLINE_BORDER), (0, 0)))
            self._spline = ndimage.spline_filter(tiles.reshape(-1, self.width), order=3, mode="constant")
        return self._spline

    @property
    def block_max(self) -> np.ndarray:
        """Per class, the maximum of the cells [r, r + BLOCK) × [c, c + BLOCK), stored at (r, c),
        flat as the lookups read it."""
        if self._block_max is None:
            # scipy centres an even window at index BLOCK // 2: shift it to start at (r, c)
            maxed = ndimage.maximum_filter(self.values, size=(1, BLOCK, BLOCK), mode="constant", cval=0.0)
            shift = BLOCK // 2
            starts = np.zeros_like(maxed)
            starts[:, :maxed.shape[1] - shift, :maxed.shape[2] - shift] = maxed[:, shift:, shift:]
            self._block_max = _with_zero_border(starts, 1).ravel()
        return self._block_max

    @property
    def classes(self) -> int:
        return len(self.values)

    def cells(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Integer (row, col) of world points; may be out of range."""
        ij = np.floor((xy - self.origin) / self.resolution_m).astype(np.int64)
        return ij[..., 1], ij[..., 0]

    def lookup(self, rows: np.ndarray, cols: np.ndarray, classes: np.ndarray | None = None,
               block_max: bool = False) -> np.ndarray:
        """Values at integer cells (in each point's normal class), or with ``block_max`` the
        maximum of the BLOCK × BLOCK cells from there; 0 outside the grid.

        ``rows``, ``cols`` and ``classes`` broadcast against each other (so a grid of shifts
        can be given as (K, R, 1) rows and (K, 1, C) columns).
        """
        source = self.block_max if block_max else self._cells
        stride = self.width + 2
        index = (np.clip(rows, -1, self.height) + 1) * stride + (np.clip(cols, -1, self.width) + 1)
        if classes is not None and self.classes > 1:
            index = index + classes * ((self.height + 2) * stride)
        return np.asarray(source[index])

    def interpolate(self, xy: np.ndarray, classes: np.ndarray | None = None) -> np.ndarray:
        """Values at world points (..., 2), cubic-spline interpolated between cell centres; 0 outside.

        ``classes`` gives each point's normal class (broadcast against ``xy[..., 0]``).
        """
        grid = (xy - self.origin) / self.resolution_m - 0.5
        rows = np.clip(grid[..., 1], -1.0, float(self.height)) + SPLINE_BORDER
        cols = np.clip(grid[..., 0], -1.0, float(self.width))
        if classes is not None and self.classes > 1:
            rows = rows + classes * (self.height + 2 * SPLINE_BORDER)
        rows, cols = np.broadcast_arrays(rows, cols)
        return np.asarray(ndimage.map_coordinates(self.spline, [rows.ravel(), cols.ravel()], order=3,
                                                  mode="constant", cval=0.0, prefilter=False)).reshape(rows.shape)


def _with_zero_border(grids: np.ndarray, width: int) -> np.ndarray:
    return np.pad(grids, ((0, 0), (width, width), (width, width)))
