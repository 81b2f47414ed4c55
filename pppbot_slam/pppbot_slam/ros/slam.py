"""``slam``: online asynchronous grid SLAM, in slam_toolbox's place (``localization:=false``).

Subscribes ``scan`` and TF (``odom_frame → base_frame`` at each scan's stamp, and the
lidar's mounting); publishes ``/map`` and ``/map_metadata`` (transient local, rebuilt
every ``map_update_interval`` in a thread of its own, so mapping never blocks scans),
``pose`` (PoseWithCovarianceStamped of ``base_frame`` in ``map_frame``), and the TF
``map_frame → odom_frame`` every ``transform_publish_period``, stamped ahead by
``transform_timeout`` as slam_toolbox does, the pose graph as markers
(``~/graph_visualization``) and its health on ``/diagnostics`` (diagnostic_msgs, with the
map: match responses, closures accepted, rejected and undone, the largest correction, and
whether it is lost — also warned about in the log when it happens). Services (std_srvs; file names are parameters, which
``ros2 param set`` may change at run time): ``~/save_map`` (Nav2 YAML + PGM at
``map_save_name``), ``~/serialize_map`` (the pose graph with its scans,
``map_save_name`` + ``.posegraph``), ``~/deserialize_map`` (load ``map_file_name``
and map on from it; also done at startup when it is set), ``~/pause_new_measurements``
(SetBool) and ``~/reset``. The algorithm is :mod:`pppbot_slam.mapper`.

Three threads besides the executor's: scan processing (keyframes matched against the
running buffer), loop closing (each new keyframe's loop search, matched and solved on a
copy of the graph, then merged), and the map builder. Scans never wait for a loop search.
In lockstep each piece of work is held for (:func:`pppbot_common.ros.lockstep.hold`): a
step is answered once its scan is processed, its loop search merged and its map
published, so the map and the pose graph are the same on every run.
"""
from __future__ import annotations

import queue
import sys
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, PoseWithCovarianceStamped, TransformStamped
from nav_msgs.msg import MapMetaData
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from rclpy.duration import Duration
from rclpy.node import Node
from sensor_msgs.msg import LaserScan
from std_msgs.msg import ColorRGBA, Header
from std_srvs.srv import SetBool, Trigger
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import Marker, MarkerArray

from pppbot_common.maps import MapFileError, OccupancyGrid, save_map
from pppbot_common.params import ParameterError, check_finite_range, param
from pppbot_common.resources import maps_directory
from pppbot_common.ros.lockstep import at_step, create_timer, hold, require_match
from pppbot_common.ros.maps import grid_message, map_metadata
from pppbot_common.ros.node_main import Warnings, guarded, run_node
from pppbot_common.ros.params import declare_parameters, on_valid_update
from pppbot_common.ros.qos import LATCHED, SENSOR
from pppbot_common.ros.scan_odometry import ScanOdometry
from pppbot_common.se2 import quaternion_from_yaw
from pppbot_slam.loops import LOOP_SEE_THROUGH_MAX, solve_loops
from pppbot_slam.mapper import LOST_KEYFRAMES, Mapper, MapperError, MapperSettings
from pppbot_slam.matcher import MatcherError, MatcherSettings
from pppbot_slam.occupancy import LogOddsGrid, OccupancyError, ScanRays
from pppbot_slam.pose_graph import Edge
from pppbot_slam.serialization import PoseGraphFileError, load_posegraph, posegraph_path, save_posegraph

WARN_PERIOD_S = 5.0
#: Scans (with their odometry) waiting for the processing thread; beyond this the oldest goes.
MAX_QUEUED = 200
#: Keyframes waiting for their loop search; beyond this the oldest goes (a later keyframe
#: searches the same places).
MAX_LOOP_QUEUED = 50


