"""``slam``: online asynchronous grid SLAM, in slam_toolbox's place (``localization:=false``).

``mode: mapping`` (the default) maps, as described here; ``mode: localization`` localizes in a
saved pose graph instead, as slam_toolbox's ``localization_slam_toolbox_node`` does
(:mod:`pppbot_slam.ros.localization`).

Subscribes ``scan`` and TF (``odom_frame → base_frame`` at each scan's stamp, and the
lidar's mounting); publishes ``/map`` and ``/map_metadata`` (transient local, updated
every ``map_update_interval`` in a thread of its own, so mapping never blocks scans; a saved
map is built anew from every keyframe at its optimised pose),
``pose`` (PoseWithCovarianceStamped of ``base_frame`` in ``map_frame``), and the TF
``map_frame → odom_frame`` every ``transform_publish_period``, stamped ahead by
``transform_timeout`` as slam_toolbox does, the pose graph as markers
(``~/graph_visualization``) and its health on ``/diagnostics`` (diagnostic_msgs, with the
map: match responses, closures accepted, rejected and undone, the largest correction, and
whether it is lost — also warned about in the log when it happens). Services, with
slam_toolbox's own types (``slam_toolbox/srv/*``) and names: ``~/save_map`` (SaveMap: Nav2
YAML + PGM at the request's ``name``), ``~/serialize_map`` (SerializePoseGraph: the pose
graph with its scans at ``filename`` + ``.posegraph``), ``~/deserialize_map``
(DeserializePoseGraph: load ``filename`` and map on from it, starting at the first keyframe
or at ``initial_pose``; also done at startup when ``map_file_name`` is set),
``~/pause_new_measurements`` (Pause: toggles taking scans), ``~/clear_queue`` (ClearQueue:
drops the scans waiting) and ``~/reset`` (Reset). An empty file name falls back to the
parameter ``map_save_name`` (saving) or ``map_file_name`` (loading). The algorithm is
:mod:`pppbot_slam.mapper`.

The work is :class:`pppbot_slam.async_mapper.AsyncMapper`'s three threads besides the
executor's (scan processing, loop closing, map building); scans never wait for a loop
search. In lockstep each piece of work is held for (:meth:`pppbot_lockstep.ros.port.StepPort.hold`):
a step is answered once its scan is processed, its loop search merged and its map
published, so the map and the pose graph are the same on every run.
"""
from __future__ import annotations

import sys
import threading
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseWithCovarianceStamped
from nav_msgs.msg import MapMetaData
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from rclpy.duration import Duration
from sensor_msgs.msg import LaserScan
from slam_toolbox.srv import (
    Clear,
    ClearQueue,
    DeserializePoseGraph,
    LoopClosure,
    Pause,
    Reset,
    SaveMap,
    SerializePoseGraph,
    ToggleInteractive,
)
from std_msgs.msg import Header
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import MarkerArray

from pppbot_common.maps import MapFileError, OccupancyGrid, save_map
from pppbot_common.params import ParameterError, check_finite_range, param
from pppbot_common.resources import maps_directory
from pppbot_common.ros.maps import grid_message, map_metadata
from pppbot_common.ros.params import LiveParameters, declare_parameters, serve_live_parameters
from pppbot_common.ros.planar import transform_message
from pppbot_common.ros.qos import LATCHED, SENSOR
from pppbot_common.se2 import quaternion_from_yaw
from pppbot_lockstep.ros.node import StepNode
from pppbot_lockstep.ros.runner import Warnings, guarded, run_node
from pppbot_lockstep.ros.scan_odometry import ScanOdometry
from pppbot_slam.async_mapper import AsyncMapper, AsyncMapperEvents, KeyframeAdded, LoopsMerged
from pppbot_slam.errors import LocalizerError, SessionStartError
from pppbot_slam.mapper import LOST_KEYFRAMES, Mapper, MapperError, MapperSettings
from pppbot_slam.matcher import MatcherError, MatcherSettings
from pppbot_slam.occupancy import OccupancyError
from pppbot_slam.ros.localization import SlamLocalization
from pppbot_slam.ros.markers import graph_markers
from pppbot_slam.ros.scan_input import scan_input
from pppbot_slam.serialization import PoseGraphFileError, load_posegraph, posegraph_path, save_posegraph
from pppbot_slam.session_start import SlamMode, check_start_pose, start_from_parameters, start_from_request

