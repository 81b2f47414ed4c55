"""``viz``: the live view. Streams what the robot knows to rerun, on sim time, as RViz shows it.

Shown (each when its topic exists): ``/map`` in map colours and the global and local costmaps
in costmap colours (each logged only when it changed), ``/scan``, the TF tree with the robot
model from ``/robot_description``, ``/plan`` and ``/local_plan``, ``/particle_cloud``,
``/amcl_pose`` with its covariance, the costmaps' footprints, the ``/odom`` trail, ``/goal_pose`` and ``/initialpose``,
camera images (any sensor_msgs/Image or CompressedImage topic, found as it appears) and the
SLAM pose graph (``/slam_toolbox/graph_visualization``).

Where it goes: ``rerun_port`` streams to a rerun server on 127.0.0.1 (``rerun --serve-web``,
started by ``launch_sim``), ``recording_path`` writes a ``.rrd`` file; both may be set.
``port`` serves the web page (``pppbot_viz.web``): the viewer plus RViz's "2D Pose Estimate"
and "2D Goal Pose" tools, which this node publishes on ``/initialpose`` and ``/goal_pose``.

Memory is bounded: the trail is decimated past ``trail_max_points``, images and particle
clouds are rate limited, and the server drops its oldest data past its memory limit.
"""
from __future__ import annotations

import math
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import rerun as rr
import rerun.blueprint as rrb
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PolygonStamped, PoseStamped, PoseWithCovarianceStamped
from nav2_msgs.msg import ParticleCloud
from nav_msgs.msg import OccupancyGrid, Odometry
from nav_msgs.msg import Path as PathMsg
from rclpy.clock import Clock, ClockType
from rclpy.qos import QoSProfile
from sensor_msgs.msg import CompressedImage, Image, LaserScan
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import MarkerArray

from pppbot_common.params import ParameterError, check_finite_range, param
from pppbot_common.ros.params import declare_parameters
from pppbot_common.ros.qos import DEFAULT, LATCHED, SENSOR, lowered_for
from pppbot_common.transforms import TransformError
from pppbot_lockstep.ros.node import StepNode
from pppbot_lockstep.ros.runner import Warnings, guarded, run_node
from pppbot_lockstep.ros.tf_listener import TfListener
from pppbot_viz.ros import convert
from pppbot_viz.viewer import grpc_url
from pppbot_viz.visuals import ChangeFilter, RateLimit, Trail
from pppbot_viz.web import POSE_KINDS, TIMELINE, PoseRequest, ViewerPage

BATCH_PERIOD_S = 0.5
BATCH_BYTES = 4 << 20
#: RViz's 2D Pose Estimate covariance: 0.5 m in x and y, pi/12 in yaw
INITIAL_POSE_COVARIANCE = {0: 0.25, 7: 0.25, 35: 0.06853891945200942}
IMAGE_TYPES = {"sensor_msgs/msg/Image": Image, "sensor_msgs/msg/CompressedImage": CompressedImage}
GRAPH_TOPIC = "/slam_toolbox/graph_visualization"
#: Seconds of message time going back that make a new recording (a bag played again)
TIME_JUMP_S = 1.0
#: seconds of transforms the node keeps to place scans at their stamps
TF_CACHE_S = 10.0
#: a scan waits this long (wall seconds) for the transforms of its stamp before it is shown in its own frame
SCAN_WAIT_S = 1.0
#: how often the node looks whether a page's viewer started (wall seconds)
REPLAY_CHECK_S = 0.5
#: a page's viewer not heard of for this long is gone (its page says it is open every 5 s)
VIEWER_GONE_S = 15.0
#: RViz's background: dark grey, so free cells (white) and unknown ones (grey-green) stand out
BACKGROUND = [48, 48, 48]


