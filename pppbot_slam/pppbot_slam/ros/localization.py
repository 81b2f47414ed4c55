"""``mode: localization`` of the ``slam`` node: slam_toolbox's ``localization_slam_toolbox_node``.

Localizes in a saved pose graph (:mod:`pppbot_slam.localizer`, on a worker thread of its own:
:mod:`pppbot_slam.async_localizer`). The graph is loaded at startup from ``map_file_name``, the
robot placed at ``map_start_pose`` (or, with ``map_start_at_dock``, at the graph's first keyframe;
else the map origin), or later by ``~/deserialize_map``.

Subscribes ``scan`` and TF (``odom_frame → base_frame`` at each scan's stamp) and ``initialpose``
(PoseWithCovarianceStamped in ``map_frame``, RViz's "2D Pose Estimate": the next scan is placed
there and matched from there, and the rolling buffer cleared). Publishes ``/map`` and
``/map_metadata`` (the loaded graph's map, latched, on each load), ``pose``
(PoseWithCovarianceStamped of ``base_frame`` in ``map_frame`` for each scan taken, its covariance
that of the match scaled by ``position_covariance_scale`` / ``yaw_covariance_scale``, as
slam_toolbox fills it), TF ``map_frame → odom_frame`` every ``transform_publish_period`` once the
first scan is localized (stamped ahead by ``transform_timeout``), and every
``map_update_interval`` the graph with the rolling buffer as markers (``~/graph_visualization``)
and its health on ``/diagnostics``.

Services, as slam_toolbox's localization node has them: ``~/deserialize_map``
(DeserializePoseGraph, ``LOCALIZE_AT_POSE`` with ``initial_pose`` only; the reply is empty, a
refusal is in the log), ``~/serialize_map`` (refused: the graph localized in is not changed;
``result`` 255), ``~/pause_new_measurements`` (toggle), ``~/reset`` (forgets the graph),
``~/clear_localization_buffer`` (std_srvs/Empty), and pppbot's ``~/clear_queue``. There is no
``~/save_map``: slam_toolbox's localization node turns its map saver off (``map_saver`` saves
``/map``).
"""
from __future__ import annotations

import threading
from typing import TYPE_CHECKING, Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseWithCovarianceStamped
from rclpy.duration import Duration
from sensor_msgs.msg import LaserScan
from slam_toolbox.srv import ClearQueue, DeserializePoseGraph, Pause, Reset, SerializePoseGraph
from std_msgs.msg import Header
from std_srvs.srv import Empty
from tf2_msgs.msg import TFMessage

from pppbot_common.ros.maps import grid_message, map_metadata
from pppbot_common.ros.planar import transform_message
from pppbot_common.ros.qos import SENSOR
from pppbot_common.se2 import quaternion_from_yaw, yaw_from_quaternion
from pppbot_lockstep.ros.runner import Warnings, guarded
from pppbot_lockstep.ros.scan_odometry import ScanOdometry
from pppbot_slam.async_localizer import AsyncLocalizer, LocalizerEvents
from pppbot_slam.errors import LocalizerError, PoseGraphFileError, SessionStartError
from pppbot_slam.localizer import LocalizedPose, Localizer
from pppbot_slam.mapper import LOST_KEYFRAMES
from pppbot_slam.ros.markers import graph_markers
from pppbot_slam.ros.scan_input import scan_input
from pppbot_slam.serialization import load_posegraph, posegraph_path
from pppbot_slam.session_start import localization_start_from_request

if TYPE_CHECKING:
    from pppbot_slam.ros.slam import Slam


