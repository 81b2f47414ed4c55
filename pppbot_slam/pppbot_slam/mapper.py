"""Online grid SLAM: keyframes by travel, scan-to-map matching, a pose graph with loop closures.

The flow of slam_toolbox's (Karto's) mapper, with its parameter names:

* A scan becomes a keyframe when the robot travelled ``minimum_travel_distance``
  or turned ``minimum_travel_heading`` since the last one (the first scan always).
* Its pose is predicted from odometry (the last keyframe's map pose composed with
  the odometry motion since) and corrected by matching against the running buffer:
  the hits of the last ``scan_buffer_size`` keyframes within
  ``scan_buffer_maximum_scan_distance``. A match below
  ``link_match_minimum_response_fine`` keeps the prediction.
* An edge joins it to the previous keyframe, with the matcher's covariance.
* Loop closure: keyframes older than the running chain within
  ``loop_search_maximum_distance``, in chains of at least
  ``loop_match_minimum_chain_size`` consecutive keyframes, are matched in a large
  window (coarse response ≥ ``loop_match_minimum_response_coarse`` and variance ≤
  ``loop_match_maximum_variance_coarse``), then finely (response ≥
  ``loop_match_minimum_response_fine``); the matches the graph can agree with become loop
  edges and the graph is optimised (:mod:`pppbot_slam.loops`).
* Along a direction its scan cannot pin (a corridor's length) a keyframe keeps odometry
  (:func:`observable_only`); hits near the range limit are not matched
  (:meth:`Mapper.within_reach`); five unmatched keyframes in a row and it is lost
  (:data:`LOST_KEYFRAMES`), says so in :meth:`Mapper.health`, and is found again only by a
  match as good as a loop closure's (``loop_match_minimum_response_fine``).
* ``map → odom`` is the latest keyframe's map pose composed with the inverse of its
  odometry pose; the grid is built from the optimised poses on request.

Poses of the robot are of its base frame; the lidar sits at ``sensor_offset`` in it.
No ROS here.
"""
from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from pppbot_common.maps import OccupancyGrid
from pppbot_common.se2 import PoseLike, finite_pose, se2_apply, se2_compose, se2_inverse, wrap_angles
from pppbot_slam.errors import MapperError
from pppbot_slam.likelihood_field import rotate, scan_normals
from pppbot_slam.loops import (
    REJECTIONS,
    LoopChain,
    LoopSearch,
    LoopSolution,
    in_frame_of,
    solve_loops,
)
from pppbot_slam.matcher import MatcherSettings, MatchResult, ScanMatcher
from pppbot_slam.occupancy import LogOddsGrid, OccupancySettings, ScanRays
from pppbot_slam.pose_graph import PoseGraph
from pppbot_slam.visibility import view_of

#: Covariance of an edge whose scan could not be matched: odometry alone (m², m², rad²).
ODOMETRY_ONLY_COVARIANCE = np.diag([0.1 ** 2, 0.1 ** 2, 0.05 ** 2])
#: Fewer hits than this and a scan is not matched (open space): odometry places it.
MIN_MATCH_POINTS = 10
#: A loop candidate chain searched without a match is searched again only this many keyframes later.
LOOP_RETRY_KEYFRAMES = 3
#: A running match below this response is searched again over every heading in a wider
#: window (``recovery_matcher``): a collision or a skid can turn the robot far beyond the
#: usual ±20° between two scans, and accepting the best pose inside that window would draw
#: the scan rotated into the map. The wider match is taken when it is this much better.
RECOVERY_RESPONSE = 0.5
RECOVERY_MARGIN = 0.1
#: A direction the scan does not pin (a corridor's length): the match's position variance along
#: it is this many times that across it, and at least DEGENERATE_MIN_STD_M². Along such a
#: direction the keyframe keeps odometry's prediction and its edge odometry's uncertainty.
DEGENERATE_RATIO = 10.0
DEGENERATE_MIN_STD_M = 0.08
#: Odometry's standard deviation along such a direction, per metre travelled (wheel slip is
#: about 1 %; this allows for five times that).
ODOMETRY_STD_PER_M = 0.05
#: This many keyframes in a row whose scans had something to match but did not match (response
#: below ``link_match_minimum_response_fine``) and the mapper is lost: it says so, and the
#: keyframes it places by odometry alone are left out of the map until a scan matches again.
#: Once lost, a match must reach ``loop_match_minimum_response_fine``: odometry no longer
#: vouches for the prediction, so finding the robot again is a relocalisation, and the best
#: pose of a window over scans of clutter can reach the running threshold by chance (a ring
#: of random hits matched a pillar 0.4 m away at 0.10).
LOST_KEYFRAMES = 5


