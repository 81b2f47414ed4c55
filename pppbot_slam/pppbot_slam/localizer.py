"""Localization in a saved pose graph: slam_toolbox's localization mode, without ROS.

slam_toolbox calls it *elastic pose-graph localization* (its README; ``localization_slam_toolbox_node``,
``slam_toolbox_localization.cpp``, and Karto's ``Mapper::ProcessLocalization`` and
``ProcessAgainstNodesNearBy``). The same steps, with the same parameters:

* A serialized pose graph (``.posegraph``, :mod:`pppbot_slam.serialization`) is loaded and not
  changed: its keyframes, their scans and the map drawn from them stay as they were mapped.
* The first scan, and the first after a new pose is given (``/initialpose``, or
  ``deserialize_map`` with ``LOCALIZE_AT_POSE``), is placed at that pose and matched against the
  saved keyframes near it (:meth:`Localizer.relocalize`).
* A later scan is taken when odometry moved ``minimum_travel_distance`` or turned
  ``minimum_travel_heading`` since the last one. It is predicted through the current
  ``map → odom`` and matched against the saved keyframes near it and the rolling buffer: the last
  ``scan_buffer_size`` localized scans. A scan that matched well (:data:`BUFFER_RESPONSE`) joins
  the buffer and the oldest leaves it, so what the robot localizes against follows what it sees
  now (a moved pallet) while the saved graph never grows.
* ``map → odom`` is the last localized scan's map pose composed with the inverse of its odometry
  pose, as in mapping.

Where pppbot's differs: slam_toolbox adds each localization scan to the graph as a node, links it
to the previous one and, by loop closure, to saved nodes, and optimises the whole graph; here
each scan is matched at once against the saved keyframes' hits (and the buffer's), so every
localized pose is tied to the map directly and nothing saved can move. The matching is the
mapper's (:class:`~pppbot_slam.matcher.ScanMatcher` with ``correlation_search_space_*``, the wider
search over every heading after a poor match, corridors kept on odometry along their length:
:func:`~pppbot_slam.mapper.observable_only`), and so are its thresholds: a match below
``link_match_minimum_response_fine`` keeps odometry's prediction, and after
:data:`~pppbot_slam.mapper.LOST_KEYFRAMES` such scans in a row the localizer is lost until a
match reaches ``loop_match_minimum_response_fine``.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from pppbot_common.maps import OccupancyGrid
from pppbot_common.se2 import PoseLike, finite_pose, se2_apply, se2_compose, se2_inverse, wrap_angles
from pppbot_slam.errors import LocalizerError
from pppbot_slam.likelihood_field import rotate
from pppbot_slam.mapper import (
    HEALTH_WINDOW,
    LOST_KEYFRAMES,
    MIN_MATCH_POINTS,
    ODOMETRY_ONLY_COVARIANCE,
    RECOVERY_MARGIN,
    RECOVERY_RESPONSE,
    Mapper,
    observable_only,
    required_response,
    scan_hits,
    within_reach,
)
from pppbot_slam.matcher import MatchResult, ScanMatcher
from pppbot_slam.occupancy import ScanRays

#: Saved keyframes a scan is matched against: the nearest this many within
#: ``scan_buffer_maximum_scan_distance`` (slam_toolbox matches a relocalized scan against the one
#: nearest node and then closes loops with chains around it; a few keyframes around cover the same
#: walls, seen from where the map was made).
MAP_KEYFRAMES = 12
#: A localized scan joins the rolling buffer only when it matched this well (the mapper's bar for a
#: running match it takes without searching wider, :data:`~pppbot_slam.mapper.RECOVERY_RESPONSE`).
#: The buffer is matched against: a scan that fit the map only just (clutter, a crowd) would draw
#: the next such scans to itself and away from the map. Scans of random clutter in the ring corridor
#: of ``tests/pppbot_slam/test_localizer.py`` fit the map at about 0.2, and with every matched scan
#: buffered the next ones fit each other at 0.42-0.47; the corridor's walls match at 0.8-0.9.
BUFFER_RESPONSE = RECOVERY_RESPONSE


@dataclass(frozen=True)
class LocalizedScan:
    """A scan of the rolling buffer: its odometry and map poses (x, y, yaw) and its hits and their
    normals in the map ((K, 2) each)."""

    stamp_s: float
    odom_pose: np.ndarray
    pose: np.ndarray
    points: np.ndarray
    normals: np.ndarray


@dataclass(frozen=True)
class LocalizedPose:
    """What one taken scan gave: the base's map pose (x m, y m, yaw rad), its covariance (3 × 3 in x,
    y, yaw of the map frame), the match response, and how it was placed: ``matched`` (else by
    odometry, or at the given pose), ``relocalized`` (at a given pose), ``recovered`` (by the search
    over every heading); ``lost`` is the state after it, ``lost_changed`` whether that changed."""

    stamp_s: float
    pose: np.ndarray
    covariance: np.ndarray
    response: float
    matched: bool
    relocalized: bool
    recovered: bool
    lost: bool
    lost_changed: bool
    required_response: float


class Localizer:
    """Localizes scans in ``graph`` (a loaded pose graph, read only), starting at ``start_pose``
    (x, y, yaw in the map; None: the graph's first keyframe, slam_toolbox's dock).

    Raises:
        LocalizerError: an empty graph, or a start pose that is not three finite numbers.
    """

    def __init__(self, graph: Mapper, start_pose: PoseLike | None = None) -> None:
        if not graph.keyframes:
            raise LocalizerError("the pose graph has no keyframes to localize against")
        self.graph = graph
        self.settings = graph.settings
        self.sensor_offset = np.asarray(graph.sensor_offset, dtype=float).copy()  # the live lidar's mounting
        usable = [k for k in graph.keyframes if k.drawn and len(k.points)]
        self._keyframe_xy = np.array([graph.map_pose(k.index)[:2] for k in usable]).reshape(-1, 2)
        self._keyframe_hits = [(np.asarray(se2_apply(graph.map_pose(k.index), k.points)),
                                rotate(k.normals, float(graph.map_pose(k.index)[2]))) for k in usable]
        self.buffer: deque[LocalizedScan] = deque(maxlen=self.settings.scan_buffer_size)
        self._anchor: tuple[np.ndarray, np.ndarray] | None = None  # the last taken scan's odometry and map poses
        self.pending: np.ndarray | None = None  # where the next scan is placed (a given pose)
        self.scans = 0  # scans taken
        self.unmatched = 0  # in a row, with something to match
        self.responses: list[float] = []  # the last HEALTH_WINDOW matches'
        self.last_response = 0.0
        self.relocalizations = 0
        self.recoveries = 0
        self.relocalize(graph.map_pose(0) if start_pose is None else start_pose)

    # ------------------------------------------------------------------ state
    @property
    def localized(self) -> bool:
        """Whether a scan has been taken since the graph was loaded (``map → odom`` is known)."""
        return self._anchor is not None

    @property
    def lost(self) -> bool:
        return self.unmatched >= LOST_KEYFRAMES

    @property
    def required_response(self) -> float:
        return required_response(self.settings, self.lost)

    def map_to_odom(self) -> np.ndarray | None:
        """The map → odom transform (x, y, yaw); None until the first scan is taken."""
        if self._anchor is None:
            return None
        odom, pose = self._anchor
        return np.asarray(se2_compose(pose, se2_inverse(odom)))

    def predict(self, odom_pose: PoseLike) -> np.ndarray | None:
        """The base's map pose for an odometry pose through the current map → odom (None before
        the first scan)."""
        map_to_odom = self.map_to_odom()
        return None if map_to_odom is None else np.asarray(se2_compose(map_to_odom, odom_pose))

    def relocalize(self, pose: PoseLike) -> None:
        """Place the next scan at ``pose`` (x, y, yaw in the map) and match it from there: the
        rolling buffer is cleared (slam_toolbox's ``/initialpose``).

        Raises:
            LocalizerError: not three finite numbers.
        """
        self.pending = finite_pose(pose, "the pose to localize at", LocalizerError)
        self.buffer.clear()
        self.unmatched = 0

    def clear_buffer(self) -> None:
        """Forget the rolling buffer (slam_toolbox's ``clear_localization_buffer``); the next scans
        match the saved keyframes alone until the buffer fills again."""
        self.buffer.clear()

    def health(self) -> dict[str, float | int | bool]:
        """How localization goes (the node's diagnostics)."""
        return {"keyframes": len(self.graph.keyframes), "localized": self.localized, "lost": self.lost,
                "scans": self.scans, "buffered_scans": len(self.buffer), "unmatched_scans": self.unmatched,
                "last_response": round(self.last_response, 3),
                "mean_response": round(float(np.mean(self.responses)), 3) if self.responses else 0.0,
                "relocalizations": self.relocalizations, "recoveries": self.recoveries}

    def grid(self, frame_id: str = "map") -> OccupancyGrid:
        """The saved graph's map (its keyframes at their saved poses; localization scans are not drawn)."""
        return self.graph.grid(frame_id)

    # ------------------------------------------------------------------ scans
    def moved_enough(self, odom_pose: np.ndarray) -> bool:
        """Whether odometry moved ``minimum_travel_distance`` or turned ``minimum_travel_heading``
        since the last taken scan (always, for the first and for one at a given pose)."""
        if self._anchor is None or self.pending is not None:
            return True
        motion = se2_compose(se2_inverse(self._anchor[0]), odom_pose)
        s = self.settings
        return bool(np.hypot(motion[0], motion[1]) >= s.minimum_travel_distance
                    or abs(float(wrap_angles(motion[2]))) >= s.minimum_travel_heading)

    def process(self, stamp_s: float, odom_pose: PoseLike, rays: ScanRays,
                sensor_offset: PoseLike | None = None) -> LocalizedPose | None:
        """Take a scan (``rays`` in the lidar frame) with the base's odometry pose at its stamp and the
        lidar's mounting on the base (default: as when the graph was mapped); None when odometry has
        not moved enough since the last one.

        Raises:
            LocalizerError: a non-finite odometry pose or sensor offset.
        """
        odom = finite_pose(odom_pose, "the odometry pose", LocalizerError)
        if sensor_offset is not None:
            self.sensor_offset = finite_pose(sensor_offset, "the sensor offset", LocalizerError)
        if not self.moved_enough(odom):
            return None
        s = self.settings
        relocalizing = self.pending is not None
        predicted = self.pending if self.pending is not None else self.predict(odom)
        assert predicted is not None  # localized, or a pose is pending
        points, normals = scan_hits(rays, self.sensor_offset, s.max_laser_range)
        near = within_reach(points, rays, self.sensor_offset, s.max_laser_range)
        was_lost, required = self.lost, self.required_response
        result, recovered = self._match(points[near], normals[near], predicted)
        matched = result is not None and result.response >= required
        pose, covariance = predicted.copy(), ODOMETRY_ONLY_COVARIANCE
        if matched and result is not None:
            travel = 0.0 if self._anchor is None or relocalizing else float(
                np.hypot(*(predicted[:2] - self._anchor[1][:2])))
            pose, covariance, _ = observable_only(result.pose, result.covariance, predicted, travel)
        self.last_response = result.response if result is not None else 0.0
        if result is not None:
            self.responses = (self.responses + [self.last_response])[-HEALTH_WINDOW:]
            self.unmatched = 0 if matched else self.unmatched + 1
        self.recoveries += recovered
        self.relocalizations += relocalizing
        self.scans += 1
        self.pending = None
        self._anchor = (odom, pose)
        if matched and self.last_response >= BUFFER_RESPONSE:
            self.buffer.append(LocalizedScan(stamp_s, odom, pose, np.asarray(se2_apply(pose, points)),
                                             rotate(normals, float(pose[2]))))
        return LocalizedPose(stamp_s, pose, covariance, self.last_response, matched, relocalizing, recovered,
                             self.lost, self.lost != was_lost, required)

    def references(self, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """What a scan at ``pose`` is matched against: the hits (and normals) in the map of the
        :data:`MAP_KEYFRAMES` saved keyframes nearest to it and of the buffered scans, all within
        ``scan_buffer_maximum_scan_distance``; (K, 2) each."""
        reach = self.settings.scan_buffer_maximum_scan_distance
        distance = np.hypot(*(self._keyframe_xy - pose[:2]).T)
        nearest = [int(i) for i in np.argsort(distance)[:MAP_KEYFRAMES] if distance[i] <= reach]
        pieces = [self._keyframe_hits[i] for i in nearest]
        pieces += [(b.points, b.normals) for b in self.buffer if np.hypot(*(b.pose[:2] - pose[:2])) <= reach]
        if not pieces:
            return np.zeros((0, 2)), np.zeros((0, 2))
        return np.vstack([p for p, _ in pieces]), np.vstack([n for _, n in pieces])

    def _match(self, points: np.ndarray, normals: np.ndarray, predicted: np.ndarray) -> tuple[MatchResult | None, bool]:
        """The scan matched around ``predicted`` (None: nothing to match, or too few hits), and
        whether the search over every heading found it."""
        world, world_normals = self.references(predicted)
        if len(world) < MIN_MATCH_POINTS or len(points) < MIN_MATCH_POINTS:
            return None, False
        s = self.settings
        result = ScanMatcher(world, s.matcher, world_normals).match(points, predicted, normals)
        if result.response < RECOVERY_RESPONSE:
            wide = ScanMatcher(world, s.recovery_matcher, world_normals).match(points, predicted, normals)
            if wide.response >= result.response + RECOVERY_MARGIN:
                return wide, True
        return result, False
