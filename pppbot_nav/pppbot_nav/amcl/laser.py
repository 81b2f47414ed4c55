"""Laser models: how well a scan fits each particle's pose on the map (Nav2's ``nav2_amcl`` laser models).

* :class:`LikelihoodFieldModel` (``likelihood_field``, Thrun et al. §6.4): each beam's end
  point is scored by its distance ``d`` to the nearest occupied cell,
  ``pz = z_hit·exp(−d²/2σ²) + z_rand/range_max``, with ``d`` capped at
  ``laser_likelihood_max_dist`` and taken as that cap off the map; beams at or beyond
  the maximum range are skipped.
* :class:`BeamModel` (``beam``, §6.3): each beam's range is compared with the range
  ray-cast on the map from the particle (``z_hit`` Gaussian, ``z_short`` exponential
  for readings short of the map, ``z_max`` for max-range readings, ``z_rand`` uniform).

Both combine beams as Nav2 does, ``p = 1 + Σ pz³`` (a tempered product that keeps one bad beam
from zeroing a good pose), and return ``p`` per particle, to multiply into its weight.
Cells count as in Nav2's map conversion: 100 occupied, 0 free, anything else unknown.
"""
from __future__ import annotations

import enum
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from scipy import ndimage

from pppbot_common.maps import FREE, OCCUPIED, OccupancyGrid
from pppbot_nav.errors import AmclError

#: Sphere-tracing steps of the beam model's ray cast before a ray counts as reaching max range.
RAY_CAST_STEPS = 64


class LaserModelType(enum.Enum):
    """Nav2's ``laser_model_type`` values."""

    LIKELIHOOD_FIELD = "likelihood_field"
    BEAM = "beam"


@dataclass(frozen=True)
class LaserSettings:
    """Nav2's laser parameters (their names); ``laser_min_range``/``laser_max_range`` ≤ 0
    use the scan's own limits. ``beams_with_returns`` (pppbot's): pick the ``max_beams``
    among the beams that returned, not among all of them."""

    z_hit: float = 0.5
    z_short: float = 0.05
    z_max: float = 0.05
    z_rand: float = 0.5
    sigma_hit: float = 0.2
    lambda_short: float = 0.1
    laser_likelihood_max_dist: float = 2.0
    max_beams: int = 60
    laser_min_range: float = -1.0
    laser_max_range: float = 100.0
    beams_with_returns: bool = False


