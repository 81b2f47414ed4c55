"""Log-odds occupancy grid drawn from laser scans at (optimised) sensor poses: rebuilt whole, or
kept between map updates by :class:`GridCache`.

The update follows OctoMap (Hornung et al., Autonomous Robots 34(3), 2013, §III-C): a
cell is updated at most ONCE per scan, a "hit" if some beam ends in it, else a "miss"
if some beam passes through it (a cell crossed by two beams gets one miss, and a cell
hit by one beam and crossed by another only the hit). So a scan weighs the same
whatever its beam count and cells near the sensor are not saturated by hundreds of
beams. With the defaults (miss 0.4, free threshold 0.25) a cell needs three free
observations to read free; one hit reads occupied.

Cells lie on a lattice anchored at world (0, 0): cell (ix, iy) covers
[ix·res, (ix+1)·res) × [iy·res, (iy+1)·res). The reported extent is the hull of every
cell a scan needed, rounded outwards to blocks of ``BLOCK_CELLS``, so grids built from
the same scans in any order have the same origin and shape (the log-odds agree up to
float rounding, and exactly while no cell reaches the clamp, which is order dependent).
Storage grows with a margin beyond that extent so most scans do not re-allocate.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields
from typing import NamedTuple

import numpy as np

from pppbot_common.maps import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from pppbot_common.se2 import PoseLike, finite_pose, se2_apply, se2_compose, wrap_angles
from pppbot_slam.errors import OccupancyError

#: The reported grid extent is a multiple of this many cells, aligned to world (0, 0).
BLOCK_CELLS = 16


def _logit(p: float) -> float:
    return math.log(p / (1.0 - p))


@dataclass(frozen=True)
class OccupancySettings:
    """How scans become a map. Probabilities are unitless, in (0, 1).

    Raises:
        OccupancyError: on construction, naming the first bad field (see :meth:`validate`).
    """

    resolution_m: float = 0.05  # cell side
    max_range_m: float = 20.0  # beams are used up to this range (slam_toolbox's max_laser_range)
    hit_probability: float = 0.7  # p(occupied | a beam ends in the cell)
    miss_probability: float = 0.4  # p(occupied | a beam passes through the cell)
    clamp_log_odds: float = 5.0  # |log-odds| never exceeds this
    occupied_threshold: float = 0.65  # p above this → 100
    free_threshold: float = 0.25  # p below this → 0; between, or never observed → -1

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        """Raise OccupancyError naming the first bad field, its value and what is allowed."""
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise OccupancyError(f"{f.name} must be a finite number, not {value!r}")
        for name in ("resolution_m", "max_range_m", "clamp_log_odds"):
            if getattr(self, name) <= 0:
                raise OccupancyError(f"{name} must be positive, not {getattr(self, name)}")
        for name in ("hit_probability", "miss_probability", "occupied_threshold", "free_threshold"):
            if not 0.0 < getattr(self, name) < 1.0:
                raise OccupancyError(f"{name} must be in (0, 1), not {getattr(self, name)}")
        if not self.miss_probability < 0.5 < self.hit_probability:
            bad = "hit_probability" if self.hit_probability <= 0.5 else "miss_probability"
            raise OccupancyError(f"{bad} is {getattr(self, bad)}: need hit_probability > 0.5 > miss_probability")
        if not self.free_threshold < self.occupied_threshold:
            raise OccupancyError(f"free_threshold ({self.free_threshold}) must be below "
                                 f"occupied_threshold ({self.occupied_threshold})")

    @property
    def hit_log_odds(self) -> float:
        return _logit(self.hit_probability)

    @property
    def miss_log_odds(self) -> float:
        return _logit(self.miss_probability)


class BeamClasses(NamedTuple):
    """What each beam of a scan does: ``used`` beams clear ``length_m`` (0 if unused) and,
    if ``hit``, mark the cell at that range occupied."""

    used: np.ndarray  # (N,) bool
    hit: np.ndarray  # (N,) bool
    length_m: np.ndarray  # (N,) float


@dataclass(frozen=True, eq=False)
class ScanRays:
    """One laser scan in the SENSOR frame: unit ``directions`` (N, 2) and ``ranges_m`` (N,).

    Ranges follow REP-117: +inf = no return within range_max, -inf = closer than
    range_min, NaN = invalid. Arrays are stored read-only.

    Raises:
        OccupancyError: mismatched shapes, non-finite directions, bad range limits.
    """

    directions: np.ndarray
    ranges_m: np.ndarray
    range_min_m: float = 0.0
    range_max_m: float = math.inf

    def __post_init__(self) -> None:
        ranges = np.array(self.ranges_m, dtype=float).ravel()
        directions = np.array(self.directions, dtype=float)
        if directions.size == 0 and ranges.size == 0:
            directions = directions.reshape(0, 2)
        if directions.shape != (ranges.size, 2):
            raise OccupancyError(f"directions must be ({ranges.size}, 2) for {ranges.size} ranges, "
                                 f"not shape {directions.shape}")
        norms = np.hypot(directions[:, 0], directions[:, 1])
        if not np.all(np.abs(norms - 1.0) < 1e-6):  # also rejects NaN and inf
            worst = norms[np.argmax(np.abs(norms - 1))]
            raise OccupancyError(f"directions must be finite unit vectors; one has norm {worst}")
        if not (math.isfinite(self.range_min_m) and self.range_min_m >= 0):
            raise OccupancyError(f"range_min_m must be a finite number >= 0, not {self.range_min_m}")
        if not self.range_max_m > self.range_min_m:  # also rejects NaN
            raise OccupancyError(f"range_max_m ({self.range_max_m}) must exceed range_min_m ({self.range_min_m})")
        directions.setflags(write=False)
        ranges.setflags(write=False)
        object.__setattr__(self, "directions", directions)
        object.__setattr__(self, "ranges_m", ranges)

    @classmethod
    def from_laser(cls, angle_min_rad: float, angle_increment_rad: float, ranges: Sequence[float] | np.ndarray,
                   range_min_m: float, range_max_m: float) -> ScanRays:
        """Rays of a sensor_msgs/LaserScan: beam i points at angle_min + i·increment (rad).

        Raises:
            OccupancyError: as the constructor.
        """
        ranges_m = np.asarray(ranges, dtype=float).ravel()
        angles_rad = angle_min_rad + angle_increment_rad * np.arange(ranges_m.shape[0])
        return cls(np.stack([np.cos(angles_rad), np.sin(angles_rad)], axis=-1), ranges_m, range_min_m, range_max_m)

    @property
    def beam_count(self) -> int:
        return int(self.ranges_m.shape[0])

    def classify(self, max_range_m: float) -> BeamClasses:
        """Classify beams against limit = min(range_max_m, max_range_m).

        * finite r with range_min <= r < limit: free up to r, the cell at r occupied;
        * r >= limit (including +inf): free up to limit, nothing occupied;
        * r < range_min, -inf, NaN: ignored.
        """
        limit_m = min(self.range_max_m, max_range_m)
        r = self.ranges_m
        used = r >= self.range_min_m  # False for NaN and -inf
        hit = used & (r < limit_m)
        length_m = np.where(hit, r, np.where(used, limit_m, 0.0))
        return BeamClasses(used, hit, length_m)


class LogOddsGrid:
    """An incrementally growing log-odds grid (float32 log-odds, bool observed mask).

    Accessors return copies cropped to the reported extent: row 0 is the lowest y.
    """

    def __init__(self, settings: OccupancySettings | None = None) -> None:
        self._settings = settings if settings is not None else OccupancySettings()
        self._log_odds: np.ndarray = np.zeros((0, 0), dtype=np.float32)  # storage, beyond the extent
        self._observed: np.ndarray = np.zeros((0, 0), dtype=bool)
        self._store_lo: np.ndarray = np.zeros(2, dtype=np.int64)  # world cell (ix, iy) of storage[0, 0]
        self._extent: np.ndarray | None = None  # world cells [ix_lo, iy_lo, ix_hi, iy_hi), block aligned
        self._scan_count = 0

    @property
    def settings(self) -> OccupancySettings:
        return self._settings

    @property
    def scan_count(self) -> int:
        """Number of scans integrated so far."""
        return self._scan_count

    @classmethod
    def build(cls, settings: OccupancySettings, poses_xyyaw: np.ndarray | Sequence[PoseLike],
              scans: Sequence[ScanRays], sensor_in_base_xyyaw: PoseLike = (0.0, 0.0, 0.0)) -> LogOddsGrid:
        """The full rebuild: scans[k] taken at poses[k] ∘ sensor_in_base (m, m, rad), in order;
        the same as ``add_scan`` one by one.

        ``poses_xyyaw`` (K, 3) are (optimised) base poses in the map frame when
        ``sensor_in_base_xyyaw`` is the laser mount, or sensor poses when it is zero.

        Raises:
            OccupancyError: poses not (K, 3) for K scans, or a non-finite pose.
        """
        poses = np.asarray(poses_xyyaw, dtype=float)
        poses = poses.reshape(0, 3) if poses.size == 0 else poses
        if poses.shape != (len(scans), 3):
            raise OccupancyError(f"poses must be ({len(scans)}, 3) for {len(scans)} scans, not shape {poses.shape}")
        grid = cls(settings)
        for pose, scan in zip(se2_compose(poses, sensor_in_base_xyyaw), scans, strict=True):
            grid.add_scan(pose, scan)
        return grid

    def add_scan(self, sensor_pose_xyyaw: PoseLike, rays: ScanRays) -> None:
        """Integrate one scan taken at ``sensor_pose_xyyaw`` (m, m, rad in the map frame).

        Beams are sampled every <= resolution/2 from the sensor to their end (a cell the
        beam clips by less than that may be skipped); see :meth:`ScanRays.classify`.

        Raises:
            OccupancyError: a pose that is not three finite numbers.
        """
        pose = finite_pose(sensor_pose_xyyaw, "sensor pose", OccupancyError)
        res = self._settings.resolution_m
        beams = rays.classify(self._settings.max_range_m)
        used = np.flatnonzero(beams.used)
        dirs = se2_apply((0.0, 0.0, pose[2]), rays.directions[used])  # unit vectors on world axes
        length_cells = beams.length_m[used] / res
        counts = np.ceil(length_cells * 2.0).astype(np.intp) + 1  # sample step <= half a cell
        ends = np.cumsum(counts) - 1
        # Sample positions in cells relative to an integer anchor that keeps them all > 0, so
        # truncation is floor; float32 (~1e-7 relative) is good to ~1e-4 cell over 800 cells.
        sensor_cells = pose[:2] / res
        anchor = np.floor(sensor_cells) - np.ceil(length_cells.max(initial=0.0)) - 2.0
        start_rel = sensor_cells - anchor
        end_rel = (start_rel + dirs * length_cells[:, None]).astype(np.float32)
        step_rel = (dirs * (length_cells / np.maximum(counts - 1, 1))[:, None]).astype(np.float32)
        k = (np.arange(ends[-1] + 1 if used.size else 0, dtype=np.int32)
             - np.repeat((ends - counts + 1).astype(np.int32), counts)).astype(np.float32)
        cells = []
        for axis in (0, 1):
            rel = np.repeat(step_rel[:, axis], counts)
            rel *= k
            rel += np.float32(start_rel[axis])
            rel[ends] = end_rel[:, axis]  # exact end
            cells.append(rel.astype(np.intp))
        ix, iy = cells
        sensor_rel = np.floor(start_rel).astype(np.intp)
        lo_rel = np.array([ix.min(initial=sensor_rel[0]), iy.min(initial=sensor_rel[1])])
        hi_rel = np.array([ix.max(initial=sensor_rel[0]), iy.max(initial=sensor_rel[1])]) + 1
        lo, hi = lo_rel + anchor.astype(np.int64), hi_rel + anchor.astype(np.int64)
        self._grow(lo, hi)
        self._scan_count += 1
        if not used.size:
            return
        # One update per cell per scan, hits taking precedence: the cells the scan touched, found
        # in its window, then updated where they are stored (only those: a scan touches a few
        # percent of its window).
        rows, cols = hi_rel[1] - lo_rel[1], hi_rel[0] - lo_rel[0]
        flat = iy * cols
        flat += ix
        flat -= lo_rel[1] * cols + lo_rel[0]
        seen, occupied = np.zeros((2, rows * cols), dtype=bool)
        seen[flat] = True
        occupied[flat[ends[beams.hit[used]]]] = True
        touched = np.flatnonzero(seen)
        # Window cell (r, c) is storage cell (r + dr, c + dc): flat index r·S + c + dr·S + dc, S
        # the storage's columns (one-dimensional gathers and scatters are the fast ones).
        store_cols = self._log_odds.shape[1]
        row, col = np.divmod(touched, cols)
        row *= store_cols
        row += col
        row += (lo[1] - self._store_lo[1]) * store_cols + lo[0] - self._store_lo[0]
        log_odds, observed = self._log_odds.reshape(-1), self._observed.reshape(-1)  # views
        change = np.where(occupied[touched], np.float32(self._settings.hit_log_odds),
                          np.float32(self._settings.miss_log_odds))
        change += log_odds.take(row)
        clamp = np.float32(self._settings.clamp_log_odds)
        log_odds[row] = np.clip(change, -clamp, clamp, out=change)
        observed[row] = True

    def _grow(self, lo: np.ndarray, hi: np.ndarray) -> None:
        """Extend the reported extent to hold world cells [lo, hi); re-allocate storage if needed."""
        block_lo = np.floor_divide(lo, BLOCK_CELLS) * BLOCK_CELLS
        block_hi = -np.floor_divide(-hi, BLOCK_CELLS) * BLOCK_CELLS
        if self._extent is None:
            self._extent = np.concatenate([block_lo, block_hi])
        else:
            self._extent = np.concatenate([np.minimum(self._extent[:2], block_lo),
                                           np.maximum(self._extent[2:], block_hi)])
        store_hi = self._store_lo + np.array(self._log_odds.shape[::-1])
        if np.all(self._extent[:2] >= self._store_lo) and np.all(self._extent[2:] <= store_hi):
            return
        size = self._extent[2:] - self._extent[:2]
        margin = np.maximum(4 * BLOCK_CELLS, (size // 2 // BLOCK_CELLS) * BLOCK_CELLS)
        new_lo, new_hi = self._extent[:2] - margin, self._extent[2:] + margin
        log_odds = np.zeros((new_hi[1] - new_lo[1], new_hi[0] - new_lo[0]), dtype=np.float32)
        observed = np.zeros(log_odds.shape, dtype=bool)
        if self._log_odds.size:
            c0, r0 = self._store_lo - new_lo
            rows, cols = self._log_odds.shape
            log_odds[r0:r0 + rows, c0:c0 + cols] = self._log_odds
            observed[r0:r0 + rows, c0:c0 + cols] = self._observed
        self._log_odds, self._observed, self._store_lo = log_odds, observed, new_lo

    def _crop(self) -> tuple[slice, slice]:
        if self._extent is None:
            return slice(0, 0), slice(0, 0)
        c0, r0 = self._extent[:2] - self._store_lo
        c1, r1 = self._extent[2:] - self._store_lo
        return slice(int(r0), int(r1)), slice(int(c0), int(c1))

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, cols) of the reported grid."""
        rows, cols = self._crop()
        return rows.stop - rows.start, cols.stop - cols.start

    @property
    def bounds_m(self) -> tuple[float, float, float, float]:
        """(x_min, y_min, x_max, y_max) in m of the reported grid; all 0 before any scan."""
        if self._extent is None:
            return 0.0, 0.0, 0.0, 0.0
        x0, y0, x1, y1 = (float(v) * self._settings.resolution_m for v in self._extent)
        return x0, y0, x1, y1

    @property
    def observed(self) -> np.ndarray:
        """(rows, cols) bool: cells some scan updated."""
        return self._observed[self._crop()].copy()

    def log_odds(self) -> np.ndarray:
        """(rows, cols) float32 log-odds, 0 where never observed."""
        return self._log_odds[self._crop()].copy()

    def probabilities(self) -> np.ndarray:
        """(rows, cols) occupancy probability 1/(1+exp(-L)); 0.5 where never observed."""
        return 1.0 / (1.0 + np.exp(-self._log_odds[self._crop()].astype(np.float64)))

    def to_occupancy_grid(self, frame_id: str = "map") -> OccupancyGrid:
        """0 free (p < free_threshold) / 100 occupied (p > occupied_threshold) / -1 otherwise
        or never observed; origin (x, y, 0) m at the lower-left corner, row 0 = lowest y."""
        crop = self._crop()
        log_odds, observed = self._log_odds[crop], self._observed[crop]
        data = np.full(log_odds.shape, UNKNOWN, dtype=np.int8)
        data[observed & (log_odds > _logit(self._settings.occupied_threshold))] = OCCUPIED
        data[observed & (log_odds < _logit(self._settings.free_threshold))] = FREE
        x0, y0, _, _ = self.bounds_m
        return OccupancyGrid(data, self._settings.resolution_m, (x0, y0, 0.0), frame_id)