def required_response(settings: MapperSettings, lost: bool) -> float:
    """The response a running match needs to be taken: the loop closure's when lost (see
    :data:`LOST_KEYFRAMES`), else the link's."""
    return settings.loop_match_minimum_response_fine if lost else settings.link_match_minimum_response_fine
#: Keyframes whose match responses the health report averages.
HEALTH_WINDOW = 20
#: Hits this close to the range limit are not matched (see :meth:`Mapper.within_reach`).
MATCH_RANGE_MARGIN_M = 1.0


@dataclass(frozen=True)
class MapperSettings:
    """slam_toolbox's parameter names and ppp_bot's values (mapper_params_online_async.yaml)."""

    resolution: float = 0.05
    max_laser_range: float = 20.0
    minimum_travel_distance: float = 0.5
    minimum_travel_heading: float = 0.5
    scan_buffer_size: int = 10
    scan_buffer_maximum_scan_distance: float = 10.0
    link_match_minimum_response_fine: float = 0.1
    do_loop_closing: bool = True
    loop_search_maximum_distance: float = 3.0
    loop_match_minimum_chain_size: int = 10
    loop_match_maximum_variance_coarse: float = 3.0
    loop_match_minimum_response_coarse: float = 0.35
    loop_match_minimum_response_fine: float = 0.45
    # pppbot's: loops over a partial overlap (see LoopSearch.run); 0: none. On the CARMEN logs
    # 10 m found more closures and mapped no better (benchmarks/RESULTS.md): off by default.
    loop_search_overlap_distance: float = 0.0
    loop_match_minimum_overlap: float = 0.2
    loop_match_minimum_response_overlap: float = 0.7
    # pppbot's, after Cartographer's constraint builder (see Mapper.global_loop_search): once the
    # robot has gone loop_search_global_after_distance (m) without a closure and the local search
    # has no chain near, the older keyframes within loop_search_global_distance (Cartographer's
    # max_constraint_distance, 15 m) are searched over global_loop_matcher's window (its
    # linear_search_window ±7 m and angular_search_window ±30°, unpenalised) and taken at a fine
    # response of loop_match_minimum_response_global; 0: no global search.
    loop_search_global_distance: float = 15.0
    loop_search_global_after_distance: float = 10.0
    loop_match_minimum_response_global: float = 0.55
    matcher: MatcherSettings = MatcherSettings()
    # loop_search_space_dimension 8.0 and its smear 0.03; searched coarsely at 0.1 m
    loop_matcher: MatcherSettings = MatcherSettings(search_size_m=8.0, coarse_resolution_m=0.1, smear_m=0.03,
                                                    coarse_points=100)
    global_loop_matcher: MatcherSettings = MatcherSettings(search_size_m=14.0, coarse_resolution_m=0.1, smear_m=0.03,
                                                           coarse_points=100, search_angle_rad=0.52,
                                                           minimum_distance_penalty=1.0, minimum_angle_penalty=1.0)
    # after a poor running match: every heading, ±0.75 m (see RECOVERY_RESPONSE)
    recovery_matcher: MatcherSettings = MatcherSettings(search_size_m=1.5, search_angle_rad=math.pi)

    def __post_init__(self) -> None:
        for name in ("resolution", "max_laser_range", "scan_buffer_maximum_scan_distance",
                     "loop_search_maximum_distance", "loop_match_maximum_variance_coarse"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise MapperError(f"{name} must be a positive number, not {value}")
        if not (math.isfinite(self.loop_search_overlap_distance) and self.loop_search_overlap_distance >= 0):
            raise MapperError("loop_search_overlap_distance must be 0 (no partial-overlap loops) or a positive "
                              f"number, not {self.loop_search_overlap_distance}")
        if not (math.isfinite(self.loop_search_global_distance) and self.loop_search_global_distance >= 0):
            raise MapperError("loop_search_global_distance must be 0 (no global loop search) or a positive "
                              f"number, not {self.loop_search_global_distance}")
        for name in ("minimum_travel_distance", "minimum_travel_heading", "loop_search_global_after_distance"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise MapperError(f"{name} must be a number >= 0, not {value}")
        for name in ("scan_buffer_size", "loop_match_minimum_chain_size"):
            if getattr(self, name) < 1:
                raise MapperError(f"{name} must be at least 1, not {getattr(self, name)}")
        for name in ("link_match_minimum_response_fine", "loop_match_minimum_response_coarse",
                     "loop_match_minimum_response_fine", "loop_match_minimum_overlap",
                     "loop_match_minimum_response_overlap", "loop_match_minimum_response_global"):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0 <= value <= 1):
                raise MapperError(f"{name} must be in [0, 1], not {value}")


@dataclass
class Keyframe:
    index: int
    stamp_s: float
    odom_pose: np.ndarray  # base in the odom frame when the scan was taken
    rays: ScanRays  # in the sensor frame
    points: np.ndarray  # (K, 2) hits in the base frame
    normals: np.ndarray  # (K, 2) their unit surface normals, facing the sensor
    session: int = 0  # odometry session: a continued map's new run starts a new one
    drawn: bool = True  # in the map (False: placed while the mapper was lost)


@dataclass
class LoopClosure:
    source: int  # the older keyframe
    target: int  # the new one
    response: float


@dataclass
class Mapper:
    settings: MapperSettings = MapperSettings()
    sensor_offset: np.ndarray = field(default_factory=lambda: np.zeros(3))  # lidar in the base frame
    keyframes: list[Keyframe] = field(default_factory=list)
    graph: PoseGraph = field(default_factory=PoseGraph)
    loop_closures: list[LoopClosure] = field(default_factory=list)
    last_response: float = 0.0
    session: int = 0  # the current odometry session
    #: loop chain (its first keyframe; whether it came within loop_search_maximum_distance, else it
    #: was tried on its overlap only) → keyframe that last tried it
    tried: dict[tuple[int, bool], int] = field(default_factory=dict)
    global_tried: int = -LOOP_RETRY_KEYFRAMES  # the keyframe that last searched globally
    rejected_closures: int = 0  # loop matches the graph could not agree with
    undone_closures: int = 0  # accepted loop closures that later closures showed to be wrong
    rejected_why: dict[str, int] = field(default_factory=dict)  # rejected_closures by reason (loops.REJECTIONS)
    largest_correction: np.ndarray = field(default_factory=lambda: np.zeros(2))  # m, rad: the most a solve moved
    unmatched: int = 0  # keyframes in a row with something to match that did not match (see LOST_KEYFRAMES)
    responses: list[float] = field(default_factory=list)  # the last HEALTH_WINDOW keyframes' match responses
    recoveries: int = 0  # running matches replaced by the wider search (see RECOVERY_RESPONSE)
    degenerate_matches: int = 0  # running matches that pinned only one direction (see observable_only)
    start_pose: np.ndarray | None = None  # where the current session's first keyframe is (continued maps)
    #: With True, :meth:`process` leaves loop closing to the caller (a loop-closing thread:
    #: :meth:`loop_search`, :meth:`LoopSearch.run`, :func:`solve_loops`, :meth:`merge_loops`).
    defer_loops: bool = False

    def snapshot(self) -> Mapper:
        """A copy to read (save, draw) while this one maps on; keyframes are shared (only their
        ``drawn`` flag ever changes)."""
        return Mapper(self.settings, self.sensor_offset.copy(), list(self.keyframes), self.graph.copy(),
                      list(self.loop_closures), self.last_response, session=self.session, tried=dict(self.tried),
                      global_tried=self.global_tried,
                      rejected_closures=self.rejected_closures, recoveries=self.recoveries,
                      degenerate_matches=self.degenerate_matches, undone_closures=self.undone_closures,
                      rejected_why=dict(self.rejected_why),
                      largest_correction=self.largest_correction.copy(), unmatched=self.unmatched,
                      responses=list(self.responses),
                      start_pose=None if self.start_pose is None else self.start_pose.copy(),
                      defer_loops=self.defer_loops)

    @property
    def lost(self) -> bool:
        """Whether the last :data:`LOST_KEYFRAMES` keyframes found nothing they matched."""
        return self.unmatched >= LOST_KEYFRAMES

    @property
    def required_response(self) -> float:
        return required_response(self.settings, self.lost)

    def health(self) -> dict[str, float | int | bool]:
        """How mapping goes: match responses, closures accepted, rejected and undone, the largest
        correction a closure made, whether the mapper is lost (the node's diagnostics)."""
        return {"keyframes": len(self.keyframes), "lost": self.lost, "unmatched_keyframes": self.unmatched,
                "keyframes_left_out": sum(not k.drawn for k in self.keyframes),
                "last_response": round(self.last_response, 3),
                "mean_response": round(float(np.mean(self.responses)), 3) if self.responses else 0.0,
                "recoveries": self.recoveries, "degenerate_matches": self.degenerate_matches,
                "loop_closures": len(self.loop_closures), "rejected_closures": self.rejected_closures,
                **{f"rejected_{why}": self.rejected_why.get(why, 0) for why in REJECTIONS},
                "undone_closures": self.undone_closures,
                "largest_correction_m": round(float(self.largest_correction[0]), 3),
                "largest_correction_rad": round(float(self.largest_correction[1]), 4)}

    # ------------------------------------------------------------------ poses
    def map_pose(self, index: int) -> np.ndarray:
        return self.graph.poses[index]

    def _last_of_session(self) -> Keyframe | None:
        if self.keyframes and self.keyframes[-1].session == self.session:
            return self.keyframes[-1]
        return None

    def map_to_odom(self) -> np.ndarray:
        """The map → odom transform: identity until the session's first keyframe."""
        last = self._last_of_session()
        if last is None:
            return np.zeros(3)
        return np.asarray(se2_compose(self.map_pose(last.index), se2_inverse(last.odom_pose)))

    def predict(self, odom_pose: PoseLike) -> np.ndarray:
        """The base's map pose for an odometry pose, through the current map → odom."""
        if self._last_of_session() is None and self.start_pose is not None:
            return np.asarray(self.start_pose, dtype=float).copy()
        return np.asarray(se2_compose(self.map_to_odom(), np.asarray(odom_pose, dtype=float)))

    def start_session(self, start_pose: PoseLike | None = None) -> None:
        """Continue mapping with a new run's odometry (after loading a saved pose graph).

        The run's first scan is placed at ``start_pose`` in the map (default: the
        first keyframe's pose, slam_toolbox's "start at dock"), corrected by matching
        against the keyframes around it, and linked to the nearest of them.
        """
        if self.keyframes:
            self.session = max(k.session for k in self.keyframes) + 1
        if start_pose is None:
            start_pose = self.map_pose(0) if self.keyframes else np.zeros(3)
        pose = finite_pose(start_pose, "the start pose", MapperError)
        self.start_pose = pose.copy()

    def hit_points(self, rays: ScanRays) -> tuple[np.ndarray, np.ndarray]:
        """The scan's hits within max_laser_range and their surface normals, in the base frame."""
        return scan_hits(rays, self.sensor_offset, self.settings.max_laser_range)

    def within_reach(self, points: np.ndarray, rays: ScanRays) -> np.ndarray:
        """Which hits (base frame) are at least :data:`MATCH_RANGE_MARGIN_M` short of the range
        limit: those the keyframes around have seen too. A hit farther out lies past the
        ends of the walls the map has (each keyframe saw them only up to the limit from where
        it was), where the likelihood field falls off; matched, such points pull the scan
        back along the walls, on both sides of a corridor at different distances, and turn
        it: a steady heading drift down long corridors."""
        return within_reach(points, rays, self.sensor_offset, self.settings.max_laser_range)

    # -------------------------------------------------------------- keyframes
    def needs_keyframe(self, odom_pose: PoseLike) -> bool:
        last = self._last_of_session()
        if last is None:
            return True
        motion = se2_compose(se2_inverse(last.odom_pose), np.asarray(odom_pose, dtype=float))
        s = self.settings
        return bool(math.hypot(motion[0], motion[1]) >= s.minimum_travel_distance
                    or abs(float(wrap_angles(motion[2]))) >= s.minimum_travel_heading)

    def process(self, stamp_s: float, odom_pose: PoseLike, rays: ScanRays) -> Keyframe | None:
        """Take a scan with its odometry pose; a new keyframe when the robot moved enough.

        A scan with fewer than :data:`MIN_MATCH_POINTS` hits (open space) is placed by
        odometry alone; its free space still goes into the map.
        """
        if not self.needs_keyframe(odom_pose):
            return None
        points, normals = self.hit_points(rays)
        odom = np.asarray(odom_pose, dtype=float).copy()
        predicted = self.predict(odom)
        index = len(self.keyframes)
        if index == 0:
            self.graph.add_node(predicted)
            self.keyframes.append(Keyframe(0, stamp_s, odom, rays, points, normals, self.session))
            self.last_response = 1.0
            return self.keyframes[0]
        continuing = self._last_of_session() is None  # the first keyframe of a continued map's new run
        near = self.within_reach(points, rays)
        result = self._match_running(points[near], normals[near], predicted)
        accepted = result is not None and result.response >= self.required_response
        pose, covariance = predicted, ODOMETRY_ONLY_COVARIANCE
        if accepted and result is not None:
            travel = float(np.hypot(*(predicted[:2] - self.map_pose(index - 1)[:2])))
            pose, covariance, degenerate = observable_only(result.pose, result.covariance, predicted, travel)
            self.degenerate_matches += degenerate
        self.last_response = result.response if result is not None else 0.0
        if result is not None:  # there was something to match
            self.responses = (self.responses + [self.last_response])[-HEALTH_WINDOW:]
            self.unmatched = 0 if accepted else self.unmatched + 1
        previous = self._nearest(pose, range(index)) if continuing else index - 1
        self.graph.add_node(pose)
        self.keyframes.append(Keyframe(index, stamp_s, odom, rays, points, normals, self.session))
        if self.lost:  # the unmatched keyframes so far, this one among them, stay out of the map
            for keyframe in self.keyframes[-min(self.unmatched, len(self.keyframes)):]:
                keyframe.drawn = False
        self.graph.add_edge(previous, index, self.graph.relative(previous, index),
                            in_frame_of(covariance, self.map_pose(previous)[2]))
        if self.settings.do_loop_closing and not self.defer_loops:
            self.close_loops(index)
        return self.keyframes[-1]

    def _world_points(self, indices: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """The keyframes' hits and normals in the map."""
        return (np.vstack([se2_apply(self.map_pose(i), self.keyframes[i].points) for i in indices]),
                np.vstack([rotate(self.keyframes[i].normals, float(self.map_pose(i)[2])) for i in indices]))

    def _distance(self, index: int, pose: np.ndarray) -> float:
        return float(np.hypot(*(self.map_pose(index)[:2] - pose[:2])))

    def _nearest(self, pose: np.ndarray, indices: Iterable[int]) -> int:
        return min(indices, key=lambda i: self._distance(i, pose))

    def _running_buffer(self, pose: np.ndarray) -> list[int]:
        """The session's last ``scan_buffer_size`` keyframes within reach that matched the map; early
        in a continued map's run, topped up with the nearest keyframes of earlier runs."""
        s = self.settings
        # Not the keyframes of an unmatched streak (they would match each other: see LOST_KEYFRAMES)
        # nor those left out of the map.
        confirmed = len(self.keyframes) - self.unmatched
        recent = [i for i in range(confirmed - 1, -1, -1)
                  if self.keyframes[i].session == self.session and self.keyframes[i].drawn][:s.scan_buffer_size][::-1]
        if len(recent) < s.scan_buffer_size:
            older = sorted((i for i in range(len(self.keyframes)) if self.keyframes[i].session != self.session),
                           key=lambda i: self._distance(i, pose))
            recent += older[:s.scan_buffer_size - len(recent)]
        return [i for i in recent if self._distance(i, pose) <= s.scan_buffer_maximum_scan_distance]

    def _match_running(self, points: np.ndarray, normals: np.ndarray, predicted: np.ndarray) -> MatchResult | None:
        buffer = [i for i in self._running_buffer(predicted) if len(self.keyframes[i].points)]
        if not buffer or len(points) < MIN_MATCH_POINTS:
            return None
        world, world_normals = self._world_points(buffer)
        result = ScanMatcher(world, self.settings.matcher, world_normals).match(points, predicted, normals)
        if result.response < RECOVERY_RESPONSE:
            wide = ScanMatcher(world, self.settings.recovery_matcher, world_normals).match(points, predicted, normals)
            if wide.response >= result.response + RECOVERY_MARGIN:
                self.recoveries += 1
                return wide
        return result

    # ----------------------------------------------------------- loop closure
    def loop_candidates(self, index: int) -> list[list[int]]:
        """Chains of consecutive older keyframes near keyframe ``index`` (outside its running
        chain): within ``loop_search_maximum_distance``, or within ``loop_search_overlap_distance``
        and before :meth:`walked_from` (the path that led here is no loop)."""
        s = self.settings
        pose = self.map_pose(index)
        old = index - s.scan_buffer_size
        walked = self.walked_from(index)
        distances = [float(np.hypot(*(self.map_pose(i)[:2] - pose[:2]))) for i in range(max(0, old))]
        near = [i for i, d in enumerate(distances)
                if d <= s.loop_search_maximum_distance or (i < walked and 0 < d <= s.loop_search_overlap_distance)]
        chains: list[list[int]] = []
        for i in near:
            if chains and i == chains[-1][-1] + 1:
                chains[-1].append(i)
            else:
                chains.append([i])
        return [c for c in chains if len(c) >= s.loop_match_minimum_chain_size]

    def walked_from(self, index: int, distance_m: float | None = None) -> int:
        """The first keyframe of the last ``distance_m`` (``loop_search_overlap_distance``)
        travelled to keyframe ``index``: what the robot saw that recently overlaps its scan by the
        scan matching's doing, not a loop's (``LoopChain.remote``), as slam_toolbox leaves the
        scans linked to a scan out of its loop search."""
        limit = self.settings.loop_search_overlap_distance if distance_m is None else distance_m
        travelled, first = 0.0, index
        while first > 0:
            travelled += float(np.hypot(*(self.map_pose(first)[:2] - self.map_pose(first - 1)[:2])))
            if travelled > limit:
                break
            first -= 1
        return first

    def global_search_due(self, index: int) -> bool:
        """Whether keyframe ``index`` searches globally (:meth:`global_loop_search`): the robot
        went ``loop_search_global_after_distance`` since the last closure (or its start), and
        the last global search is :data:`LOOP_RETRY_KEYFRAMES` keyframes old."""
        s = self.settings
        if s.loop_search_global_distance <= 0 or index - self.global_tried < LOOP_RETRY_KEYFRAMES:
            return False
        last_closure = max((c.target for c in self.loop_closures), default=0)
        return self.walked_from(index, s.loop_search_global_after_distance) > last_closure

    def global_loop_search(self, index: int) -> LoopChain | None:
        """The older keyframes within ``loop_search_global_distance`` of keyframe ``index`` that a
        local search would not see: odometry may have drifted further than the local window
        reaches (Cartographer's constraint builder searches a whole submap so). A keyframe the
        robot came from on a path shorter than twice its distance, or than that distance, is left
        out (a corridor seen ahead is no loop; a loop goes round), and at least
        ``loop_match_minimum_chain_size`` must remain. One chain of them all, matched over
        ``global_loop_matcher``'s window (:meth:`LoopSearch.run`); None when there is none."""
        s = self.settings
        before = index - s.scan_buffer_size
        if before <= 0:
            return None
        poses = np.array(self.graph.poses[:index + 1])[:, :2]
        travelled = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(poses, axis=0).T))])
        travelled = travelled[index] - travelled[:before]
        distance = np.hypot(*(poses[:before] - poses[index]).T)
        near = np.flatnonzero((distance <= s.loop_search_global_distance)
                              & (travelled > np.maximum(2 * distance, s.loop_search_global_distance)))
        if len(near) < s.loop_match_minimum_chain_size or \
                sum(len(self.keyframes[i].points) for i in near) < MIN_MATCH_POINTS:
            return None
        return self._loop_chain([int(i) for i in near], remote=True, global_search=True)

    def _loop_chain(self, indices: list[int], remote: bool, global_search: bool = False) -> LoopChain:
        """Keyframes as a :class:`LoopChain`: their hits in the map at their current poses, and their views."""
        world, world_normals = self._world_points(indices)
        poses = np.array([self.map_pose(i) for i in indices])
        views = tuple(view_of(pose, self.sensor_offset, self.keyframes[i].rays)
                      for i, pose in zip(indices, poses, strict=True))
        return LoopChain(np.array(indices), poses, world, world_normals, views, remote, global_search)

    def _linked(self, chain: list[int], index: int) -> bool:
        """Whether a loop edge already joins ``chain`` to keyframe ``index`` or its running chain:
        that loop is closed, and closing it again on every keyframe would only make the graph
        over-confident in one place (and cost a large search each time)."""
        first_recent = max(0, index - self.settings.scan_buffer_size)
        members = set(chain)
        return any(e.loop and first_recent <= e.target <= index and e.source in members for e in self.graph.edges)

    def loop_search(self, index: int) -> LoopSearch | None:
        """The loop search of keyframe ``index``: the candidate chains with their hits placed
        at their current poses (None when there is nothing to search). Chains already
        linked, or searched a moment ago, are left out; the rest are marked as tried."""
        keyframe = self.keyframes[index]
        near = self.within_reach(keyframe.points, keyframe.rays)
        if near.sum() < MIN_MATCH_POINTS:
            return None
        chains = []
        walked = self.walked_from(index)
        here = self.map_pose(index)
        reach = self.settings.loop_search_maximum_distance
        candidates = self.loop_candidates(index)
        for chain in candidates:
            if sum(len(self.keyframes[i].points) for i in chain) < MIN_MATCH_POINTS or self._linked(chain, index):
                continue
            key = (chain[0], any(np.hypot(*(self.map_pose(i)[:2] - here[:2])) <= reach for i in chain))
            if index - self.tried.get(key, -LOOP_RETRY_KEYFRAMES) < LOOP_RETRY_KEYFRAMES:
                continue  # searched a moment ago without a match: the next keyframes will see more
            self.tried[key] = index
            chains.append(self._loop_chain(chain, chain[-1] < walked))
        if not candidates and self.global_search_due(index):
            self.global_tried = index
            found = self.global_loop_search(index)
            if found is not None:
                chains.append(found)
        if not chains:
            return None
        return LoopSearch(index, self.map_pose(index).copy(), keyframe.points[near], keyframe.normals[near],
                          tuple(chains), keyframe.rays, self.sensor_offset.copy())

    def close_loops(self, index: int) -> None:
        """Search, match and add keyframe ``index``'s loop closures, and optimise (all at once)."""
        search = self.loop_search(index)
        matches = search.run(self.settings) if search is not None else []
        if matches:
            self.merge_loops(solve_loops(self.graph.copy(), matches))

    def merge_loops(self, solution: LoopSolution) -> np.ndarray:
        """Take a graph that :func:`solve_loops` solved from a copy of this one. Keyframes
        added since the copy keep their poses relative to the copy's last keyframe, which
        moves as the solution moved it (and their edges are kept). Returns how the newest
        keyframe moved (x, y, yaw in the map; zeros when the graph did not change)."""
        solved = solution.graph
        self.rejected_closures += solution.rejected
        self.rejected_why = {k: self.rejected_why.get(k, 0) + solution.why.get(k, 0) for k in REJECTIONS}
        if not solution.accepted and not solution.undone:
            return np.zeros(3)
        known = len(solved.poses)
        if known > len(self.graph.poses):
            raise MapperError(f"a solved graph of {known} keyframes does not belong to this map "
                              f"({len(self.graph.poses)})")
        last = known - 1
        newest_before = self.graph.poses[-1].copy()
        correction = se2_compose(solved.poses[last], se2_inverse(self.graph.poses[last]))
        self.graph.poses = [p.copy() for p in solved.poses] + [
            np.asarray(se2_compose(correction, p)) for p in self.graph.poses[known:]]
        copied = {id(e) for e in solution.copied_edges}  # the rest came since the copy: kept
        self.graph.edges = list(solved.edges) + [e for e in self.graph.edges if id(e) not in copied]
        self.loop_closures = [c for c in self.loop_closures if (c.source, c.target) not in solution.undone]
        self.loop_closures += [LoopClosure(m.source, m.target, m.response) for m in solution.accepted]
        self.undone_closures += len(solution.undone)
        moved = self.graph.poses[-1] - newest_before
        moved[2] = float(wrap_angles(moved[2]))
        self.largest_correction = np.maximum(self.largest_correction,
                                             [float(np.hypot(moved[0], moved[1])), abs(float(moved[2]))])
        return moved

    # -------------------------------------------------------------------- map
    def grid_inputs(self) -> tuple[OccupancySettings, list[np.ndarray], list[ScanRays]]:
        """What :meth:`LogOddsGrid.build` needs: settings, sensor poses in the map, scans (a snapshot)."""
        settings = OccupancySettings(resolution_m=self.settings.resolution, max_range_m=self.settings.max_laser_range)
        drawn = [k for k in self.keyframes if k.drawn]
        sensor_poses = [np.asarray(se2_compose(self.map_pose(k.index), self.sensor_offset)) for k in drawn]
        return settings, sensor_poses, [k.rays for k in drawn]

    def occupancy(self) -> LogOddsGrid:
        """The log-odds grid rebuilt from every keyframe (but those placed while lost) at its optimised pose."""
        return LogOddsGrid.build(*self.grid_inputs())

    def grid(self, frame_id: str = "map") -> OccupancyGrid:
        return self.occupancy().to_occupancy_grid(frame_id)