@dataclass(frozen=True)
class SlamParameters:
    odom_frame: str = param("odom", "odometry frame")
    map_frame: str = param("map", "map frame")
    base_frame: str = param("base_footprint", "robot base frame")
    scan_topic: str = param("/scan", "laser scan topic")
    mode: str = param("mapping", "mapping (localization with a map is AMCL's job here)")
    map_file_name: str = param("", "a pose graph (.posegraph) to map on from, loaded at startup and by "
                                   "~/deserialize_map")
    map_start_pose: list[float] = param([0.0, 0.0, 0.0], "where the robot starts in a loaded pose graph (x, y, yaw), "
                                                 "unless map_start_at_dock")
    map_start_at_dock: bool = param(True, "the robot starts at the loaded pose graph's first keyframe")
    map_save_name: str = param("", "where ~/save_map and ~/serialize_map write (no extension); default maps/map")
    resolution: float = param(0.05, "map cell size (m)")
    max_laser_range: float = param(20.0, "beams are used up to this range (m)")
    minimum_travel_distance: float = param(0.5, "travel between keyframes (m)")
    minimum_travel_heading: float = param(0.5, "turn between keyframes (rad)")
    map_update_interval: float = param(5.0, "seconds between map rebuilds")
    transform_publish_period: float = param(0.02, "seconds between map → odom transforms")
    transform_timeout: float = param(0.2, "map → odom is stamped this far ahead (s)")
    tf_buffer_duration: float = param(30.0, "seconds of TF history kept")
    scan_buffer_size: int = param(10, "keyframes in the running matching buffer")
    scan_buffer_maximum_scan_distance: float = param(10.0, "keyframes farther than this leave the buffer (m)")
    link_match_minimum_response_fine: float = param(0.1, "below this a match is not trusted")
    do_loop_closing: bool = param(True, "search for loop closures")
    loop_search_maximum_distance: float = param(3.0, "loop candidates within this distance (m)")
    loop_match_minimum_chain_size: int = param(10, "consecutive keyframes a loop candidate chain needs")
    loop_match_maximum_variance_coarse: float = param(3.0, "largest coarse-match variance accepted")
    loop_match_minimum_response_coarse: float = param(0.35, "coarse loop response needed")
    loop_match_minimum_response_fine: float = param(0.45, "fine loop response needed")
    correlation_search_space_dimension: float = param(0.5, "matching window width (m)")
    correlation_search_space_resolution: float = param(0.01, "fine matching step (m)")
    correlation_search_space_smear_deviation: float = param(0.1, "likelihood smear (m)")
    loop_search_space_dimension: float = param(8.0, "loop matching window width (m)")
    loop_search_space_resolution: float = param(0.05, "loop matching coarse step (m)")
    loop_search_space_smear_deviation: float = param(0.03, "loop likelihood smear (m)")
    distance_variance_penalty: float = param(0.5, "penalty on distance from odometry")
    angle_variance_penalty: float = param(1.0, "penalty on turn from odometry")
    fine_search_angle_offset: float = param(0.00349, "fine angle step (rad)")
    coarse_search_angle_offset: float = param(0.349, "angle window ± (rad)")
    coarse_angle_resolution: float = param(0.0349, "coarse angle step (rad)")
    minimum_angle_penalty: float = param(0.9, "floor of the angle penalty")
    minimum_distance_penalty: float = param(0.5, "floor of the distance penalty")

    def validate(self) -> None:
        if self.mode != "mapping":
            raise ParameterError("mode", self.mode, "must be 'mapping' (use amcl to localize on a saved map)")
        for name in ("map_update_interval", "transform_publish_period", "tf_buffer_duration"):
            check_finite_range(name, getattr(self, name), 0.0, 3600.0, low_open=True)
        check_finite_range("transform_timeout", self.transform_timeout, 0.0, 60.0)
        for name in ("odom_frame", "map_frame", "base_frame", "scan_topic"):
            if not getattr(self, name):
                raise ParameterError(name, getattr(self, name), "must not be empty")
        start = self.map_start_pose
        if len(start) != 3 or not all(isinstance(v, (int, float)) and np.isfinite(v) for v in start):
            raise ParameterError("map_start_pose", start, "must be three finite numbers [x, y, yaw]")
        try:
            self.mapper_settings()
        except (MapperError, MatcherError, OccupancyError) as exc:
            raise ParameterError("mapper", "", str(exc)) from exc

    def start_pose(self) -> np.ndarray | None:
        """Where a loaded pose graph's new run starts (None: at its first keyframe)."""
        return None if self.map_start_at_dock else np.array(self.map_start_pose, dtype=float)

    def save_name(self) -> Path:
        return Path(self.map_save_name).expanduser() if self.map_save_name else maps_directory() / "map"

    def mapper_settings(self) -> MapperSettings:
        common: dict[str, Any] = dict(distance_variance_penalty=self.distance_variance_penalty,
                      angle_variance_penalty=self.angle_variance_penalty,
                      minimum_distance_penalty=self.minimum_distance_penalty,
                      minimum_angle_penalty=self.minimum_angle_penalty,
                      search_angle_rad=self.coarse_search_angle_offset,
                      coarse_angle_step_rad=self.coarse_angle_resolution,
                      fine_angle_step_rad=self.fine_search_angle_offset)
        matcher = MatcherSettings(search_size_m=self.correlation_search_space_dimension,
                                  fine_resolution_m=self.correlation_search_space_resolution,
                                  coarse_resolution_m=max(self.correlation_search_space_resolution, 0.05),
                                  smear_m=self.correlation_search_space_smear_deviation, **common)
        loop = MatcherSettings(search_size_m=self.loop_search_space_dimension,
                               fine_resolution_m=self.loop_search_space_resolution,
                               coarse_resolution_m=max(self.loop_search_space_resolution, 0.1),
                               smear_m=self.loop_search_space_smear_deviation, coarse_points=100, **common)
        return MapperSettings(
            resolution=self.resolution, max_laser_range=self.max_laser_range,
            minimum_travel_distance=self.minimum_travel_distance, minimum_travel_heading=self.minimum_travel_heading,
            scan_buffer_size=self.scan_buffer_size,
            scan_buffer_maximum_scan_distance=self.scan_buffer_maximum_scan_distance,
            link_match_minimum_response_fine=self.link_match_minimum_response_fine,
            do_loop_closing=self.do_loop_closing, loop_search_maximum_distance=self.loop_search_maximum_distance,
            loop_match_minimum_chain_size=self.loop_match_minimum_chain_size,
            loop_match_maximum_variance_coarse=self.loop_match_maximum_variance_coarse,
            loop_match_minimum_response_coarse=self.loop_match_minimum_response_coarse,
            loop_match_minimum_response_fine=self.loop_match_minimum_response_fine,
            matcher=matcher, loop_matcher=loop)