@dataclass(frozen=True)
class VizParameters:
    rerun_port: int = param(0, "the rerun server's gRPC port on 127.0.0.1 to stream to (0: none)")
    rerun_web_port: int = param(0, "the rerun server's web viewer port (the page forwards the viewer's files)")
    port: int = param(-1, "the web page's port on 127.0.0.1 (0: a free one; -1: no page)")
    recording_path: str = param("", "also write the stream to this .rrd file (empty: none)")
    fixed_frame: str = param("map", "the view's frame, as RViz's Fixed Frame")
    application_id: str = param("pppbot", "the rerun application id (recordings of one id share a layout)")
    image_max_rate_hz: float = param(2.0, "camera images shown at most this often, per topic (0: every one)")
    particles_max_rate_hz: float = param(5.0, "particle clouds shown at most this often (0: every one)")
    scan_max_rate_hz: float = param(0.0, "scans shown at most this often (0: every one; a recording may want fewer)")
    tf_max_rate_hz: float = param(10.0, "each moving frame's transform shown at most this often (0: every one); "
                                        "scans are placed in fixed_frame at their own stamp whatever this is")
    trail_spacing: float = param(0.05, "the odometry trail keeps positions this far apart (m)")
    trail_max_points: int = param(4000, "the trail keeps its newest this many points")
    announce: bool = param(True, "log the page's address (launch_sim prints it itself)")
    images_while_watched: bool = param(True, "subscribe to camera topics only while a page's viewer is open or a "
                                             "recording is written (false: always, e.g. for a native viewer)")
    image_discovery_period: float = param(2.0, "how often new camera topics are looked for (s of wall time)")

    def validate(self) -> None:
        for name in ("rerun_port", "rerun_web_port"):
            if not 0 <= getattr(self, name) <= 65535:
                raise ParameterError(name, getattr(self, name), "must be a port number 0-65535")
        if not -1 <= self.port <= 65535:
            raise ParameterError("port", self.port, "must be a port number 0-65535, or -1 for no page")
        if self.port >= 0 and not (self.rerun_port and self.rerun_web_port):
            raise ParameterError("port", self.port, "the page needs rerun_port and rerun_web_port (a rerun server)")
        if not self.fixed_frame or any(c.isspace() for c in self.fixed_frame):
            raise ParameterError("fixed_frame", self.fixed_frame, "must be a frame name without white space")
        check_finite_range("image_max_rate_hz", self.image_max_rate_hz, 0.0)
        check_finite_range("particles_max_rate_hz", self.particles_max_rate_hz, 0.0)
        check_finite_range("scan_max_rate_hz", self.scan_max_rate_hz, 0.0)
        check_finite_range("tf_max_rate_hz", self.tf_max_rate_hz, 0.0)
        check_finite_range("trail_spacing", self.trail_spacing, 1e-6)
        if self.trail_max_points < 2:
            raise ParameterError("trail_max_points", self.trail_max_points, "must be at least 2")
        check_finite_range("image_discovery_period", self.image_discovery_period, 0.1)


def blueprint(fixed_frame: str) -> rrb.Blueprint:
    """The default layout: the map from above (where clicks set poses) beside a 3D view and the
    camera images."""
    top_down = rrb.Spatial3DView(
        origin="/", name=f"{fixed_frame} (top-down)", contents=["+ /**", "- /camera/**"],
        spatial_information=rrb.SpatialInformation(target_frame=fixed_frame, show_axes=False),
        eye_controls=rrb.EyeControls3D(kind=rrb.Eye3DKind.Orbital, position=[0.0, 0.0, 25.0],
                                       look_target=[0.0, 0.0, 0.0], eye_up=[0.0, 1.0, 0.0]),
        line_grid=rrb.LineGrid3D(visible=False), background=BACKGROUND)
    scene = rrb.Spatial3DView(
        origin="/", name="3D", contents=["+ /**", "- /camera/**"],
        spatial_information=rrb.SpatialInformation(target_frame=fixed_frame),
        eye_controls=rrb.EyeControls3D(kind=rrb.Eye3DKind.Orbital, tracking_entity="/robot"),
        background=BACKGROUND)
    cameras = rrb.Spatial2DView(origin="/camera", name="camera")
    health = rrb.TextDocumentView(origin="/slam/health", name="SLAM")
    return rrb.Blueprint(rrb.Horizontal(top_down, rrb.Vertical(scene, cameras, health, row_shares=[4, 3, 3]),
                                        column_shares=[3, 2]),
                         rrb.TimePanel(state="collapsed"), collapse_panels=True)


class Subscribed(NamedTuple):
    msg_type: Any
    wanted: QoSProfile
    callback: Any
    subscription: Any