class SlamLocalization:
    """The ``slam`` node's localization mode: wires ``node``'s publishers, scans, ``initialpose`` and
    the services to an :class:`~pppbot_slam.async_localizer.AsyncLocalizer`.

    Raises:
        PoseGraphFileError, LocalizerError: ``map_file_name`` cannot be loaded or localized in.
    """

    def __init__(self, node: Slam, warn: Warnings) -> None:
        self.node = node
        self._warn = warn
        self._diagnostics_lock = threading.Lock()
        p = node.params
        first = self._load(p.map_file_name, p.start_pose()) if p.map_file_name else None
        self.worker = AsyncLocalizer(first, LocalizerEvents(localized=self._on_localized, warn=warn),
                                     hold=node.port.hold)
        self.scans = ScanOdometry(node, p.odom_frame, p.base_frame, self._queue, warn, p.tf_buffer_duration)
        node.create_subscription(LaserScan, p.scan_topic, guarded(node, self.on_scan, "LaserScan"), SENSOR,
                                 data_path=True, at_step=True)
        node.create_subscription(PoseWithCovarianceStamped, "initialpose",
                                 guarded(node, self.on_initial_pose, "PoseWithCovarianceStamped"), 10)
        node.create_service(SerializePoseGraph, "~/serialize_map", self._serialize)
        node.create_service(DeserializePoseGraph, "~/deserialize_map", self._deserialize)
        node.create_service(Pause, "~/pause_new_measurements", self._pause)
        node.create_service(ClearQueue, "~/clear_queue", self._clear_queue)
        node.create_service(Reset, "~/reset", self._reset)
        node.create_service(Empty, "~/clear_localization_buffer", self._clear_buffer)
        node.step_timer(p.transform_publish_period, self._publish_transform, wakes=False)
        node.step_timer(p.map_update_interval, self._publish_status, wakes=False)
        self.worker.start()
        if first is not None:
            self._publish_map(first)
        else:
            node.get_logger().info("localization: no map_file_name; waiting for ~/deserialize_map "
                                   "(LOCALIZE_AT_POSE) to load a pose graph")
        node.get_logger().info(f"localization: {p.scan_topic} with {p.odom_frame} → {p.base_frame}; a scan every "
                               f"{p.minimum_travel_distance:g} m or {p.minimum_travel_heading:g} rad, rolling buffer "
                               f"of {p.scan_buffer_size}")

    def stop(self) -> None:
        self.worker.stop()

    def _load(self, name: str, start_pose: np.ndarray | None) -> Localizer:
        """A saved pose graph to localize in, the robot at ``start_pose`` (None: its first keyframe).

        Raises:
            PoseGraphFileError: the file is missing or bad (the message names it).
            LocalizerError: the graph has no keyframes.
        """
        localizer = Localizer(load_posegraph(name, self.node.params.mapper_settings()), start_pose)
        start = localizer.pending
        assert start is not None
        self.node.get_logger().info(f"localizing in {posegraph_path(name)}: {len(localizer.graph.keyframes)} "
                                    f"keyframes, starting at ({start[0]:.2f}, {start[1]:.2f}, {start[2]:.3f})")
        return localizer

    def _publish_map(self, localizer: Localizer) -> None:
        """The loaded graph's map on ``/map`` and ``/map_metadata`` (latched)."""
        grid = localizer.grid(self.node.params.map_frame)
        stamp = self.node.get_clock().now().to_msg()
        self.node.map_pub.publish(grid_message(grid, stamp))
        self.node.meta_pub.publish(map_metadata(grid, stamp))

    # ----------------------------------------------------------------- scans
    def on_scan(self, msg: LaserScan) -> None:
        """Queue the scan until odometry reaches its stamp (as tf2's message filter does)."""
        if self.node.paused:
            return
        if not self.worker.loaded:
            self._warn("no graph", "no pose graph to localize in: set map_file_name, or call ~/deserialize_map "
                                   "with LOCALIZE_AT_POSE; scans are ignored until then")
            return
        self.scans.add(msg)

    def _queue(self, msg: LaserScan, stamp: float, frame: str, odom_pose: np.ndarray, sensor: np.ndarray) -> None:
        scan = scan_input(msg, stamp, frame, odom_pose, sensor, self._warn)
        if scan is not None:
            self.worker.add_scan(scan)

    def on_initial_pose(self, msg: PoseWithCovarianceStamped) -> None:
        """Localize at the pose given (slam_toolbox's ``localizePoseCallback``): the next scan is
        placed there and matched from there; the rolling buffer is cleared."""
        frame = msg.header.frame_id.lstrip("/")
        map_frame = self.node.params.map_frame
        if frame not in ("", map_frame):
            self._warn("initial pose", f"ignoring an initial pose in frame '{msg.header.frame_id}': it must be in "
                                       f"map_frame '{map_frame}'")
            return
        position, o = msg.pose.pose.position, msg.pose.pose.orientation
        pose = np.array([position.x, position.y, yaw_from_quaternion(o.x, o.y, o.z, o.w)])
        try:
            taken = self.worker.relocalize(pose)
        except LocalizerError as exc:
            self._warn("initial pose", f"ignoring an initial pose: {exc}")
            return
        if not taken:
            self._warn("initial pose", "ignoring an initial pose: no pose graph is loaded")
            return
        self.node.get_logger().info(f"initialpose: localizing at ({pose[0]:.2f}, {pose[1]:.2f}, {pose[2]:.3f})")

    def _on_localized(self, localized: LocalizedPose, stamp: Any) -> None:
        """A scan was taken (the worker's thread): its pose goes out; relocalizations and being
        lost are logged."""
        x, y, yaw = localized.pose
        where = f"({x:.2f}, {y:.2f}, {yaw:.3f})"
        log = self.node.get_logger()
        if localized.relocalized:
            if localized.matched:
                log.info(f"localized at {where} (match response {localized.response:.2f})")
            else:
                log.warning(f"the scan at the given pose matched nothing around it (response "
                            f"{localized.response:.2f}): taking {where} as given")
        if localized.lost_changed:
            if localized.lost:
                log.warning(f"lost: the last {LOST_KEYFRAMES} scans matched nothing around where odometry put "
                            f"them (response below {localized.required_response}); following odometry until a "
                            "scan matches the map again (or give a pose on initialpose)")
            else:
                log.info(f"found again at {where}: the scan matched the map (response {localized.response:.2f})")
            self._publish_diagnostics(self.node.get_clock().now().to_msg())
        self.node.pose_pub.publish(self.pose_message(localized, stamp))

    def pose_message(self, localized: LocalizedPose, stamp: Any) -> PoseWithCovarianceStamped:
        """``localized`` as slam_toolbox publishes it on ``pose``: x, y, yaw with the covariance of x,
        y and yaw (scaled), the other entries zero."""
        p = self.node.params
        msg = PoseWithCovarianceStamped()
        msg.header.stamp, msg.header.frame_id = stamp, p.map_frame
        msg.pose.pose.position.x, msg.pose.pose.position.y = float(localized.pose[0]), float(localized.pose[1])
        o = msg.pose.pose.orientation
        o.x, o.y, o.z, o.w = quaternion_from_yaw(float(localized.pose[2]))
        covariance = np.zeros(36)
        c = localized.covariance
        covariance[[0, 1, 6, 7]] = np.array([c[0, 0], c[0, 1], c[1, 0], c[1, 1]]) * p.position_covariance_scale
        covariance[35] = c[2, 2] * p.yaw_covariance_scale
        msg.pose.covariance = covariance.tolist()
        return msg

    def _publish_transform(self) -> None:
        map_to_odom = self.worker.map_to_odom
        if map_to_odom is None:
            return  # not localized yet (slam_toolbox publishes none before its first scan either)
        p = self.node.params
        stamp = (self.node.get_clock().now() + Duration(seconds=p.transform_timeout)).to_msg()
        self.node.tf_pub.publish(TFMessage(transforms=[transform_message(p.map_frame, p.odom_frame, stamp,
                                                                         map_to_odom)]))

    # ---------------------------------------------------------------- health
    def _publish_status(self) -> None:
        stamp = self.node.get_clock().now().to_msg()
        self._publish_diagnostics(stamp)
        graph = self.worker.read(lambda loc: (np.array(loc.graph.graph.poses).reshape(-1, 3),
                                              list(loc.graph.graph.edges),
                                              np.array([b.pose for b in loc.buffer]).reshape(-1, 3)))
        if graph is not None:
            poses, edges, buffered = graph
            self.node.graph_pub.publish(graph_markers(poses, edges, self.node.params.map_frame, stamp, buffered))

    def _publish_diagnostics(self, stamp: Any) -> None:
        """The localizer's health as one DiagnosticStatus (WARN while lost or with no graph)."""
        with self._diagnostics_lock:
            health = self.worker.read(Localizer.health)
            status = DiagnosticStatus(name=f"{self.node.get_name()}: localization",
                                      hardware_id=self.node.params.scan_topic)
            if health is None:
                status.level, status.message, health = DiagnosticStatus.WARN, "no pose graph loaded", {}
            elif health["lost"]:
                status.level, status.message = DiagnosticStatus.WARN, "lost: scans do not match the map"
            else:
                status.level = DiagnosticStatus.OK
                status.message = "localizing" if health["localized"] else "waiting for a scan"
            status.values = [KeyValue(key=key, value=str(value).lower() if isinstance(value, bool) else str(value))
                             for key, value in health.items()]
            self.node.diagnostics_pub.publish(DiagnosticArray(header=Header(stamp=stamp), status=[status]))

    # -------------------------------------------------------------- services
    def _serialize(self, request: SerializePoseGraph.Request,
                   response: SerializePoseGraph.Response) -> SerializePoseGraph.Response:
        """Refused, as slam_toolbox's localization node refuses it: the graph localized in is the one
        loaded, unchanged (serialize it while mapping)."""
        self.node.get_logger().error("serialize_map: not in localization mode (as with slam_toolbox): the pose graph "
                                     "localized in is the loaded file, unchanged; serialize while mapping")
        response.result = SerializePoseGraph.Response.RESULT_FAILED_TO_WRITE_FILE
        return response

    def _deserialize(self, request: DeserializePoseGraph.Request,
                     response: DeserializePoseGraph.Response) -> DeserializePoseGraph.Response:
        """Load ``filename`` (or ``map_file_name``) and localize in it at ``initial_pose``
        (``LOCALIZE_AT_POSE`` only). The reply is empty (Jazzy's); a refusal is in the log and the
        graph localized in is kept."""
        name = request.filename or self.node.params.map_file_name
        pose = request.initial_pose
        try:
            if not name:
                raise SessionStartError("no filename in the request and no map_file_name parameter")
            start = localization_start_from_request(request.match_type, (pose.x, pose.y, pose.theta))
            localizer = self._load(name, start)
        except (SessionStartError, PoseGraphFileError, LocalizerError) as exc:
            self.node.get_logger().error(f"deserialize_map: not loaded, localization goes on as it was: {exc}")
            return response
        self.worker.replace(localizer)
        self._publish_map(localizer)
        return response

    def _pause(self, request: Pause.Request, response: Pause.Response) -> Pause.Response:
        """Toggle taking new scans (slam_toolbox's Pause is a toggle)."""
        self.node.paused = not self.node.paused
        self.node.get_logger().info("pause_new_measurements: " + ("paused, new scans are ignored"
                                                                  if self.node.paused else "taking new scans"))
        response.status = True
        return response

    def _clear_queue(self, request: ClearQueue.Request, response: ClearQueue.Response) -> ClearQueue.Response:
        dropped = self.worker.clear_queue()
        self.node.get_logger().info(f"clear_queue: dropped {dropped} waiting scan(s)")
        response.status = True
        return response

    def _reset(self, request: Reset.Request, response: Reset.Response) -> Reset.Response:
        """Forget the pose graph and the localization (until ``~/deserialize_map``); pause new scans
        when asked (a set, not a toggle)."""
        self.worker.replace(None)
        self.node.paused = bool(request.pause_new_measurements)
        self.node.get_logger().info("reset: the pose graph is forgotten; ~/deserialize_map loads one"
                                    + (", new scans paused" if self.node.paused else ""))
        response.result = Reset.Response.RESULT_SUCCESS
        return response

    def _clear_buffer(self, request: Empty.Request, response: Empty.Response) -> Empty.Response:
        """slam_toolbox's ``clear_localization_buffer``: the rolling buffer is emptied."""
        self.worker.read(Localizer.clear_buffer)
        self.node.get_logger().info("clear_localization_buffer: the rolling buffer is cleared")
        return response