class GridCache:
    """A :class:`LogOddsGrid` kept between map updates, so that each update draws only the scans
    it has not drawn yet instead of every scan again.

    The grid stays as drawn while the scans it drew come first, in order, and each lies where it
    was drawn to within half a cell: the pose moved at most ``resolution / 2`` once its turn
    is counted at the scan's farthest beam end (``|Δxy| + reach·|Δyaw|``). Then every point of
    the scan's beams lies within half a cell of where a rebuild would put it (a cell it marks is
    at most one cell off), and the small corrections a pose graph makes while the robot goes
    over mapped ground cost nothing. Each pose is compared with the one it was drawn at, so
    small moves do not add up unseen.

    A larger move (a loop that bends the map) starts a redraw: a new grid that draws every scan
    at its pose, at most ``redraw_per_update`` scans per update, and replaces the kept one
    when it has drawn them all. A map of up to that many scans is redrawn within the update;
    a larger one over several, the kept grid (with new scans drawn on it) returned meanwhile,
    its moved scans where they were drawn (:attr:`stale` counts them). So no update draws
    more than about ``redraw_per_update`` scans beyond the new ones, however large the map.
    A scan that left the map or other settings draw every scan again within the update.

    The grid depends on the sequence of updates, so the same updates give the same grid: in
    lockstep, the same on every machine. For the grid of the poses as they are now (a saved
    map), use :meth:`LogOddsGrid.build`. Not thread-safe: one caller at a time.

    Raises:
        OccupancyError: ``redraw_per_update`` below 1.
    """

    def __init__(self, redraw_per_update: int = 100) -> None:
        if isinstance(redraw_per_update, bool) or not isinstance(redraw_per_update, int) or redraw_per_update < 1:
            raise OccupancyError(f"redraw_per_update must be an integer >= 1, not {redraw_per_update!r}")
        self.redraw_per_update = redraw_per_update
        self._grid: LogOddsGrid | None = None
        self._poses = np.zeros((0, 3))  # the sensor pose each drawn scan was drawn at, in order
        self._scans: list[ScanRays] = []
        self._reach_m = np.zeros(0)  # each drawn scan's farthest beam end from its sensor
        self._redraw: LogOddsGrid | None = None  # the grid being redrawn, its first scans drawn
        self._redraw_poses: list[np.ndarray] = []  # where the redraw drew each
        self.rebuilds = 0  # grids drawn whole so far (the first build counts as one)
        self.stale = 0  # scans the returned grid drew over half a cell from their pose

    def update(self, settings: OccupancySettings, sensor_poses: np.ndarray | Sequence[PoseLike],
               scans: Sequence[ScanRays]) -> LogOddsGrid:
        """The grid of ``scans`` at ``sensor_poses`` (as :meth:`LogOddsGrid.build` with no mount),
        with scans drawn before kept where they were drawn until a redraw has drawn them again.

        Raises:
            OccupancyError: as :meth:`LogOddsGrid.build`.
        """
        poses = np.asarray(sensor_poses, dtype=float)
        poses = poses.reshape(0, 3) if poses.size == 0 else poses
        try:
            if self._grid is None or self._replaced(settings, poses, scans):
                grid = LogOddsGrid.build(settings, poses, scans)
                self._keep(grid, poses, scans, np.array([self._reach(settings, s) for s in scans]))
                return grid
            drawn = len(self._scans)
            for pose, scan in zip(poses[drawn:], scans[drawn:], strict=True):
                self._grid.add_scan(pose, scan)
            self._poses = np.concatenate([self._poses, poses[drawn:]])
            self._scans += scans[drawn:]
            self._reach_m = np.concatenate([self._reach_m, [self._reach(settings, s) for s in scans[drawn:]]])
            moved = self._moved(settings, poses)
            if self._redraw is None and moved:
                self._redraw = LogOddsGrid(settings)
            if self._redraw is not None:
                start = len(self._redraw_poses)
                for pose, scan in zip(poses[start:start + self.redraw_per_update],
                                      scans[start:start + self.redraw_per_update], strict=True):
                    self._redraw.add_scan(pose, scan)
                    self._redraw_poses.append(pose)
                if len(self._redraw_poses) == len(scans):  # the same scans as kept: their reach too
                    self._keep(self._redraw, np.array(self._redraw_poses), scans, self._reach_m)
                    moved = self._moved(settings, poses)
            self.stale = moved
            return self._grid
        except BaseException:
            self._grid = None  # partly drawn: the next update starts over
            raise

    def _keep(self, grid: LogOddsGrid, poses: np.ndarray, scans: Sequence[ScanRays], reach_m: np.ndarray) -> None:
        """Keep ``grid``, which drew ``scans`` at ``poses``; any redraw under way is dropped."""
        self._grid, self._poses, self._scans, self._reach_m = grid, poses.copy(), list(scans), reach_m
        self._redraw, self._redraw_poses = None, []
        self.rebuilds += 1
        self.stale = 0

    @staticmethod
    def _reach(settings: OccupancySettings, scan: ScanRays) -> float:
        return float(scan.classify(settings.max_range_m).length_m.max(initial=0.0))

    def _replaced(self, settings: OccupancySettings, poses: np.ndarray, scans: Sequence[ScanRays]) -> bool:
        """Whether the drawn scans are no longer the first of ``scans`` or the settings changed."""
        drawn = len(self._scans)
        return (self._grid is None or self._grid.settings != settings or len(scans) < drawn
                or poses.shape != (len(scans), 3)
                or any(a is not b for a, b in zip(self._scans, scans[:drawn], strict=True)))

    def _moved(self, settings: OccupancySettings, poses: np.ndarray) -> int:
        """How many drawn scans lie more than half a cell from where they were drawn."""
        moved = poses[:len(self._scans)] - self._poses
        shift_m = np.hypot(moved[:, 0], moved[:, 1]) + self._reach_m * np.abs(wrap_angles(moved[:, 2]))
        return int(np.count_nonzero(shift_m > settings.resolution_m / 2))