def scan_hits(rays: ScanRays, sensor_offset: np.ndarray, max_laser_range: float) -> tuple[np.ndarray, np.ndarray]:
    """A scan's hits within ``max_laser_range`` (m) and their unit surface normals, (K, 2) each, in
    the base frame of a lidar mounted at ``sensor_offset`` (x, y, yaw)."""
    classes = rays.classify(max_laser_range)
    sensor_xy = rays.directions[classes.hit] * rays.ranges_m[classes.hit, None]
    normals = rotate(scan_normals(sensor_xy), float(sensor_offset[2]))
    return np.asarray(se2_apply(sensor_offset, sensor_xy)), normals


def within_reach(points: np.ndarray, rays: ScanRays, sensor_offset: np.ndarray, max_laser_range: float) -> np.ndarray:
    """Which hits (base frame, (K, 2)) are at least :data:`MATCH_RANGE_MARGIN_M` short of the range
    limit (see :meth:`Mapper.within_reach`); a (K,) boolean mask."""
    limit = min(rays.range_max_m, max_laser_range) - MATCH_RANGE_MARGIN_M
    return np.asarray(np.hypot(*(points - sensor_offset[:2]).T) < limit)


def observable_only(pose: np.ndarray, covariance: np.ndarray, predicted: np.ndarray, travel_m: float
                    ) -> tuple[np.ndarray, np.ndarray, bool]:
    """A match taken only along the directions its scan observes.

    In a featureless corridor every position along its length fits the scan about as well:
    the matched pose there is noise, not a measurement. When the position covariance's
    larger axis is degenerate (:data:`DEGENERATE_RATIO`, :data:`DEGENERATE_MIN_STD_M`), the
    correction from ``predicted`` (odometry, ``travel_m`` since the last keyframe) along it is
    dropped and the variance along it is odometry's (:data:`ODOMETRY_STD_PER_M`) instead of the
    search window's spread, so the pose graph weighs that axis as what it is: dead reckoning.
    Returns the pose, the covariance and whether it was degenerate.
    """
    values, vectors = np.linalg.eigh(covariance[:2, :2])
    if values[1] < DEGENERATE_RATIO * max(values[0], 0.0) or values[1] < DEGENERATE_MIN_STD_M ** 2:
        return pose, covariance, False
    axis = vectors[:, 1]
    kept = pose.copy()
    kept[:2] -= axis * float(axis @ (pose[:2] - predicted[:2]))
    odometry = max(ODOMETRY_STD_PER_M * travel_m, DEGENERATE_MIN_STD_M / 4) ** 2
    along = np.zeros(3)
    along[:2] = axis
    across = np.eye(3) - np.outer(along, along)  # the matcher's covariance without that axis ...
    return kept, across @ covariance @ across + odometry * np.outer(along, along), True  # ... and odometry's on it