class Viz(StepNode):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__("viz", **kwargs)
        self.params = p = declare_parameters(self, VizParameters)
        p.validate()
        self.subscribed: dict[str, Subscribed] = {}
        self.warn = Warnings(self)
        # Chunks of half a second: a viewer ingests at most 10 ms of messages a frame, and a web
        # viewer without a GPU draws 2-4 frames a second; it keeps up with a few large chunks where
        # chunks of a fifth of a second left it minutes behind (benchmarks/view_browser.py).
        self.recordings = 0
        self.rec = self._new_recording()
        #: what was logged static (the robot model, /tf_static), for a new recording after a time jump
        self.statics: dict[str, list[Any]] = {}
        self.newest_s = -math.inf  # the newest /scan or /odom stamp: time going back is a new recording
        self.grids = ChangeFilter()
        self.trail = Trail(p.trail_spacing, p.trail_max_points)
        self.trail_frame = ""
        self.slam_health: str | None = None  # the SLAM health text shown last
        self.particle_rate = RateLimit(p.particles_max_rate_hz)
        self.scan_rate = RateLimit(p.scan_max_rate_hz)
        self.tf_rates: dict[str, RateLimit] = {}
        #: each static frame's parent and height in it (a scan placed in fixed_frame keeps its sensor's height)
        self.static_heights: dict[str, tuple[str, float]] = {}
        #: the newest scan, waiting for the transforms of its stamp (RViz's message filter)
        self.pending_scan: tuple[LaserScan, float] | None = None
        self.tf = TfListener(self, self.warn, cache_s=TF_CACHE_S, on_tf=self._place_scan).buffer
        self.image_rates: dict[str, RateLimit] = {}
        #: what a viewer that starts late is sent again (the newest of each: maps, costmaps, plans,
        #: poses, the trail's segments, the SLAM graph's markers), by entity path: (time s, archetypes)
        self.shown: dict[str, tuple[float, list[Any]]] = {}
        self._viewer_started = threading.Event()
        self._viewer_heard_s = -math.inf  # monotonic time a page's viewer last said it is open
        self.pose_pubs = {"goal": self.create_publisher(PoseStamped, POSE_KINDS["goal"], 10),
                          "initial": self.create_publisher(PoseWithCovarianceStamped, POSE_KINDS["initial"], 10)}
        self.page: ViewerPage | None = None
        if p.port >= 0:
            # Before the subscriptions: a launch that sees them knows the page is up.
            self.page = ViewerPage(p.port, p.rerun_port, p.rerun_web_port, self._set_pose, p.fixed_frame,
                                   on_viewer=self._heard_viewer)
            self.page.start()
            if p.announce:  # launch_sim prints the address itself, once, when everything is up
                self.get_logger().info(f"live view: {self.page.url}")
        colormaps = rr.components.Colormap
        self._subscribe(OccupancyGrid, "/map", LATCHED, lambda m: self._grid("map", m, colormaps.RvizMap, 1.0, 0.0))
        self._subscribe(OccupancyGrid, "/global_costmap/costmap", LATCHED,
                        lambda m: self._grid("costmaps/global", m, colormaps.RvizCostmap, 0.5, 0.01))
        self._subscribe(OccupancyGrid, "/local_costmap/costmap", LATCHED,
                        lambda m: self._grid("costmaps/local", m, colormaps.RvizCostmap, 0.6, 0.02))
        for costmap in ("global_costmap", "local_costmap"):
            self._subscribe(PolygonStamped, f"/{costmap}/published_footprint", DEFAULT, lambda m, c=costmap: self._log(
                f"costmaps/{c.removesuffix('_costmap')}/footprint", m.header,
                convert.polygon(m, convert.FOOTPRINT_COLOR), keep=True))
        self._subscribe(LaserScan, "/scan", SENSOR, self._scan)
        self._subscribe(TFMessage, "/tf", QoSProfile(depth=100), lambda m: self._tf(m, static=False))
        self._subscribe(TFMessage, "/tf_static", LATCHED_MANY, lambda m: self._tf(m, static=True))
        self._subscribe(String, "/robot_description", LATCHED, self._robot)
        self._subscribe(PathMsg, "/plan", DEFAULT,
                        lambda m: self._log("plans/global", m.header, convert.path(m, convert.PLAN_COLOR), keep=True))
        self._subscribe(PathMsg, "/local_plan", DEFAULT, lambda m: self._log(
            "plans/local", m.header, convert.path(m, convert.LOCAL_PLAN_COLOR), keep=True))
        self._subscribe(ParticleCloud, "/particle_cloud", SENSOR, self._particles)
        self._subscribe(PoseWithCovarianceStamped, "/amcl_pose", LATCHED,
                        lambda m: self._log("amcl/pose", m.header, convert.pose_with_covariance(m), keep=True))
        self._subscribe(Odometry, "/odom", DEFAULT, self._odom)
        self._subscribe(PoseStamped, "/goal_pose", DEFAULT,
                        lambda m: self._log("goals/goal_pose", m.header, convert.pose(m), keep=True))
        self._subscribe(PoseWithCovarianceStamped, "/initialpose", DEFAULT,
                        lambda m: self._log("goals/initialpose", m.header, convert.pose_with_covariance(m), keep=True))
        self._subscribe(MarkerArray, GRAPH_TOPIC, DEFAULT, self._markers)
        self._subscribe(DiagnosticArray, "/diagnostics", DEFAULT, self._diagnostics)
        self.image_topics: set[str] = set()
        self._discover()
        self.discovery_timer = self.create_timer(p.image_discovery_period, self._discover,
                                                 clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.replay_timer = self.create_timer(REPLAY_CHECK_S, self._replay_if_asked,
                                              clock=Clock(clock_type=ClockType.STEADY_TIME))

    # ------------------------------------------------------------ plumbing
    def _new_recording(self) -> rr.RecordingStream:
        """A recording streaming to the server and/or the file; after the first, the file's name
        gets ``-2``, ``-3``…: one recording per file."""
        p = self.params
        self.recordings += 1
        rec = rr.RecordingStream(p.application_id, batcher_config=rr.ChunkBatcherConfig(
            flush_tick=BATCH_PERIOD_S, flush_num_bytes=BATCH_BYTES))
        sinks: list[Any] = []
        if p.rerun_port:
            sinks.append(rr.GrpcSink(grpc_url(p.rerun_port)))
        if p.recording_path:
            path = Path(p.recording_path)
            if self.recordings > 1:
                path = path.with_name(f"{path.stem}-{self.recordings}{path.suffix}")
            path.parent.mkdir(parents=True, exist_ok=True)
            sinks.append(rr.FileSink(str(path)))
        if sinks:
            rec.set_sinks(*sinks, default_blueprint=blueprint(p.fixed_frame))
        return rec

    def _subscribe(self, msg_type: Any, topic: str, qos: QoSProfile, callback: Any) -> None:
        subscription = self.create_subscription(msg_type, topic, guarded(self, callback, topic), qos)
        self.subscribed[topic] = Subscribed(msg_type, qos, callback, subscription)

    def _match_publishers(self) -> None:
        """Subscribe again, best effort or volatile, where a publisher offers no more (a bag recorded
        without QoS, another tool's node): otherwise DDS would connect them silently never."""
        for topic, sub in list(self.subscribed.items()):
            infos = self.get_publishers_info_by_topic(topic)
            if not infos:
                continue
            qos = lowered_for(sub.wanted, infos)
            current = sub.subscription.qos_profile
            if (qos.reliability, qos.durability) == (current.reliability, current.durability):
                continue
            self.destroy_subscription(sub.subscription)
            self.subscribed[topic] = Subscribed(sub.msg_type, sub.wanted, sub.callback, self.create_subscription(
                sub.msg_type, topic, guarded(self, sub.callback, topic), qos))
            self.get_logger().info(f"{topic}: subscribed {qos.reliability.name.lower()} and "
                                   f"{qos.durability.name.lower()}, as its publishers offer")

    def _discover(self) -> None:
        if self._watched():
            self._find_images()
        elif self.image_topics:
            self._drop_images()
        self._match_publishers()

    def _heard_viewer(self, started: bool) -> None:
        """A page's viewer started (``started``) or says it is still open (the page server's thread)."""
        self._viewer_heard_s = time.monotonic()
        if started:
            self._viewer_started.set()

    def _watched(self) -> bool:
        """Whether camera images are wanted now: someone looks (a page's viewer said so lately) or
        everything is kept (a recording), or always (``images_while_watched`` false). A camera
        nobody subscribes to is not rendered: an open bringup costs less with no page open."""
        p = self.params
        return (not p.images_while_watched or bool(p.recording_path)
                or time.monotonic() - self._viewer_heard_s < VIEWER_GONE_S)

    def _drop_images(self) -> None:
        for topic in sorted(self.image_topics):
            self.destroy_subscription(self.subscribed.pop(topic).subscription)
        self.get_logger().info(f"no viewer open: not showing {', '.join(sorted(self.image_topics))} until one is")
        self.image_topics.clear()

    def _check_time(self, header: Any) -> None:
        """Time going back by over a second on /scan or /odom (one publisher each, so their stamps
        only grow; a bag played again, a simulator restarted): the view starts a new recording,
        with the robot model and /tf_static, as RViz resets."""
        stamp_s = convert.stamp_seconds(header.stamp)
        if stamp_s <= 0.0:
            return
        if stamp_s < self.newest_s - TIME_JUMP_S:
            self.get_logger().info(f"time went back from {self.newest_s:.1f} s to {stamp_s:.1f} s: "
                                   f"a new recording in the view")
            old, self.rec = self.rec, self._new_recording()
            old.flush(timeout_sec=2.0)
            for path, archetypes in self.statics.items():
                self.rec.log(path, *archetypes, static=True)
            self.grids = ChangeFilter()
            self.slam_health = None
            self.shown.clear()
            self.trail_frame = ""
            self.newest_s = stamp_s
        else:
            self.newest_s = max(self.newest_s, stamp_s)

    def _log_static(self, path: str, archetypes: list[Any]) -> None:
        self.statics[path] = archetypes
        self.rec.log(path, *archetypes, static=True)

    def _at(self, header: Any) -> None:
        self.rec.set_time(TIMELINE, duration=convert.stamp_seconds(header.stamp))

    def _log(self, path: str, header: Any, archetypes: list[Any], keep: bool = False) -> None:
        """Log ``archetypes`` at ``path`` at the header's time; ``keep``: the newest of ``path``,
        sent again to a viewer that starts later (what it shows until it changes)."""
        self._at(header)
        self.rec.log(path, *archetypes)
        if keep:
            self.shown[path] = (convert.stamp_seconds(header.stamp), archetypes)

    def _forget(self, prefix: str) -> None:
        """No longer send ``prefix`` and what is under it to viewers that start later (cleared)."""
        for path in [p for p in self.shown if p == prefix or p.startswith(prefix + "/")]:
            del self.shown[path]

    def _replay_if_asked(self) -> None:
        """A page's viewer started: send it what the view shows now, each at its own time. The
        server keeps only the newest minutes of the stream; a map published once at the start (a
        map_server's) or a trail driven an hour ago would be gone from it."""
        if not self._viewer_started.is_set():
            return
        self._viewer_started.clear()
        for path, archetypes in self.statics.items():
            self.rec.log(path, *archetypes, static=True)
        for path, (stamp_s, archetypes) in sorted(self.shown.items(), key=lambda item: item[1][0]):
            self.rec.set_time(TIMELINE, duration=stamp_s)
            self.rec.log(path, *archetypes)
        self.get_logger().debug(f"a viewer started: sent it {len(self.shown)} displays again")

    # ------------------------------------------------------------ displays
    def _grid(self, path: str, msg: OccupancyGrid, colormap: Any, opacity: float, lift_m: float) -> None:
        o = msg.info.origin
        origin = (o.position.x, o.position.y, o.position.z, o.orientation.x, o.orientation.y, o.orientation.z,
                  o.orientation.w)
        cells = convert.grid_cells_of(msg)
        if not self.grids.changed(path, cells, msg.info.resolution, origin, msg.header.frame_id):
            return
        self._log(path, msg.header, convert.grid(msg, colormap, opacity, lift_m, cells), keep=True)

    def _tf(self, msg: TFMessage, static: bool) -> None:
        """TF edges for the viewer, which places every display through them; a moving frame's at
        most ``tf_max_rate_hz`` (the robot model needs no more; scans are placed here)."""
        for t in msg.transforms:
            child = t.child_frame_id.lstrip("/")
            if static:
                self.static_heights[child] = (t.header.frame_id.lstrip("/"), float(t.transform.translation.z))
                self._log_static(f"tf/{child}", [convert.transform(t)])
                continue
            rate = self.tf_rates.get(child)
            if rate is None:
                rate = self.tf_rates[child] = RateLimit(self.params.tf_max_rate_hz)
            if rate.due(convert.stamp_seconds(t.header.stamp)):
                self._log(f"tf/{child}", t.header, [convert.transform(t)])

    def _robot(self, msg: String) -> None:
        visuals, warnings = convert.robot_visuals(msg.data, resolve_mesh=_resolve_mesh)
        for path in [path for path in self.statics if path == "robot" or path.startswith("robot/")]:
            del self.statics[path]
        self._log_static("robot", [rr.Clear(recursive=True)])
        for visual in visuals:
            self._log_static(visual.path, list(visual.archetypes))
        for warning in warnings:
            self.warn(warning, f"robot model: {warning}")

    def _stamp_or_now(self, header: Any) -> float:
        """A message's stamp in seconds; the node's time for an unstamped one (rate limits)."""
        return convert.stamp_seconds(header.stamp) or self.get_clock().now().nanoseconds * 1e-9

    def _scan(self, msg: LaserScan) -> None:
        self._check_time(msg.header)
        if self.scan_rate.due(self._stamp_or_now(msg.header)):
            if self.pending_scan is not None:  # never placed: shown where its own frame is
                self._log("scan", self.pending_scan[0].header, convert.scan(self.pending_scan[0]))
            self.pending_scan = (msg, time.monotonic())
            self._place_scan()

    def _place_scan(self) -> None:
        """Show the waiting scan in ``fixed_frame``, placed by the transforms at its stamp (as RViz
        transforms a scan into its fixed frame, interpolating): where the robot was when it
        scanned, whatever the viewer's transforms' rate. A scan whose stamp the transforms have
        not reached yet waits for them (up to :data:`SCAN_WAIT_S`); one that cannot be placed
        (frames not connected, too old) is shown in its own frame."""
        if self.pending_scan is None:
            return
        msg, since = self.pending_scan
        fixed, frame = self.params.fixed_frame, msg.header.frame_id.lstrip("/")
        stamp_s = convert.stamp_seconds(msg.header.stamp)
        try:
            newest = self.tf.latest_time(fixed, frame)
            if newest is not None and newest < stamp_s and time.monotonic() - since < SCAN_WAIT_S:
                return  # the transforms of its stamp are still on their way
            pose = self.tf.lookup(fixed, frame, stamp_s)
        except TransformError:
            self.pending_scan = None
            self._log("scan", msg.header, convert.scan(msg))
            return
        self.pending_scan = None
        self._log("scan", msg.header, convert.scan(msg, pose=pose, frame=fixed, height_m=self._height(frame)))

    def _height(self, frame: str) -> float:
        """A frame's height above the moving frame it is mounted on (its static transforms' z)."""
        height, seen = 0.0, set()
        while frame in self.static_heights and frame not in seen:
            seen.add(frame)
            frame, z = self.static_heights[frame]
            height += z
        return height

    def _particles(self, msg: ParticleCloud) -> None:
        if self.particle_rate.due(self._stamp_or_now(msg.header)):
            self._log("amcl/particles", msg.header, convert.particles(msg))

    def _odom(self, msg: Odometry) -> None:
        self._check_time(msg.header)
        position = msg.pose.pose.position
        frame = msg.header.frame_id.lstrip("/") or "odom"
        if frame != self.trail_frame:  # a new odometry frame: a new trail
            self.trail = Trail(self.params.trail_spacing, self.params.trail_max_points)
            self.trail_frame = frame
            self._log("odom/trail", msg.header, [rr.Clear(recursive=True)])
            self._forget("odom/trail")
        if self.trail.add(position.x, position.y, position.z):
            slot, segment = self.trail.newest()  # only the segment that grew is sent
            self._log(f"odom/trail/{slot}", msg.header, convert.trail(segment, frame), keep=True)

    def _markers(self, msg: MarkerArray) -> None:
        for key, archetypes in convert.markers(msg).items():
            path = f"slam/graph/{key}".rstrip("/")
            if archetypes is None:
                self.rec.log(path, rr.Clear(recursive=True))
                self._forget(path)
            else:
                self._log(path, msg.markers[0].header, archetypes, keep=True)

    def _diagnostics(self, msg: DiagnosticArray) -> None:
        """The SLAM node's health beside the views (:func:`convert.slam_health`), when it changes."""
        text = convert.slam_health(msg)
        if text is not None and text != self.slam_health:
            self.slam_health = text
            self._log("slam/health", msg.header, [rr.TextDocument(text, media_type=rr.MediaType.MARKDOWN)], keep=True)

    def _find_images(self) -> None:
        """Subscribe to camera topics as they appear; of an image and its image_transport
        ``/compressed`` twin, only the twin (what RViz's Image display does with the
        "compressed" transport): a fraction of the bytes over DDS."""
        found = {topic: next((IMAGE_TYPES[t] for t in types if t in IMAGE_TYPES), None)
                 for topic, types in self.get_topic_names_and_types()}
        for topic, kind in found.items():
            if kind is None or topic in self.image_topics:
                continue
            if kind is Image and found.get(f"{topic}/compressed") is CompressedImage:
                continue
            raw = topic.removesuffix("/compressed")
            if kind is CompressedImage and raw in self.image_topics:
                self.destroy_subscription(self.subscribed.pop(raw).subscription)
                self.image_topics.discard(raw)
            self.image_topics.add(topic)
            self.image_rates[topic] = RateLimit(self.params.image_max_rate_hz)
            self._subscribe(kind, topic, SENSOR, lambda m, t=topic: self._image(t, m))
            self.get_logger().info(f"showing camera images of {topic}")

    def _image(self, topic: str, msg: Any) -> None:
        if not self.image_rates[topic].due(self._stamp_or_now(msg.header)):
            return
        visual = convert.image(msg) if isinstance(msg, Image) else convert.compressed_image(msg)
        self._log(f"camera{topic}", msg.header, [visual])

    # ------------------------------------------------------------ poses from the page
    def _set_pose(self, request: PoseRequest) -> str:
        """Publish a pose set in the view (called from the page server's thread)."""
        stamp = self.get_clock().now().to_msg()
        half = 0.5 * request.yaw
        if request.kind == "goal":
            goal = PoseStamped()
            goal.header.frame_id, goal.header.stamp = self.params.fixed_frame, stamp
            goal.pose.position.x, goal.pose.position.y = request.x, request.y
            goal.pose.orientation.z, goal.pose.orientation.w = math.sin(half), math.cos(half)
            self.pose_pubs["goal"].publish(goal)
        else:
            initial = PoseWithCovarianceStamped()
            initial.header.frame_id, initial.header.stamp = self.params.fixed_frame, stamp
            initial.pose.pose.position.x, initial.pose.pose.position.y = request.x, request.y
            initial.pose.pose.orientation.z, initial.pose.pose.orientation.w = math.sin(half), math.cos(half)
            for index, value in INITIAL_POSE_COVARIANCE.items():
                initial.pose.covariance[index] = value
            self.pose_pubs["initial"].publish(initial)
        text = (f"{'goal' if request.kind == 'goal' else 'initial pose'} sent: x {request.x:.2f} m, "
                f"y {request.y:.2f} m, yaw {math.degrees(request.yaw):.0f}° on {POSE_KINDS[request.kind]}")
        self.get_logger().info(text)
        return text

    def destroy_node(self) -> None:
        if self.page is not None:
            self.page.close()
            self.page = None
        try:
            self.rec.flush(timeout_sec=2.0)
            self.rec.disconnect()
        except RuntimeError as exc:  # the server stopped first (the launch stops all at once)
            self.get_logger().debug(f"the rerun stream ended early: {exc}")
        super().destroy_node()


#: /tf_static: every static broadcaster's last message (tf2's listener keeps depth 100 too)
LATCHED_MANY = QoSProfile(depth=100, reliability=LATCHED.reliability, durability=LATCHED.durability)


def _resolve_mesh(filename: str) -> Path | None:
    """A URDF mesh's file: ``package://pkg/...`` in the package's share directory, or a path."""
    if filename.startswith("package://"):
        package, _, rest = filename.removeprefix("package://").partition("/")
        try:
            from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
            return Path(get_package_share_directory(package)) / rest
        except (ImportError, PackageNotFoundError, ValueError):
            return None
    return Path(filename.removeprefix("file://"))


def main(args: list[str] | None = None) -> int:
    return run_node(Viz, "viz", args)


if __name__ == "__main__":
    sys.exit(main())