WARN_PERIOD_S = 5.0


@dataclass(frozen=True)
class SlamParameters:
    odom_frame: str = param("odom", "odometry frame")
    map_frame: str = param("map", "map frame")
    base_frame: str = param("base_footprint", "robot base frame")
    scan_topic: str = param("/scan", "laser scan topic")
    mode: str = param("mapping", "mapping (online async SLAM) or localization (in the pose graph of map_file_name, "
                                 "as slam_toolbox's localization_slam_toolbox_node)")
    map_file_name: str = param("", "a pose graph (.posegraph) loaded at startup and by ~/deserialize_map: mapped on "
                                   "from (mapping) or localized in (localization)")
    map_start_pose: list[float] = param([], "where the robot starts in the pose graph loaded at startup "
                                            "[x, y, yaw]; when given it wins over map_start_at_dock")
    map_start_at_dock: bool = param(True, "without map_start_pose: start at the loaded pose graph's first "
                                          "keyframe (false: at the map origin)")
    position_covariance_scale: float = param(1.0, "scales the position covariance of localization's pose")
    yaw_covariance_scale: float = param(1.0, "scales the yaw covariance of localization's pose")
    map_save_name: str = param("", "where ~/save_map and ~/serialize_map write when the request names no file "
                                   "(no extension); default maps/map")
    autosave_name: str = param("", "pppbot's: mapping saves its pose graph here (no extension) every "
                                   "autosave_period, and a node that starts and finds it maps on from it, where "
                                   "it was (a restarted node: launch_sim respawn:=true); empty: no autosave")
    autosave_period: float = param(10.0, "pppbot's: sim seconds between autosaves (with autosave_name)")
    resolution: float = param(0.05, "map cell size (m)")
    max_laser_range: float = param(20.0, "beams are used up to this range (m)")
    minimum_travel_distance: float = param(0.5, "travel between keyframes (m)")
    minimum_travel_heading: float = param(0.5, "turn between keyframes (rad)")
    map_update_interval: float = param(5.0, "seconds between map updates")
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
    loop_search_overlap_distance: float = param(0.0, "pppbot's: loop candidates within this distance (m), off the "
                                                     "path just driven, are also judged on the part of the scan "
                                                     "they saw (0: not)")
    loop_match_minimum_overlap: float = param(0.2, "pppbot's: share of the scan a loop candidate must have seen "
                                                   "to be judged on it")
    loop_match_minimum_response_overlap: float = param(0.7, "pppbot's: response needed over that shared part")
    loop_search_global_distance: float = param(15.0, "pppbot's (Cartographer's max_constraint_distance): older "
                                                     "keyframes within this distance (m) are searched over the "
                                                     "global window once no closure came for a while (0: never)")
    loop_search_global_after_distance: float = param(10.0, "pppbot's: travel without a closure (m) before the "
                                                           "global search starts")
    loop_search_global_space_dimension: float = param(14.0, "pppbot's: global window width (m; Cartographer's "
                                                            "linear_search_window ±7 m)")
    loop_search_global_angle_offset: float = param(0.52, "pppbot's: global window angle ± (rad; Cartographer's "
                                                         "angular_search_window)")
    loop_match_minimum_response_global: float = param(0.55, "pppbot's: fine response a global match needs "
                                                            "(Cartographer's min_score)")
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
        self.slam_mode()
        for name in ("position_covariance_scale", "yaw_covariance_scale"):
            check_finite_range(name, getattr(self, name), 0.0)
        for name in ("map_update_interval", "transform_publish_period", "tf_buffer_duration"):
            check_finite_range(name, getattr(self, name), 0.0, 3600.0, low_open=True)
        check_finite_range("transform_timeout", self.transform_timeout, 0.0, 60.0)
        check_finite_range("autosave_period", self.autosave_period, 0.0, 86400.0, low_open=True)
        for name in ("odom_frame", "map_frame", "base_frame", "scan_topic"):
            if not getattr(self, name):
                raise ParameterError(name, getattr(self, name), "must not be empty")
        try:
            check_start_pose(self.map_start_pose)
        except SessionStartError as exc:
            raise ParameterError("map_start_pose", self.map_start_pose, "must be three finite numbers [x, y, yaw], "
                                 "or empty (not given)") from exc
        try:
            self.mapper_settings()
        except (MapperError, MatcherError, OccupancyError) as exc:
            raise ParameterError("mapper", "", str(exc)) from exc

    def slam_mode(self) -> SlamMode:
        """``mode`` as :class:`SlamMode`.

        Raises:
            ParameterError: neither ``mapping`` nor ``localization``.
        """
        try:
            return SlamMode(self.mode)
        except ValueError:
            raise ParameterError("mode", self.mode, "must be 'mapping' or 'localization'") from None

    def start_pose(self) -> np.ndarray | None:
        """Where the pose graph loaded at startup has the robot start (None: at its first keyframe)."""
        return start_from_parameters(self.map_start_pose, self.map_start_at_dock)

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
        whole_window = replace(loop, search_size_m=self.loop_search_global_space_dimension,
                               search_angle_rad=self.loop_search_global_angle_offset,
                               minimum_distance_penalty=1.0, minimum_angle_penalty=1.0)
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
            loop_search_overlap_distance=self.loop_search_overlap_distance,
            loop_match_minimum_overlap=self.loop_match_minimum_overlap,
            loop_match_minimum_response_overlap=self.loop_match_minimum_response_overlap,
            loop_search_global_distance=self.loop_search_global_distance,
            loop_search_global_after_distance=self.loop_search_global_after_distance,
            loop_match_minimum_response_global=self.loop_match_minimum_response_global,
            matcher=matcher, loop_matcher=loop, global_loop_matcher=whole_window)