@dataclass(frozen=True)
class Scan:
    """The beams a laser model uses, in the robot's base frame: ``ranges`` (m, ``range_max``
    for no return), ``bearings`` (rad) and where they start, ``origin`` (x, y of the laser)."""

    ranges: np.ndarray
    bearings: np.ndarray
    origin: tuple[float, float]
    range_max: float

    @classmethod
    def from_laser(cls, ranges: np.ndarray, angle_min: float, angle_increment: float, range_min: float,
                   range_max: float, laser_pose: tuple[float, float, float], settings: LaserSettings,
                   max_beams: int | None = None) -> Scan:
        """Nav2's beam selection: every ``(n − 1) // (max_beams − 1)``-th beam (``max_beams``
        from the settings unless given); ranges under ``range_min`` and non-finite ones become
        ``range_max`` (no return); ``laser_min_range``/``laser_max_range``, when positive, narrow
        the scan's own limits. With the settings' ``beams_with_returns`` (and ``max_beams`` not
        given), ``max_beams`` spread evenly over the beams that returned instead: where most
        beams see nothing (a cone field), Nav2's pick keeps few of the hits, and the likelihood
        field has nothing to weigh the particles with.

        Raises:
            AmclError: no beams, or limits that are not finite or out of order.
        """
        ranges = np.asarray(ranges, dtype=float).ravel()
        if ranges.size == 0:
            raise AmclError("a scan with no ranges")
        if not (math.isfinite(angle_min) and math.isfinite(angle_increment)):
            raise AmclError(f"scan angles must be finite: angle_min {angle_min}, angle_increment {angle_increment}")
        low = max(range_min, settings.laser_min_range) if settings.laser_min_range > 0 else range_min
        high = min(range_max, settings.laser_max_range) if settings.laser_max_range > 0 else range_max
        if not (math.isfinite(low) and math.isfinite(high) and 0 <= low < high):
            raise AmclError(f"scan range limits must satisfy 0 ≤ min < max and be finite: {low} … {high}")
        beams = settings.max_beams if max_beams is None else max_beams
        step = max(1, (ranges.size - 1) // max(1, beams - 1))
        index = np.arange(0, ranges.size, step)
        if settings.beams_with_returns and max_beams is None:
            returned = np.flatnonzero(np.isfinite(ranges) & (ranges > low) & (ranges < high))
            if returned.size > beams:
                index = returned[np.linspace(0, returned.size - 1, beams).round().astype(int)]
            elif returned.size:
                index = returned
        picked = ranges[index]
        picked = np.where(np.isfinite(picked) & (picked > low), np.minimum(picked, high), high)
        bearings = laser_pose[2] + angle_min + index * angle_increment
        return cls(picked, bearings, (laser_pose[0], laser_pose[1]), high)

    def end_points(self, particles: np.ndarray, hits_only: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """World x and y ((N, B)) of each beam's end from each particle; with ``hits_only``,
        only the beams short of ``range_max``."""
        use = self.ranges < self.range_max if hits_only else np.ones(self.ranges.size, dtype=bool)
        r, b = self.ranges[use], self.bearings[use]
        bx, by = self.origin[0] + r * np.cos(b), self.origin[1] + r * np.sin(b)
        c, s = np.cos(particles[:, 2:3]), np.sin(particles[:, 2:3])
        return particles[:, 0:1] + c * bx - s * by, particles[:, 1:2] + s * bx + c * by


def laser_scans(ranges: np.ndarray, angle_min: float, angle_increment: float, range_min: float,
                range_max: float, laser_pose: tuple[float, float, float], settings: LaserSettings,
                full: bool = True) -> tuple[Scan, Scan | None]:
    """What a LaserScan gives the localizer: the ``max_beams`` beams the particles are weighed
    with, and (``full``) every beam, for the refinement; None when not wanted.

    Raises:
        AmclError: a malformed scan (see :meth:`Scan.from_laser`).
    """
    args = (ranges, angle_min, angle_increment, range_min, range_max, laser_pose, settings)
    return Scan.from_laser(*args), Scan.from_laser(*args, max_beams=len(ranges)) if full else None


class MapField:
    """A map prepared for the laser models: the distance (m) from each cell to the nearest occupied
    cell, and to the nearest cell that stops a ray (occupied or unknown)."""

    def __init__(self, grid: OccupancyGrid) -> None:
        if grid.origin[2] != 0.0:
            raise AmclError(f"map origin yaw must be 0 (a rotated map is not supported), not {grid.origin[2]}")
        self.grid = grid
        occupied = grid.data == OCCUPIED
        self.free = grid.data == FREE
        if not self.free.any():
            raise AmclError("the map has no free cell to put a particle in")
        res = grid.resolution
        self.occupied_distance_m: np.ndarray = (np.asarray(ndimage.distance_transform_edt(~occupied)) * res
                                                if occupied.any() else np.full(grid.data.shape, np.inf))
        self.blocked_distance_m: np.ndarray = np.asarray(ndimage.distance_transform_edt(self.free)) * res

    def flat_index(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Index into a raveled grid of each point, or ``height·width`` (one past the end) off the map."""
        row, col = self.grid.cell_of(x, y)
        h, w = self.grid.data.shape
        inside = (row >= 0) & (row < h) & (col >= 0) & (col < w)
        return np.where(inside, row * w + col, h * w)

    def free_cell_centres(self) -> np.ndarray:
        """(M, 2) x, y of the free cells' centres: where particles may be drawn uniformly."""
        xs, ys = self.grid.cell_centers()
        return np.column_stack([xs[self.free], ys[self.free]])


class LaserModel(Protocol):
    def likelihoods(self, particles: np.ndarray, scan: Scan) -> np.ndarray:
        """``p`` ≥ 1 of each particle ((N, 3) poses in the map) for ``scan``."""


class LikelihoodFieldModel:
    def __init__(self, field: MapField, settings: LaserSettings) -> None:
        self.field = field
        self.settings = settings
        self._tables: dict[float, np.ndarray] = {}

    def _table(self, range_max: float) -> np.ndarray:
        """``pz³`` of every cell, raveled, with one more entry for off the map."""
        table = self._tables.get(range_max)
        if table is None:
            s = self.settings
            d = np.append(np.minimum(self.field.occupied_distance_m.ravel(), s.laser_likelihood_max_dist),
                          s.laser_likelihood_max_dist)
            pz = s.z_hit * np.exp(-d * d / (2.0 * s.sigma_hit ** 2)) + s.z_rand / range_max
            table = self._tables[range_max] = (pz ** 3).astype(np.float32)
        return table

    def likelihoods(self, particles: np.ndarray, scan: Scan) -> np.ndarray:
        x, y = scan.end_points(particles)
        cubes = self._table(scan.range_max)[self.field.flat_index(x, y)]
        return 1.0 + cubes.sum(axis=1, dtype=np.float64)


class BeamModel:
    def __init__(self, field: MapField, settings: LaserSettings) -> None:
        self.field = field
        self.settings = settings
        self._blocked = np.append(field.blocked_distance_m.ravel(), 0.0)  # off the map stops a ray

    def ray_cast(self, particles: np.ndarray, scan: Scan) -> np.ndarray:
        """(N, B) range from each particle along each beam to the first occupied or unknown cell
        (``range_max`` if none): sphere tracing on the distance field, to within one cell."""
        res = self.field.grid.resolution
        c, s = np.cos(particles[:, 2:3]), np.sin(particles[:, 2:3])
        ox = particles[:, 0:1] + c * scan.origin[0] - s * scan.origin[1]
        oy = particles[:, 1:2] + s * scan.origin[0] + c * scan.origin[1]
        heading = particles[:, 2:3] + scan.bearings[None, :]
        dx, dy = np.cos(heading), np.sin(heading)
        t = np.zeros(heading.shape)
        # Cell centres' distance, less a half-diagonal each for the point's and the wall's cells.
        margin = res * math.sqrt(2.0)
        for _ in range(RAY_CAST_STEPS):
            clearance = self._blocked[self.field.flat_index(ox + t * dx, oy + t * dy)]
            if not (clearance > 0).any():
                break
            t = np.where(clearance > 0, t + np.maximum(clearance - margin, 0.5 * res), t)
            t = np.minimum(t, scan.range_max)
            if ((clearance == 0) | (t >= scan.range_max)).all():
                break
        return np.minimum(t, scan.range_max)

    def likelihoods(self, particles: np.ndarray, scan: Scan) -> np.ndarray:
        st = self.settings
        expected = self.ray_cast(particles, scan)
        obs = scan.ranges[None, :]
        z = obs - expected
        pz = st.z_hit * np.exp(-z * z / (2.0 * st.sigma_hit ** 2))
        pz += np.where(z < 0, st.z_short * st.lambda_short * np.exp(-st.lambda_short * obs), 0.0)
        at_max = obs >= scan.range_max
        pz += np.where(at_max, st.z_max, st.z_rand / scan.range_max)
        return 1.0 + (pz ** 3).sum(axis=1)


def laser_model(kind: LaserModelType, field: MapField, settings: LaserSettings) -> LaserModel:
    """The laser model registered under ``kind``."""
    models: dict[LaserModelType, Callable[[MapField, LaserSettings], LaserModel]] = {
        LaserModelType.LIKELIHOOD_FIELD: LikelihoodFieldModel, LaserModelType.BEAM: BeamModel}
    return models[kind](field, settings)