class Slam(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__("slam_toolbox", **kwargs)
        self.params = p = declare_parameters(self, SlamParameters)
        on_valid_update(self, lambda: self.params, self._set_params)
        self.mapper = Mapper(p.mapper_settings(), defer_loops=True)
        if p.map_file_name:
            self.mapper = self._load(p.map_file_name)
        self.lock = threading.Lock()  # the mapper: scans write it, the map thread reads it
        self._diagnostics_lock = threading.Lock()  # one health reading published at a time
        self.paused = False
        self._warn = Warnings(self, WARN_PERIOD_S)
        self.scans = ScanOdometry(self, p.odom_frame, p.base_frame, self._queue, self._warn, p.tf_buffer_duration)
        self._scan_frame: str | None = None
        # Scans with their odometry, processed in a worker thread: the executor stays free
        # for TF (in and out) while a keyframe is matched or a loop searched. Each item carries
        # the release of its lockstep hold.
        self._work: queue.Queue[tuple[Callable[[], None], LaserScan, float, str, np.ndarray, np.ndarray] | None] = \
            queue.Queue(maxsize=MAX_QUEUED)
        # Keyframes (of which mapper: a reset or a loaded graph replaces it) to search for loops.
        self._loops: queue.Queue[tuple[Callable[[], None], Mapper, int] | None] = queue.Queue(maxsize=MAX_LOOP_QUEUED)
        self.map_pub = self.create_publisher(OccupancyGridMsg, "/map", LATCHED)
        self.meta_pub = self.create_publisher(MapMetaData, "/map_metadata", LATCHED)
        self.graph_pub = self.create_publisher(MarkerArray, "~/graph_visualization", 1)
        self.pose_pub = self.create_publisher(PoseWithCovarianceStamped, "pose", 10)
        self.tf_pub = self.create_publisher(TFMessage, "/tf", 100)
        self.diagnostics_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        on_scan = guarded(self, at_step(self, self.on_scan), "LaserScan")
        require_match(self, self.create_subscription(LaserScan, p.scan_topic, on_scan, SENSOR))
        self.create_service(Trigger, "~/save_map", self._save_map)
        self.create_service(Trigger, "~/serialize_map", self._serialize)
        self.create_service(Trigger, "~/deserialize_map", self._deserialize)
        self.create_service(SetBool, "~/pause_new_measurements", self._pause)
        self.create_service(Trigger, "~/reset", self._reset)
        # map → odom is stamped ahead (transform_timeout): nobody waits for each one.
        create_timer(self, p.transform_publish_period, self._publish_transform, wakes=False)
        create_timer(self, p.map_update_interval, self._request_map)
        self._map_wake = threading.Event()
        self._map_holds: list[Callable[[], None]] = []
        self._map_lock = threading.Lock()
        self._stopping = threading.Event()
        self._map_thread = threading.Thread(target=self._map_loop, name="map-builder", daemon=True)
        self._map_thread.start()
        self._worker = threading.Thread(
            target=self._serve, args=(self._work, self._process, "process", "a scan could not be processed"),
            name="scan-processing", daemon=True)
        self._worker.start()
        self._loop_closer = threading.Thread(
            target=self._serve, args=(self._loops, self._close_loops, "loops", "a loop search failed"),
            name="loop-closing", daemon=True)
        self._loop_closer.start()
        self.get_logger().info(f"mapping: {p.scan_topic} with {p.odom_frame} → {p.base_frame}; map every "
                               f"{p.map_update_interval:g} s at {p.resolution} m")

    def _set_params(self, params: SlamParameters) -> None:
        self.params = params
        self.scans.odom_frame, self.scans.base_frame = params.odom_frame, params.base_frame

    def _load(self, name: str) -> Mapper:
        """A saved pose graph to map on from, the robot starting where the parameters say.

        Raises:
            PoseGraphFileError: the file is missing or bad (the message names it).
        """
        mapper = load_posegraph(name, self.params.mapper_settings())
        mapper.defer_loops = True
        mapper.start_session(self.params.start_pose())
        start = mapper.predict(np.zeros(3))  # the new session's first keyframe goes here
        self.get_logger().info(f"mapping on from {posegraph_path(name)}: {len(mapper.keyframes)} keyframes, "
                               f"starting at ({start[0]:.2f}, {start[1]:.2f}, {start[2]:.3f})")
        return mapper

    # ----------------------------------------------------------------- scans
    def on_scan(self, msg: LaserScan) -> None:
        """Queue the scan until odometry reaches its stamp (as tf2's message filter does)."""
        if self.paused:
            return
        self.scans.add(msg)

    def _queue(self, msg: LaserScan, stamp: float, frame: str, odom_pose: np.ndarray, sensor: np.ndarray) -> None:
        if _put_dropping_oldest(self._work, (hold(), msg, stamp, frame, odom_pose, sensor)):
            self._warn("behind", f"scan processing is {MAX_QUEUED} scans behind: dropping the oldest")

    def _serve(self, work: queue.Queue[Any], handle: Callable[..., None], kind: str, failure: str) -> None:
        """A thread's loop: ``handle`` each item of ``work`` until the stop sign; one that fails
        is warned about (``failure``, throttled per ``kind``) and the thread goes on. The item's
        lockstep hold is released when it is done."""
        while True:
            item = work.get()
            if item is None or self._stopping.is_set():
                return
            release, *args = item
            try:
                handle(*args)
            except Exception as exc:  # noqa: BLE001 - one bad scan or search must not stop the thread
                self._warn(kind, f"{failure}: {type(exc).__name__}: {exc}")
            finally:
                release()

    def _process(self, msg: LaserScan, stamp: float, frame: str, odom_pose: np.ndarray, sensor: np.ndarray) -> None:
        try:
            rays = ScanRays.from_laser(msg.angle_min, msg.angle_increment, np.asarray(msg.ranges, dtype=float),
                                       msg.range_min, msg.range_max)
        except OccupancyError as exc:
            self._warn("scan", f"dropping a malformed scan: {exc}")
            return
        with self.lock:
            mapper = self.mapper
            if self._scan_frame != frame or not np.allclose(mapper.sensor_offset, sensor):
                mapper.sensor_offset = sensor
                self._scan_frame = frame
            recoveries, was_lost = mapper.recoveries, mapper.lost
            keyframe = mapper.process(stamp, odom_pose, rays)
            recovered = mapper.recoveries > recoveries
            lost = mapper.lost
            pose = mapper.predict(odom_pose)
            response = mapper.last_response
        if keyframe is not None:
            self.get_logger().debug(f"keyframe {keyframe.index} at t = {stamp:.2f} s: match response "
                                    f"{response:.2f}, pose ({pose[0]:.2f}, {pose[1]:.2f}, {pose[2]:.3f})")
            if recovered:
                self.get_logger().warning(
                    f"keyframe {keyframe.index}: the scan did not fit where odometry put it (a collision or a "
                    f"skid?); found at ({pose[0]:.2f}, {pose[1]:.2f}, {pose[2]:.3f}) by a search over every heading "
                    f"(response {response:.2f})")
            if lost != was_lost:
                self._report_lost(lost, keyframe.index, stamp, mapper)
            self._publish_pose(msg.header.stamp, pose)
            if keyframe.index == 0:
                self._request_map()  # a first map at once
            if mapper.settings.do_loop_closing and _put_dropping_oldest(self._loops, (hold(), mapper, keyframe.index)):
                self._warn("loops behind", f"loop closing is {MAX_LOOP_QUEUED} keyframes behind: the oldest "
                                           "keyframe's search is skipped")

    # ---------------------------------------------------------- loop closure
    def _close_loops(self, mapper: Mapper, index: int) -> None:
        """Keyframe ``index``'s loop search: taken from the mapper under the lock, matched and
        solved outside it (scans go on), merged under it. A mapper replaced meanwhile (reset,
        a loaded graph) is left alone."""
        with self.lock:
            if mapper is not self.mapper:
                return
            search = mapper.loop_search(index)
        matches = search.run(mapper.settings) if search is not None else []
        if not matches:
            return
        with self.lock:
            if mapper is not self.mapper:
                return
            graph = mapper.graph.copy()
        solution = solve_loops(graph, matches)
        accepted, rejected = solution.accepted, solution.rejected
        with self.lock:
            if mapper is not self.mapper:
                return
            moved = mapper.merge_loops(solution)
            stamp = mapper.keyframes[index].stamp_s
        for match in accepted:
            self.get_logger().info(f"loop closure: keyframe {match.target} (scan at t = {stamp:.2f} s) with "
                                   f"{match.source} (response {match.response:.2f})")
        if accepted:
            self.get_logger().info(f"the graph solved with keyframe {index}'s closures moved the newest keyframe "
                                   f"{float(np.hypot(moved[0], moved[1])):.3f} m, {float(moved[2]):+.4f} rad")
        if rejected:
            taken = {id(match) for match in accepted}
            through = sum(1 for m in matches if id(m) not in taken and m.see_through > LOOP_SEE_THROUGH_MAX)
            why = f" ({through} whose scans saw through each other's walls)" if through else ""
            self.get_logger().info(f"keyframe {index} (t = {stamp:.2f} s): {rejected} loop match(es) the pose graph "
                                   f"could not agree with{why}, dropped")
        for source, target in sorted(solution.undone):
            self.get_logger().warning(f"loop closure of keyframe {target} with {source} undone: the closures since "
                                      "show it was wrong (a place that looks like another)")

    def _publish_pose(self, stamp: Any, pose: np.ndarray) -> None:
        msg = PoseWithCovarianceStamped()
        msg.header.stamp = stamp
        msg.header.frame_id = self.params.map_frame
        msg.pose.pose.position.x, msg.pose.pose.position.y = float(pose[0]), float(pose[1])
        o = msg.pose.pose.orientation
        o.x, o.y, o.z, o.w = quaternion_from_yaw(float(pose[2]))
        self.pose_pub.publish(msg)

    def _publish_transform(self) -> None:
        with self.lock:
            map_to_odom = self.mapper.map_to_odom()
        t = TransformStamped()
        t.header.stamp = (self.get_clock().now() + Duration(seconds=self.params.transform_timeout)).to_msg()
        t.header.frame_id = self.params.map_frame
        t.child_frame_id = self.params.odom_frame
        t.transform.translation.x, t.transform.translation.y = float(map_to_odom[0]), float(map_to_odom[1])
        r = t.transform.rotation
        r.x, r.y, r.z, r.w = quaternion_from_yaw(float(map_to_odom[2]))
        self.tf_pub.publish(TFMessage(transforms=[t]))

    # ------------------------------------------------------------------- map
    def _request_map(self) -> None:
        """A map rebuild by the map thread (every map_update_interval of sim time, and at the first keyframe)."""
        with self._map_lock:
            self._map_holds.append(hold())
        self._map_wake.set()

    def _map_loop(self) -> None:
        while not self._stopping.is_set():
            self._map_wake.wait()
            self._map_wake.clear()
            with self._map_lock:
                releases, self._map_holds = self._map_holds, []
            try:
                if not self._stopping.is_set():
                    self.publish_map()
            except Exception as exc:  # noqa: BLE001 - a failed build must not stop the map thread
                self._warn("map", f"the map could not be built: {type(exc).__name__}: {exc}")
            finally:
                for release in releases:
                    release()

    def build_map(self) -> OccupancyGrid | None:
        """The grid from the keyframes' current poses; built outside the lock (scans go on)."""
        with self.lock:
            if not self.mapper.keyframes:
                return None
            inputs = self.mapper.grid_inputs()
        return LogOddsGrid.build(*inputs).to_occupancy_grid(self.params.map_frame)

    def publish_map(self) -> None:
        grid = self.build_map()
        if grid is None:
            return
        stamp = self.get_clock().now().to_msg()
        self.map_pub.publish(grid_message(grid, stamp))
        self.meta_pub.publish(map_metadata(grid, stamp))
        self.publish_graph(stamp)
        self.publish_diagnostics(stamp)

    def _report_lost(self, lost: bool, index: int, stamp: float, mapper: Mapper) -> None:
        if lost:
            self.get_logger().warning(
                f"lost at keyframe {index} (t = {stamp:.2f} s): the last {LOST_KEYFRAMES} scans matched nothing "
                f"around where odometry put them (response below {mapper.settings.link_match_minimum_response_fine}); "
                "keyframes are placed by odometry alone and left out of the map until a scan matches again")
        else:
            self.get_logger().info(f"found again at keyframe {index} (t = {stamp:.2f} s): the scan matched the map "
                                   f"(response {mapper.last_response:.2f})")
        self.publish_diagnostics(self.get_clock().now().to_msg())

    def publish_diagnostics(self, stamp: Any) -> None:
        """The mapper's health as one DiagnosticStatus (level WARN while lost or when a closure
        had to be undone, as rqt_robot_monitor and the diagnostic aggregator read it).

        The scan worker and the map thread both publish: reading the health and publishing it
        under one lock keeps an older reading from going out after a newer one (a "lost" lost
        behind a stale "mapping", with no later message to correct it while the clock stands)."""
        with self._diagnostics_lock:
            self._publish_diagnostics(stamp)

    def _publish_diagnostics(self, stamp: Any) -> None:
        with self.lock:
            health = self.mapper.health()
        status = DiagnosticStatus(name=f"{self.get_name()}: mapping", hardware_id=self.params.scan_topic)
        if health["lost"]:
            status.level, status.message = DiagnosticStatus.WARN, "lost: scans do not match the map"
        elif health["undone_closures"]:
            status.level = DiagnosticStatus.WARN
            status.message = f"{health['undone_closures']} loop closure(s) proved wrong and were undone"
        else:
            status.level, status.message = DiagnosticStatus.OK, "mapping"
        status.values = [KeyValue(key=key, value=str(value).lower() if isinstance(value, bool) else str(value))
                         for key, value in health.items()]
        self.diagnostics_pub.publish(DiagnosticArray(header=Header(stamp=stamp), status=[status]))

    def publish_graph(self, stamp: Any) -> None:
        """Keyframes as spheres, matching edges and loop closures as lines (slam_toolbox's markers)."""
        with self.lock:
            poses = np.array(self.mapper.graph.poses).reshape(-1, 3)
            edges = list(self.mapper.graph.edges)
        self.graph_pub.publish(graph_markers(poses, edges, self.params.map_frame, stamp))

    # -------------------------------------------------------------- services
    def _save_map(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        grid = self.build_map()
        if grid is None:
            response.success, response.message = False, "no map yet: no scan has been processed"
            return response
        path = self.params.save_name()
        try:
            yaml_path = save_map(grid, path)
        except (MapFileError, OSError) as exc:
            response.success, response.message = False, f"could not save the map to {path}: {exc}"
            return response
        response.success, response.message = True, f"saved {yaml_path}"
        return response

    def _serialize(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        with self.lock:
            snapshot = self.mapper.snapshot()  # written outside the lock: scans go on
        try:
            path = save_posegraph(snapshot, self.params.save_name())
        except PoseGraphFileError as exc:
            response.success, response.message = False, str(exc)
            return response
        response.success, response.message = True, f"saved {path} ({len(snapshot.keyframes)} keyframes)"
        return response

    def _deserialize(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        if not self.params.map_file_name:
            response.success, response.message = False, "set the parameter map_file_name to the pose graph to load"
            return response
        try:
            mapper = self._load(self.params.map_file_name)
        except PoseGraphFileError as exc:
            response.success, response.message = False, str(exc)
            return response
        with self.lock:
            mapper.sensor_offset = self.mapper.sensor_offset
            self.mapper = mapper
        self._request_map()
        response.success, response.message = True, f"mapping on from {posegraph_path(self.params.map_file_name)}"
        return response

    def _pause(self, request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        self.paused = bool(request.data)
        response.success, response.message = True, "paused" if self.paused else "processing scans"
        return response

    def _reset(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        with self.lock:
            self.mapper = Mapper(self.params.mapper_settings(), self.mapper.sensor_offset, defer_loops=True)
        response.success, response.message = True, "the map and pose graph are cleared"
        return response

    def destroy_node(self) -> None:
        self._stopping.set()
        self._map_wake.set()
        _put_dropping_oldest(self._work, None)
        _put_dropping_oldest(self._loops, None)
        for thread in (self._worker, self._loop_closer, self._map_thread):
            thread.join(timeout=3.0)
        super().destroy_node()


def _put_dropping_oldest(work: queue.Queue[Any], item: Any) -> bool:
    """Put ``item``, first dropping the oldest entries while ``work`` is full (releasing the lockstep
    hold each carries first); whether any went."""
    dropped = False
    while True:
        try:
            work.put_nowait(item)
            return dropped
        except queue.Full:
            try:
                old = work.get_nowait()
                dropped = True
                if old is not None:
                    old[0]()
            except queue.Empty:
                pass


def graph_markers(poses: np.ndarray, edges: list[Edge], frame: str, stamp: Any) -> MarkerArray:
    """The pose graph for RViz: keyframes (blue spheres), matching edges (thin blue lines) and
    loop closures (red lines); one marker each, replaced on every update."""
    points = [Point(x=float(x), y=float(y)) for x, y, _ in poses]
    markers = []
    for ident, (kind, width, rgba, segments) in enumerate([
            (Marker.SPHERE_LIST, 0.1, (0.1, 0.3, 1.0, 1.0), None),
            (Marker.LINE_LIST, 0.02, (0.1, 0.3, 1.0, 0.6), [e for e in edges if not e.loop]),
            (Marker.LINE_LIST, 0.03, (1.0, 0.1, 0.1, 1.0), [e for e in edges if e.loop])]):
        marker = Marker(type=kind, action=Marker.ADD, id=ident, ns="slam_toolbox")
        marker.header.frame_id, marker.header.stamp = frame, stamp
        marker.pose.orientation.w = 1.0
        marker.scale.x = marker.scale.y = marker.scale.z = width
        marker.color = ColorRGBA(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3])
        marker.points = points if segments is None else [points[i] for e in segments for i in (e.source, e.target)]
        markers.append(marker)
    return MarkerArray(markers=markers)


def main(args: list[str] | None = None) -> int:
    return run_node(Slam, "slam", args, fatal=(ParameterError, PoseGraphFileError))


if __name__ == "__main__":
    sys.exit(main())
