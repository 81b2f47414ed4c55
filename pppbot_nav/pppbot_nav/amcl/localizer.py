"""AMCL without ROS: odometry and scans in, a pose estimate and the map → odom correction out.

:class:`Localizer` is what Nav2's ``amcl`` node does between its callbacks: it keeps the
particle filter, applies the motion model for the odometry since the last filter update,
weighs the particles with the laser model once the robot has moved ``update_min_d``
(either axis, in the odometry frame) or turned ``update_min_a`` (or when forced: the
first scan, a new initial pose, a no-motion update request), resamples every
``resample_interval`` updates, and reports the heaviest cluster. Until an initial pose
is set (or global localization asked for) it does nothing.
"""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field

import numpy as np

from pppbot_common.maps import OccupancyGrid
from pppbot_common.se2 import finite_pose, se2_compose, se2_inverse, wrap_angle, wrap_angles
from pppbot_nav.amcl.filter import Cluster, FilterSettings, ParticleFilter, uniform_poses
from pppbot_nav.amcl.laser import LaserModelType, LaserSettings, MapField, Scan, laser_model
from pppbot_nav.amcl.motion import MotionNoise, RobotModel, motion_model
from pppbot_nav.amcl.refine import ScanFitter
from pppbot_nav.errors import AmclError, OffTheMap

#: Global localization's search grid: position step (m) and headings over a turn, scored
#: this many poses at a time.
GLOBAL_STEP_M = 0.25
GLOBAL_HEADINGS = 60
GLOBAL_CHUNK_POSES = 60000
#: The heaviest cluster's share of the weight from which the filter counts as settled on it.
SETTLED_WEIGHT = 0.9
#: Global localization settles on its heaviest cluster only if the whole scan fits the map there
#: this well (:meth:`ScanFitter.fit_fraction`); a cluster that holds the weight but fits worse is an
#: alias of the place, and the particles are searched for again with the scan of that moment, at
#: most :data:`GLOBAL_RESEARCHES` times (then the filter goes on as Nav2's would).
GLOBAL_SETTLE_FIT = 0.9
GLOBAL_RESEARCHES = 10
#: Standard deviations (m, m, rad) of the particles redrawn around a refined estimate.
REFINED_SPREAD = np.array([0.02, 0.02, 0.01])
#: Odometry that moved less than this (m, rad) since the last fit between updates is standing
#: still: the fit is not made again (it would only follow the scan's noise), as Nav2's AMCL
#: does not update below ``update_min_d`` / ``update_min_a``.
TRACK_STILL = (1e-3, 1e-3)


class LocalizerMode(enum.Enum):
    """Where the localizer is: no pose yet, tracking one, or in global localization."""

    UNINITIALIZED = "no pose yet"
    TRACKING = "tracking"
    SEARCH_PENDING = "global localization: the next scan places the particles"
    SETTLING = "global localization: until one hypothesis fits the whole scan"


@dataclass(frozen=True)
class LocalizerSettings:
    filter: FilterSettings = field(default_factory=FilterSettings)
    laser: LaserSettings = field(default_factory=LaserSettings)
    laser_model_type: LaserModelType = LaserModelType.LIKELIHOOD_FIELD
    robot_model_type: RobotModel = RobotModel.DIFFERENTIAL
    motion_noise: MotionNoise = field(default_factory=MotionNoise)
    update_min_d: float = 0.25
    update_min_a: float = 0.2
    resample_interval: int = 1
    refine_estimate: bool = True  # polish the estimate with every beam (pppbot_nav.amcl.refine)
    #: After each update, this share of the particles is redrawn around a refined estimate
    #: (sensor resetting, Lenser & Veloso 2000, with the scan fit as the sensor's pose).
    refined_particle_fraction: float = 0.1


@dataclass(frozen=True)
class Update:
    """One filter update: the estimate (heaviest cluster) and ``map_to_odom`` that puts
    the robot there, both at the scan's time."""

    estimate: Cluster
    map_to_odom: np.ndarray
    resampled: bool
    refined: bool = False  # the estimate's mean is the scan fit's, not the particles'
    #: Global localization let go of a cluster whose place the scan did not fit: (its mean,
    #: the share of end points that fitted); the particles were searched for again.
    alias: tuple[np.ndarray, float] | None = None