_SOLVER = ("the pose graph is solved by GTSAM's Levenberg-Marquardt (loop closures switchable by dynamic "
           "covariance scaling), not Ceres")
#: slam_toolbox keys that mean nothing here, with the reason (named in the start-up warning when given).
NO_EFFECT = {
    "solver_plugin": _SOLVER, "ceres_*": _SOLVER,
    "debug_logging": "the node logs at its --log-level",
    "enable_interactive_mode": "no interactive markers: the graph is not edited from RViz",
    "stack_size_to_use": "Python needs no larger stack to serialize a graph",
    "use_map_saver": "~/save_map is served in mapping mode whatever this says",
    "throttle_scans": "every scan is taken (slam_toolbox's default, 1)",
    "minimum_time_interval": "keyframes are taken by minimum_travel_distance and _heading alone",
    "link_scan_maximum_distance": "each scan is matched against the running buffer "
                                  "(scan_buffer_maximum_scan_distance), not against linked chains",
    "use_response_expansion": "the matcher's search window is fixed (correlation_search_space_dimension)",
    "use_scan_barycenter": "scans are placed at the sensor's pose, not their barycenter",
    "use_scan_matching": "scans are always matched (false, odometry alone, is not offered)",
    "use_sim_time": "",
}


class Slam(StepNode):
    """The ROS side of :class:`~pppbot_slam.async_mapper.AsyncMapper`: scans and TF in, the map,
    pose, transform, graph and health out, and the services. In ``mode: localization`` the work is
    :class:`~pppbot_slam.ros.localization.SlamLocalization`'s (the same publishers)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("slam_toolbox", **kwargs)
        self.params = p = declare_parameters(self, SlamParameters)
        self.parameter_notes = NO_EFFECT
        # What the node reads at each use; the rest (the mode, topics, rates, the matcher's settings)
        # is built into it at start-up, as slam_toolbox reads it once.
        live = {"odom_frame", "base_frame", "map_frame", "transform_timeout", "map_save_name", "map_file_name"}
        serve_live_parameters(self, [LiveParameters("", lambda: self.params, self._set_params, live,
                                                    "it is read once, at start-up, as slam_toolbox's; restart "
                                                    "the node to change it")])
        self._diagnostics_lock = threading.Lock()  # one health reading published at a time
        self.paused = False
        self._warn = Warnings(self, WARN_PERIOD_S, settling=("transform",))
        self.map_pub = self.create_publisher(OccupancyGridMsg, "/map", LATCHED)
        self.meta_pub = self.create_publisher(MapMetaData, "/map_metadata", LATCHED)
        self.graph_pub = self.create_publisher(MarkerArray, "~/graph_visualization", 1)
        self.pose_pub = self.create_publisher(PoseWithCovarianceStamped, "pose", 10)
        self.tf_pub = self.create_publisher(TFMessage, "/tf", 100)
        self.diagnostics_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        # slam_toolbox's interactive-mode services, for its RViz panel: answered, with what happened.
        for srv_type, name in ((Clear, "~/clear_changes"), (LoopClosure, "~/manual_loop_closure"),
                               (ToggleInteractive, "~/toggle_interactive_mode")):
            self.create_service(srv_type, name, self._no_interactive_mode)
        self.localization: SlamLocalization | None = None
        if p.slam_mode() is SlamMode.LOCALIZATION:
            self.localization = SlamLocalization(self, self._warn)
        else:
            self._start_mapping()

    def _start_mapping(self) -> None:
        p = self.params
        events = AsyncMapperEvents(keyframe=self._on_keyframe, loops=self._on_loops, map_built=self._on_map,
                                   warn=self._warn)
        autosaved = posegraph_path(p.autosave_name) if p.autosave_name else None
        if autosaved is not None and autosaved.is_file():
            first = self._resume(autosaved)
        elif p.map_file_name:
            first = self._load(p.map_file_name, p.start_pose())
        else:
            first = Mapper(p.mapper_settings())
        self.mapping = AsyncMapper(first, events, hold=self.port.hold, map_frame=p.map_frame)
        self.scans = ScanOdometry(self, p.odom_frame, p.base_frame, self._queue, self._warn, p.tf_buffer_duration)
        self.create_subscription(LaserScan, p.scan_topic, guarded(self, self.on_scan, "LaserScan"), SENSOR,
                                 data_path=True, at_step=True)
        self.create_service(SaveMap, "~/save_map", self._save_map)
        self.create_service(SerializePoseGraph, "~/serialize_map", self._serialize)
        self.create_service(DeserializePoseGraph, "~/deserialize_map", self._deserialize)
        self.create_service(Pause, "~/pause_new_measurements", self._pause)
        self.create_service(ClearQueue, "~/clear_queue", self._clear_queue)
        self.create_service(Reset, "~/reset", self._reset)
        # map → odom is stamped ahead (transform_timeout): nobody waits for each one.
        self.step_timer(p.transform_publish_period, self._publish_transform, wakes=False)
        self.step_timer(p.map_update_interval, self.mapping.request_map)
        if autosaved is not None:
            self.step_timer(p.autosave_period, self._autosave, wakes=False)
        self.mapping.start()
        self.get_logger().info(f"mapping: {p.scan_topic} with {p.odom_frame} → {p.base_frame}; map every "
                               f"{p.map_update_interval:g} s at {p.resolution} m")

    def _set_params(self, params: SlamParameters) -> None:
        self.params = params
        scans = self.localization.scans if self.localization is not None else self.scans
        scans.odom_frame, scans.base_frame = params.odom_frame, params.base_frame

    def _load(self, name: str, start_pose: np.ndarray | None) -> Mapper:
        """A saved pose graph to map on from, the robot starting at ``start_pose`` (None: at its
        first keyframe).

        Raises:
            PoseGraphFileError: the file is missing or bad (the message names it).
        """
        mapper = load_posegraph(name, self.params.mapper_settings())
        mapper.start_session(start_pose)
        start = mapper.predict(np.zeros(3))  # the new session's first keyframe goes here
        self.get_logger().info(f"mapping on from {posegraph_path(name)}: {len(mapper.keyframes)} keyframes, "
                               f"starting at ({start[0]:.2f}, {start[1]:.2f}, {start[2]:.3f})")
        return mapper

    def _resume(self, autosaved: Path) -> Mapper:
        """Map on from the last autosave, in the same session: the odometry frame is the one the
        saved keyframes were in (the node restarted, the robot did not), so map → odom is where
        it was and the next keyframe links to the last one saved.

        Raises:
            PoseGraphFileError: the autosave is bad (the message names it).
        """
        mapper = load_posegraph(autosaved, self.params.mapper_settings())
        at = mapper.map_to_odom()
        self.get_logger().warning(f"mapping on from the autosave {autosaved} ({len(mapper.keyframes)} keyframes, "
                                  f"map → odom ({at[0]:.2f}, {at[1]:.2f}, {at[2]:.3f})): this node was restarted")
        return mapper

    def _autosave(self) -> None:
        snapshot = self.mapping.read(Mapper.snapshot)
        if not snapshot.keyframes:
            return
        try:
            Path(self.params.autosave_name).expanduser().parent.mkdir(parents=True, exist_ok=True)
            save_posegraph(snapshot, self.params.autosave_name)
        except (PoseGraphFileError, OSError) as exc:
            self._warn("autosave", f"autosave: {exc}")
            return
        self._warn.settled("autosave")

    # ----------------------------------------------------------------- scans
    def on_scan(self, msg: LaserScan) -> None:
        """Queue the scan until odometry reaches its stamp (as tf2's message filter does)."""
        if self.paused:
            return
        self.scans.add(msg)

    def _queue(self, msg: LaserScan, stamp: float, frame: str, odom_pose: np.ndarray, sensor: np.ndarray) -> None:
        scan = scan_input(msg, stamp, frame, odom_pose, sensor, self._warn)
        if scan is not None:
            self.mapping.add_scan(scan)

    def _on_keyframe(self, added: KeyframeAdded) -> None:
        pose = added.pose
        where = f"({pose[0]:.2f}, {pose[1]:.2f}, {pose[2]:.3f})"
        self.get_logger().debug(f"keyframe {added.index} at t = {added.stamp_s:.2f} s: match response "
                                f"{added.response:.2f}, pose {where}")
        if added.recovered:
            self.get_logger().warning(
                f"keyframe {added.index}: the scan did not fit where odometry put it (a collision or a skid?); "
                f"found at {where} by a search over every heading (response {added.response:.2f})")
        if added.lost_changed:
            self._report_lost(added)
        self._publish_pose(added.tag, pose)

    def _on_loops(self, merged: LoopsMerged) -> None:
        for match in merged.accepted:
            self.get_logger().info(f"loop closure: keyframe {match.target} (scan at t = {merged.stamp_s:.2f} s) "
                                   f"with {match.source} (response {match.response:.2f})")
        moved = merged.moved
        if merged.accepted:
            self.get_logger().info(f"the graph solved with keyframe {merged.index}'s closures moved the newest "
                                   f"keyframe {float(np.hypot(moved[0], moved[1])):.3f} m, {float(moved[2]):+.4f} rad")
        if merged.rejected:
            why = f" ({merged.see_through} whose scans saw through each other's walls)" if merged.see_through else ""
            self.get_logger().info(f"keyframe {merged.index} (t = {merged.stamp_s:.2f} s): {merged.rejected} loop "
                                   f"match(es) the pose graph could not agree with{why}, dropped")
        for source, target in merged.undone:
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
        map_to_odom = self.mapping.read(Mapper.map_to_odom)
        stamp = (self.get_clock().now() + Duration(seconds=self.params.transform_timeout)).to_msg()
        self.tf_pub.publish(TFMessage(transforms=[transform_message(self.params.map_frame, self.params.odom_frame,
                                                                    stamp, map_to_odom)]))

    # ------------------------------------------------------------------- map
    def _on_map(self, grid: OccupancyGrid) -> None:
        stamp = self.get_clock().now().to_msg()
        self.map_pub.publish(grid_message(grid, stamp))
        self.meta_pub.publish(map_metadata(grid, stamp))
        self.publish_graph(stamp)
        self.publish_diagnostics(stamp)

    def _report_lost(self, added: KeyframeAdded) -> None:
        if added.lost:
            self.get_logger().warning(
                f"lost at keyframe {added.index} (t = {added.stamp_s:.2f} s): the last {LOST_KEYFRAMES} scans matched "
                f"nothing around where odometry put them (response below {added.required_response}); keyframes are "
                "placed by odometry alone and left out of the map until a scan matches again")
        else:
            self.get_logger().info(f"found again at keyframe {added.index} (t = {added.stamp_s:.2f} s): the scan "
                                   f"matched the map (response {added.response:.2f})")
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
        health = {**self.mapping.read(Mapper.health), "map_rebuilds": self.mapping.map_rebuilds,
                  "map_stale_keyframes": self.mapping.map_stale_keyframes}
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
        poses, edges = self.mapping.read(lambda m: (np.array(m.graph.poses).reshape(-1, 3), list(m.graph.edges)))
        self.graph_pub.publish(graph_markers(poses, edges, self.params.map_frame, stamp))

    # -------------------------------------------------------------- services
    def _save_map(self, request: SaveMap.Request, response: SaveMap.Response) -> SaveMap.Response:
        """The map as map_saver writes it: ``<name>.yaml`` + ``<name>.pgm``."""
        grid = self.mapping.build_map(exact=True)
        if grid is None:
            self.get_logger().error("save_map: no map yet, no scan has been processed")
            response.result = SaveMap.Response.RESULT_NO_MAP_RECEIEVD
            return response
        path = Path(request.name.data).expanduser() if request.name.data else self.params.save_name()
        try:
            yaml_path = save_map(grid, path)
        except (MapFileError, OSError) as exc:
            self.get_logger().error(f"save_map: could not save the map to {path}: {exc}")
            response.result = SaveMap.Response.RESULT_UNDEFINED_FAILURE
            return response
        self.get_logger().info(f"save_map: saved {yaml_path}")
        response.result = SaveMap.Response.RESULT_SUCCESS
        return response

    def _serialize(self, request: SerializePoseGraph.Request,
                   response: SerializePoseGraph.Response) -> SerializePoseGraph.Response:
        """The pose graph with its scans at ``<filename>.posegraph`` (pppbot's format)."""
        snapshot = self.mapping.read(Mapper.snapshot)  # written outside the lock: scans go on
        name = Path(request.filename).expanduser() if request.filename else self.params.save_name()
        try:
            path = save_posegraph(snapshot, name)
        except PoseGraphFileError as exc:
            self.get_logger().error(f"serialize_map: {exc}")
            response.result = SerializePoseGraph.Response.RESULT_FAILED_TO_WRITE_FILE
            return response
        self.get_logger().info(f"serialize_map: saved {path} ({len(snapshot.keyframes)} keyframes)")
        response.result = SerializePoseGraph.Response.RESULT_SUCCESS
        return response

    def _deserialize(self, request: DeserializePoseGraph.Request,
                     response: DeserializePoseGraph.Response) -> DeserializePoseGraph.Response:
        """Load ``filename`` and map on from it. The reply is empty (as in Jazzy's slam_toolbox):
        a refusal is in the log, and the running map is kept."""
        name = request.filename or self.params.map_file_name
        pose = request.initial_pose
        try:
            if not name:
                raise SessionStartError("no filename in the request and no map_file_name parameter")
            start = start_from_request(request.match_type, (pose.x, pose.y, pose.theta))
            mapper = self._load(name, start)
        except (SessionStartError, PoseGraphFileError) as exc:
            self.get_logger().error(f"deserialize_map: not loaded, mapping goes on as it was: {exc}")
            return response
        self.mapping.replace(mapper)
        return response

    def _pause(self, request: Pause.Request, response: Pause.Response) -> Pause.Response:
        """Toggle taking new scans (slam_toolbox's Pause is a toggle)."""
        self.paused = not self.paused
        self.get_logger().info("pause_new_measurements: " + ("paused, new scans are ignored" if self.paused
                                                              else "taking new scans"))
        response.status = True
        return response

    def _no_interactive_mode(self, request: Any, response: Any) -> Any:
        """clear_changes, manual_loop_closure, toggle_interactive_mode: there is no interactive mode
        (no markers to move, so no moved nodes to clear or close a loop with); said in the log."""
        self.get_logger().warning("slam_toolbox's interactive mode is not implemented: no graph node was moved, "
                                  "nothing to clear, close or toggle (the graph closes loops by itself)")
        return response

    def _clear_queue(self, request: ClearQueue.Request, response: ClearQueue.Response) -> ClearQueue.Response:
        """Drop the scans waiting to be matched."""
        dropped = self.mapping.clear_queue()
        self.get_logger().info(f"clear_queue: dropped {dropped} waiting scan(s)")
        response.status = True
        return response

    def _reset(self, request: Reset.Request, response: Reset.Response) -> Reset.Response:
        """Forget the map and the pose graph; pause new scans when asked (a set, not a toggle)."""
        self.mapping.replace(Mapper(self.params.mapper_settings()))
        self.paused = bool(request.pause_new_measurements)
        self.get_logger().info("reset: the map and pose graph are cleared" + (", new scans paused" if self.paused
                                                                               else ""))
        response.result = Reset.Response.RESULT_SUCCESS
        return response

    def destroy_node(self) -> None:
        if self.localization is not None:
            self.localization.stop()
        else:
            self.mapping.stop()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    return run_node(Slam, "slam", args, fatal=(ParameterError, PoseGraphFileError, LocalizerError))


if __name__ == "__main__":
    sys.exit(main())