class Localizer:
    def __init__(self, settings: LocalizerSettings, grid: OccupancyGrid, rng: np.random.Generator) -> None:
        """Raises AmclError: bad filter settings, or a map without free space."""
        self.settings = settings
        self.rng = rng
        self.filter = ParticleFilter(settings.filter)
        self.motion = motion_model(settings.robot_model_type, settings.motion_noise)
        self.set_map(grid)
        self.mode = LocalizerMode.UNINITIALIZED
        self._odom: np.ndarray | None = None  # odometry pose at the last filter update
        self._force = False
        self._researches_left = 0
        self._updates = 0
        self.last: Update | None = None
        #: Where odometry was at the last fit between updates, and the update it started from.
        self._tracked: tuple[np.ndarray, Update] | None = None

    def set_map(self, grid: OccupancyGrid) -> None:
        """Localize on ``grid`` from now on (particles are kept; Nav2 re-initialises on a new map
        only when asked to).

        Raises:
            AmclError: the map has no free cell, or a rotated origin.
        """
        self.field = MapField(grid)
        self.laser = laser_model(self.settings.laser_model_type, self.field, self.settings.laser)
        self.fitter = ScanFitter(self.field)
        self._free_xy = self.field.free_cell_centres()

    def reconfigure(self, settings: LocalizerSettings) -> None:
        """Go on with new ``settings`` (a runtime parameter change), keeping the particles and the
        last estimate; the next scan updates the filter.

        Raises:
            AmclError: bad filter settings (nothing is changed then).
        """
        fresh = ParticleFilter(settings.filter)
        fresh.particles, fresh.weights = self.filter.particles, self.filter.weights
        self.settings = settings
        self.filter = fresh
        self.motion = motion_model(settings.robot_model_type, settings.motion_noise)
        self.set_map(self.field.grid)
        self._force = True

    # -------------------------------------------------------------- initial poses
    def set_initial_pose(self, mean: np.ndarray, covariance: np.ndarray) -> None:
        """Particles around ``mean`` (x, y, yaw in the map) with the 3 × 3 ``covariance``; the next
        scan updates the filter whether or not the robot moved.

        Beyond Nav2, which takes any pose: one whose mean lies outside the map, or whose spread
        (the larger of x's and y's standard deviations) is wider than the map is across, is
        refused, and the particles stay as they were. A stranger's message there would leave the
        robot localized nowhere; the way to search the whole map is ``global_localization``.

        Raises:
            AmclError: a non-finite pose, a covariance that is not positive semi-definite, a pose
                outside the map or a spread wider than it.
        """
        self._check_on_map(np.asarray(mean, dtype=float), np.asarray(covariance, dtype=float))
        self.filter.init_gaussian(mean, covariance, self.rng)
        self._initialized()

    def _check_on_map(self, mean: np.ndarray, covariance: np.ndarray) -> None:
        """Raises OffTheMap: ``mean`` outside the map, or a spread wider than the map (only for a
        finite pose and covariance: the filter names the others)."""
        grid = self.field.grid
        x0, x1, y0, y1 = grid.extent
        edge = 0.5 * grid.resolution  # a pose typed on the map's edge is on it, whatever the rounding of x1, y1
        if mean.shape == (3,) and np.isfinite(mean).all() and not (x0 - edge <= mean[0] <= x1 + edge
                                                                    and y0 - edge <= mean[1] <= y1 + edge):
            raise OffTheMap(f"an initial pose at ({mean[0]:.6g}, {mean[1]:.6g}) lies outside the map "
                            f"(x {x0:.2f} to {x1:.2f} m, y {y0:.2f} to {y1:.2f} m)")
        if covariance.shape == (3, 3) and np.isfinite(covariance).all():
            across = math.hypot(x1 - x0, y1 - y0)
            spread = math.sqrt(max(covariance[0, 0], covariance[1, 1], 0.0))
            if spread > across:
                raise OffTheMap(f"an initial pose's spread (a standard deviation of {spread:.6g} m) is wider than "
                                f"the map ({across:.2f} m across): to search the whole map, call "
                                f"reinitialize_global_localization")

    def global_localization(self) -> None:
        """Particles spread uniformly over the map's free space (``reinitialize_global_localization``).

        Beyond Nav2: the next scan places them. Every pose of a grid over the free space
        (:data:`GLOBAL_STEP_M`, :data:`GLOBAL_HEADINGS` headings) is scored with the laser model,
        and the ``max_particles`` best, jittered within their grid cell, become the particles.
        Uniform particles alone rarely put one near enough to the robot for the laser model to
        tell it from the many half-fitting places of a maze. Once one cluster holds the weight,
        it is taken only if the whole scan fits the map there (:data:`GLOBAL_SETTLE_FIT`);
        otherwise the search is made again with the scan of that moment.
        """
        self.filter.init_uniform(self._free_xy, self.field.grid.resolution, self.rng)
        self._initialized()
        self.mode = LocalizerMode.SEARCH_PENDING
        self._researches_left = GLOBAL_RESEARCHES

    @property
    def initialized(self) -> bool:
        """Whether it has particles to update: a pose was given or global localization asked for."""
        return self.mode is not LocalizerMode.UNINITIALIZED

    def forget_pose(self) -> None:
        """No pose from now on, until one is given or global localization asked for (a new map
        that does not hold the last one): scans are not used and nothing is published."""
        self.mode = LocalizerMode.UNINITIALIZED
        self.last = None
        self._tracked = None

    def _initialized(self) -> None:
        self.mode = LocalizerMode.TRACKING
        self._force = True
        self._odom = None
        self.last = None

    def request_nomotion_update(self) -> None:
        """Update the filter on the next scan even if the robot has not moved."""
        self._force = True

    def random_poses(self, count: int, rng: np.random.Generator) -> np.ndarray:
        return uniform_poses(self._free_xy, self.field.grid.resolution, count, rng)

    # -------------------------------------------------------------------- update
    def moved_enough(self, odom_pose: np.ndarray) -> bool:
        """Whether the odometry since the last update passes ``update_min_d`` / ``update_min_a``."""
        if self._odom is None:
            return True
        d = np.asarray(odom_pose, dtype=float) - self._odom
        s = self.settings
        return abs(d[0]) > s.update_min_d or abs(d[1]) > s.update_min_d or abs(wrap_angle(d[2])) > s.update_min_a

    def update(self, odom_pose: np.ndarray, scan: Scan, full_scan: Scan | None = None) -> Update | None:
        """Process one scan taken at odometry pose ``odom_pose`` (base in the odometry frame):
        ``scan`` has the beams the particles are weighed with, ``full_scan`` (default ``scan``)
        the beams the estimate is refined with.

        Returns the new estimate when the filter updated, None when not (not initialised, or the
        robot has not moved enough since the last update).

        Raises:
            AmclError: a non-finite odometry pose.
        """
        odom_pose = finite_pose(odom_pose, "an odometry pose", AmclError)
        if not self.initialized:
            return None
        if not (self._force or self.moved_enough(odom_pose)):
            return None
        if self.mode is LocalizerMode.SEARCH_PENDING:
            self._search(scan)
        elif self._odom is not None:
            self.motion.sample(self.filter.particles, self._odom, odom_pose, self.rng)
        self._odom = odom_pose.copy()
        self._force = False
        self.filter.update_sensor(self.laser.likelihoods(self.filter.particles, scan))
        self._updates += 1
        resampled = self._updates % max(1, self.settings.resample_interval) == 0
        # Before resampling, on the weighted set. Nav2 takes its clusters after resampling, when
        # every weight is equal; the weighted set has the same mean in expectation, without
        # the resampling's draw noise.
        estimate = self.filter.estimate()
        if resampled:
            self.filter.resample(self.rng, self.random_poses)
        refined = None
        alias: tuple[np.ndarray, float] | None = None
        whole = scan if full_scan is None else full_scan
        if self.mode is LocalizerMode.SETTLING and estimate.weight >= SETTLED_WEIGHT:
            # Global localization is down to one hypothesis: settled if the scan fits there,
            # otherwise that place only looks alike (a maze), and the particles start over.
            polished = self.fitter.refine(estimate.mean, whole)
            at = estimate.mean if polished is None else polished
            fit = self.fitter.fit_fraction(at, whole)
            if fit >= GLOBAL_SETTLE_FIT or not self._researches_left:
                self.mode = LocalizerMode.TRACKING
            else:
                alias = (at.copy(), fit)
                self._researches_left -= 1
                self._search(scan)
                self.filter.update_sensor(self.laser.likelihoods(self.filter.particles, scan))
                estimate = self.filter.estimate()
        if self.settings.refine_estimate:
            refined = self.fitter.refine(estimate.mean, whole)
            if refined is not None:
                estimate = Cluster(estimate.weight, refined, estimate.covariance)
                if estimate.weight >= SETTLED_WEIGHT and self.mode is LocalizerMode.TRACKING:
                    # Only once one hypothesis holds the weight: while several compete (global
                    # localization, a symmetric place), redrawing would crown the leader early.
                    self._reset_around(refined)
        self.last = Update(estimate, self.map_to_odom(estimate.mean, odom_pose), resampled, refined is not None,
                           alias)
        return self.last

    def track(self, odom_pose: np.ndarray, full_scan: Scan) -> np.ndarray | None:
        """Between filter updates, with ``refine_estimate``: the map → odom that fits ``full_scan``
        (taken at ``odom_pose``) to the map, starting from the last one, so that odometry's drift
        since the last update is taken out at every scan; None when there is nothing to refine
        or the fit is not trusted (the last map → odom stands). The particles are left alone.
        """
        if not (self.settings.refine_estimate and self.initialized and self.last is not None):
            return None
        odom_pose = np.asarray(odom_pose, dtype=float)
        if self._tracked is not None and self._tracked[1] is self.last:
            moved = se2_compose(se2_inverse(self._tracked[0]), odom_pose)
            if math.hypot(moved[0], moved[1]) < TRACK_STILL[0] and abs(moved[2]) < TRACK_STILL[1]:
                return None
        refined = self.fitter.refine(se2_compose(self.last.map_to_odom, odom_pose), full_scan)
        if refined is not None:
            self.last = Update(Cluster(self.last.estimate.weight, refined, self.last.estimate.covariance),
                               self.map_to_odom(refined, odom_pose), resampled=False, refined=True)
        self._tracked = (odom_pose.copy(), self.last)
        return None if refined is None else self.last.map_to_odom

    def _search(self, scan: Scan) -> None:
        """Global localization's particles: the best poses for ``scan`` (see :meth:`global_localization`)."""
        self.mode = LocalizerMode.SETTLING
        self.filter.particles = self._best_poses(scan)
        self.filter.weights = np.full(len(self.filter.particles), 1.0 / len(self.filter.particles))

    def _best_poses(self, scan: Scan) -> np.ndarray:
        """The ``max_particles`` best-scoring poses of a grid over the free space, jittered within their cell."""
        res = self.field.grid.resolution
        stride = max(1, round(GLOBAL_STEP_M / res))
        free = self._free_xy
        keys = np.floor(free / (stride * res)).astype(np.int64)
        _, first = np.unique(keys, axis=0, return_index=True)
        cells = free[np.sort(first)]
        step = stride * res
        headings = np.linspace(-np.pi, np.pi, GLOBAL_HEADINGS, endpoint=False)
        count = self.settings.filter.max_particles
        best_p = np.full(0, -np.inf)
        best = np.zeros((0, 3))
        chunk = max(1, GLOBAL_CHUNK_POSES // GLOBAL_HEADINGS)
        for start in range(0, len(cells), chunk):
            xy = cells[start:start + chunk]
            poses = np.column_stack([np.repeat(xy, GLOBAL_HEADINGS, axis=0), np.tile(headings, len(xy))])
            p = self.laser.likelihoods(poses, scan)
            best_p, best = np.concatenate([best_p, p]), np.vstack([best, poses])
            if len(best_p) > count:
                keep = np.argpartition(-best_p, count)[:count]
                best_p, best = best_p[keep], best[keep]
        jitter = self.rng.uniform(-0.5, 0.5, size=best.shape) * (step, step, 2 * np.pi / GLOBAL_HEADINGS)
        poses = best + jitter
        poses[:, 2] = wrap_angles(poses[:, 2])
        return poses

    def _reset_around(self, pose: np.ndarray) -> None:
        count = int(round(self.settings.refined_particle_fraction * len(self.filter)))
        if count > 0:
            poses = pose + self.rng.normal(0.0, 1.0, size=(count, 3)) * REFINED_SPREAD
            poses[:, 2] = wrap_angles(poses[:, 2])
            self.filter.replace_some(poses, self.rng)

    @staticmethod
    def map_to_odom(map_pose: np.ndarray, odom_pose: np.ndarray) -> np.ndarray:
        """The map → odom transform that puts the base, at ``odom_pose`` in odom, at ``map_pose``."""
        return se2_compose(map_pose, se2_inverse(odom_pose))


def covariance_from_message(covariance: np.ndarray | list[float]) -> np.ndarray:
    """The x, y, yaw 3 × 3 block of a ROS 6 × 6 pose covariance (row-major, 36 values).

    Raises:
        AmclError: not 36 finite values.
    """
    c = np.asarray(covariance, dtype=float)
    if c.size != 36 or not np.isfinite(c).all():
        raise AmclError("a pose covariance must be 36 finite numbers (6 × 6, row-major)")
    full = c.reshape(6, 6)
    return full[np.ix_((0, 1, 5), (0, 1, 5))]


def covariance_to_message(covariance: np.ndarray) -> list[float]:
    """A 3 × 3 x, y, yaw covariance as the 36 values of a ROS pose covariance."""
    full = np.zeros((6, 6))
    full[np.ix_((0, 1, 5), (0, 1, 5))] = covariance
    return [float(v) for v in full.ravel()]

