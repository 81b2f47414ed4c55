"""A costmap as a ROS node: Nav2's ``Costmap2DROS``, run inside the planner and controller servers.

The node is named after its costmap (``global_costmap`` or ``local_costmap``) in a namespace of
the same name, as Nav2's, so its parameters sit under ``global_costmap: global_costmap:
ros__parameters:`` in ``config/nav2_params.yaml`` and it publishes ``/global_costmap/costmap``
(nav_msgs/OccupancyGrid, Nav2's cost translation, transient local) and serves
``/global_costmap/clear_entirely_global_costmap`` (nav2_msgs/ClearEntireCostmap).

Layers (``plugins``, applied in order) are chosen by name: ``static_layer`` (the map on
``static_layer.map_topic``; the costmap takes the map's size and origin unless it rolls),
``obstacle_layer`` (also accepted as ``voxel_layer``, as ppp_bot's local costmap names it: marks
and clears from the LaserScan on ``obstacle_layer.scan.topic``) and ``inflation_layer``. A
rolling window (``rolling_window``) is ``width`` × ``height`` m centred on the robot
(``global_frame`` → ``robot_base_frame`` from TF). The master is rebuilt at
``update_frequency`` and published at ``publish_frequency``.

As Nav2's observation buffer, scans are kept (with the sensor's pose at their stamp) and
applied when the layers update, not as they come: with ``observation_persistence`` 0 (Nav2's
default) the newest scan only, else every scan of the last that many seconds. A global
costmap updating at 1 Hz marks one scan a second, not the lidar's ten.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np
from nav2_msgs.msg import Costmap as Nav2Costmap
from nav2_msgs.srv import ClearCostmapAroundRobot, ClearCostmapExceptRegion, ClearEntireCostmap, GetCostmap
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from rclpy.node import Node
from sensor_msgs.msg import LaserScan

from pppbot_common.params import ParameterError, check_finite_range, param
from pppbot_common.ros.lockstep import at_step, create_timer, require, require_match
from pppbot_common.ros.maps import grid_from_message, grid_message
from pppbot_common.ros.node_main import Warnings, guarded
from pppbot_common.ros.params import declare_parameters
from pppbot_common.ros.planar import stamp_seconds
from pppbot_common.ros.qos import LATCHED, SENSOR
from pppbot_common.ros.tf_listener import TfListener
from pppbot_common.transforms import TransformError
from pppbot_nav.costmap.costs import NO_INFORMATION
from pppbot_nav.costmap.grid import Costmap
from pppbot_nav.costmap.layers import InflationLayer, Layer, LayeredCostmap, ObstacleLayer, StaticLayer
from pppbot_nav.errors import CostmapError

#: Scans that may wait for their transform: two seconds of a 10 Hz lidar (AMCL stamps map → odom
#: ahead by its transform_tolerance, but a busy machine can still hold it back).
SCAN_QUEUE = 20
LAYER_NAMES = ("static_layer", "obstacle_layer", "voxel_layer", "inflation_layer")


@dataclass(frozen=True, eq=False)
class _Observation:
    """A scan and the sensor's (x, y, yaw) in the costmap's frame at its stamp."""
    stamp_s: float
    scan: LaserScan
    sensor: tuple[float, float, float]


@dataclass(frozen=True)
class CostmapParameters:
    global_frame: str = param("map", "the costmap's frame")
    robot_base_frame: str = param("base_link", "the robot's frame")
    update_frequency: float = param(5.0, "layer updates per second (Hz)")
    publish_frequency: float = param(1.0, "costmap publications per second (Hz)")
    rolling_window: bool = param(False, "follow the robot (a window of width × height m)")
    width: int = param(5, "rolling window width (m)")
    height: int = param(5, "rolling window height (m)")
    resolution: float = param(0.05, "cell size (m); a static map's own resolution wins")
    robot_radius: float = param(0.3, "the robot's radius (m): the inscribed zone")
    track_unknown_space: bool = param(True, "unknown cells stay unknown (else free)")
    lethal_cost_threshold: int = param(100, "map values at or above this are lethal")
    plugins: list = param(["static_layer", "obstacle_layer", "inflation_layer"],
                          "layers in order, of: " + ", ".join(LAYER_NAMES))
    map_topic: str = param("/map", "static layer: the map topic (transient local)",
                           ros_name="static_layer.map_topic")
    scan_topic: str = param("/scan", "obstacle layer: the LaserScan topic", ros_name="obstacle_layer.scan.topic")
    obstacle_max_range: float = param(2.5, "obstacle layer: mark returns up to this range (m)",
                                      ros_name="obstacle_layer.scan.obstacle_max_range")
    obstacle_min_range: float = param(0.0, "obstacle layer: mark returns from this range (m)",
                                      ros_name="obstacle_layer.scan.obstacle_min_range")
    raytrace_max_range: float = param(3.0, "obstacle layer: clear along beams up to this range (m)",
                                      ros_name="obstacle_layer.scan.raytrace_max_range")
    raytrace_min_range: float = param(0.0, "obstacle layer: clear from this range (m)",
                                      ros_name="obstacle_layer.scan.raytrace_min_range")
    observation_persistence: float = param(0.0, "obstacle layer: how long a scan is applied (s); 0: the newest only",
                                           ros_name="obstacle_layer.scan.observation_persistence")
    inflation_radius: float = param(0.55, "inflation layer: radius (m)", ros_name="inflation_layer.inflation_radius")
    cost_scaling_factor: float = param(3.0, "inflation layer: exponential decay (1/m)",
                                       ros_name="inflation_layer.cost_scaling_factor")
    inflate_unknown: bool = param(False, "inflation layer: inflate into unknown cells",
                                  ros_name="inflation_layer.inflate_unknown")

    def validate(self) -> None:
        for name in ("update_frequency", "publish_frequency", "resolution"):
            check_finite_range(name, getattr(self, name), 0.0, 1000.0, low_open=True)
        check_finite_range("robot_radius", self.robot_radius, 0.0, 100.0)
        check_finite_range("obstacle_layer.scan.observation_persistence", self.observation_persistence, 0.0, 3600.0)
        if self.rolling_window and not (self.width > 0 and self.height > 0):
            raise ParameterError("width", f"{self.width} × {self.height}", "a rolling window needs a positive size")
        if not 1 <= self.lethal_cost_threshold <= 100:
            raise ParameterError("lethal_cost_threshold", self.lethal_cost_threshold, "must be in [1, 100]")
        unknown = [p for p in self.plugins if p not in LAYER_NAMES]
        if unknown or not self.plugins:
            raise ParameterError("plugins", self.plugins, f"must be a list of: {', '.join(LAYER_NAMES)}")
        if self.rolling_window is False and "static_layer" not in self.plugins:
            raise ParameterError("plugins", self.plugins, "a costmap that does not roll needs static_layer "
                                                          "(it takes the map's size)")
        for name in ("global_frame", "robot_base_frame"):
            if not getattr(self, name):
                raise ParameterError(name, getattr(self, name), "must not be empty")
        try:
            self.layers()
        except CostmapError as exc:
            raise ParameterError("plugins", self.plugins, str(exc)) from exc

    def layers(self) -> list[Layer]:
        made: list[Layer] = []
        for name in self.plugins:
            if name == "static_layer":
                made.append(StaticLayer(self.track_unknown_space, self.lethal_cost_threshold))
            elif name in ("obstacle_layer", "voxel_layer"):
                made.append(ObstacleLayer(self.obstacle_max_range, self.obstacle_min_range, self.raytrace_max_range,
                                          self.raytrace_min_range, self.track_unknown_space))
            else:
                made.append(InflationLayer(self.inflation_radius, self.cost_scaling_factor, self.robot_radius,
                                           self.inflate_unknown))
        return made


def costmap_message(costmap: Costmap, stamp: Any) -> Nav2Costmap:
    """A costmap as nav2_msgs/Costmap: its costs as they are (not translated to occupancy)."""
    msg = Nav2Costmap()
    msg.header.frame_id = costmap.frame_id
    msg.header.stamp = stamp
    meta = msg.metadata
    meta.map_load_time = meta.update_time = stamp
    meta.layer = "master"
    meta.resolution = float(costmap.resolution)
    meta.size_x, meta.size_y = costmap.width, costmap.height
    meta.origin.position.x, meta.origin.position.y = float(costmap.origin[0]), float(costmap.origin[1])
    meta.origin.orientation.w = 1.0
    msg.data = costmap.costs.ravel().tobytes()
    return msg


class CostmapNode(Node):
    def __init__(self, name: str, **kwargs: Any) -> None:
        super().__init__(name, namespace=name, **kwargs)
        self.costmap_name = name
        self.params = p = declare_parameters(self, CostmapParameters)
        self._warn = Warnings(self, settling=("robot pose", "scan transform"))
        self._pending: deque[LaserScan] = deque()  # scans waiting for their transform
        self._observations: deque[_Observation] = deque()  # scans with their sensor pose, oldest first
        self._applied: tuple[tuple[_Observation, ...], tuple[float, float]] | None = None  # and where
        self.tf = TfListener(self, self._warn, on_tf=self._drain).buffer
        self.layers = p.layers()
        self.static = next((la for la in self.layers if isinstance(la, StaticLayer)), None)
        self.obstacles = [la for la in self.layers if isinstance(la, ObstacleLayer)]
        self.layered: LayeredCostmap | None = None
        if p.rolling_window:
            size = (p.width, p.height)
            self.layered = LayeredCostmap(Costmap.filled(size[0], size[1], p.resolution, (0.0, 0.0), NO_INFORMATION,
                                                         p.global_frame), self.layers, rolling=True,
                                          default_value=NO_INFORMATION if p.track_unknown_space else 0)
        self.costmap: Costmap | None = None  # the last update, a copy owned by its readers
        #: The message of the costmap last published: an unchanged costmap is sent again restamped.
        self._message: tuple[Costmap, OccupancyGridMsg] | None = None
        self.pub = self.create_publisher(OccupancyGridMsg, "costmap", LATCHED)
        self._map_arrived = require(self, f"a map on '{p.map_topic}'") if self.static is not None else None
        if self.static is not None:
            self.create_subscription(OccupancyGridMsg, p.map_topic, guarded(self, self._on_map, "OccupancyGrid"),
                                     LATCHED)
        if self.obstacles:
            on_scan = guarded(self, at_step(self, self._on_scan), "LaserScan")
            require_match(self, self.create_subscription(LaserScan, p.scan_topic, on_scan, SENSOR))
        self.create_service(ClearEntireCostmap, f"clear_entirely_{name}", self._clear)
        self.create_service(GetCostmap, "get_costmap", self._get_costmap)
        self.create_service(ClearCostmapAroundRobot, f"clear_around_{name}", self._clear_around)
        self.create_service(ClearCostmapExceptRegion, f"clear_except_{name}", self._clear_except)
        create_timer(self, 1.0 / p.update_frequency, self.update)
        create_timer(self, 1.0 / p.publish_frequency, self.publish)
        self.get_logger().info(f"{name}: {', '.join(p.plugins)} in '{p.global_frame}'"
                               + (f", rolling {p.width} × {p.height} m" if p.rolling_window else ""))

    # ------------------------------------------------------------------ inputs
    def _on_map(self, msg: OccupancyGridMsg) -> None:
        assert self.static is not None
        grid = grid_from_message(msg)
        self.static.set_map(grid)
        if not self.params.rolling_window:
            old = self.layered.master if self.layered is not None else None
            if old is None or old.costs.shape != grid.data.shape or old.origin != grid.origin[:2]:
                master = Costmap.filled(grid.width * grid.resolution, grid.height * grid.resolution, grid.resolution,
                                        (grid.origin[0], grid.origin[1]), NO_INFORMATION, self.params.global_frame)
                self.layered = LayeredCostmap(master, self.layers)
        self.update()
        if self._map_arrived is not None:
            self._map_arrived()
            self._map_arrived = None

    def robot_pose(self) -> tuple[float, float, float] | None:
        """The robot's newest (x, y, yaw) in the costmap's frame, or None without TF."""
        try:
            pose = self.tf.lookup(self.params.global_frame, self.params.robot_base_frame)
        except TransformError as exc:
            self._warn("robot pose", f"no robot pose: {exc}")
            return None
        self._warn.settled("robot pose")
        return pose

    def _on_scan(self, msg: LaserScan) -> None:
        """As tf2's message filter: a scan is marked with the sensor's pose at its stamp, waiting
        for that transform if it is not there yet (up to :data:`SCAN_QUEUE` scans); never with an
        older pose, which smears walls across free space while the robot turns."""
        if self.layered is None:
            return
        self._pending.append(msg)
        if len(self._pending) > SCAN_QUEUE:
            old = self._pending.popleft()
            self._warn("scan transform", f"dropping a scan of '{old.header.frame_id}' at "
                                         f"{stamp_seconds(old.header.stamp):.3f} s: its transform to "
                                         f"'{self.params.global_frame}' did not arrive in time")
        self._drain()

    def _drain(self) -> None:
        """Mark the waiting scans whose transform has arrived, oldest first."""
        while self._pending and self.layered is not None:
            msg = self._pending[0]
            frame = msg.header.frame_id.lstrip("/")
            stamp = stamp_seconds(msg.header.stamp)
            try:
                sensor = self.tf.lookup(self.params.global_frame, frame, stamp)
            except TransformError as exc:
                try:
                    newest = self.tf.latest_time(self.params.global_frame, frame)
                except TransformError:
                    newest = None
                if newest is None or stamp > newest:
                    return  # the transform may still come
                self._pending.popleft()
                self._warn("scan transform", f"dropping a scan: {exc}")
                continue
            self._pending.popleft()
            self._warn.settled("scan transform")
            self._buffer(_Observation(stamp, msg, sensor))

    def _buffer(self, observation: _Observation) -> None:
        """Keep ``observation``, and of the older ones those within ``observation_persistence`` of it
        (Nav2's ObservationBuffer: with 0, the newest only)."""
        self._observations.append(observation)
        keep_s = self.params.observation_persistence
        while len(self._observations) > 1 and (
                keep_s == 0.0 or self._observations[0].stamp_s < observation.stamp_s - keep_s):
            self._observations.popleft()

    def _mark(self, layered: LayeredCostmap) -> None:
        """Apply the kept scans, oldest first; not again when neither they nor the grid moved
        (clearing then marking the same scans gives the same cells)."""
        observations = tuple(self._observations)
        applied = (observations, layered.master.origin)  # scans compare by identity
        if not observations or applied == self._applied:
            return
        for obs in observations:
            msg, sensor = obs.scan, obs.sensor
            ranges = np.asarray(msg.ranges, dtype=float)
            bearings = sensor[2] + msg.angle_min + msg.angle_increment * np.arange(len(ranges))
            valid = ~(ranges < msg.range_min)  # NaN stays: no return
            ranges = np.where(np.isfinite(ranges) & (ranges < msg.range_max), ranges, np.inf)
            for layer in self.obstacles:
                layer.observe(layered.master, (sensor[0], sensor[1]), bearings[valid], ranges[valid])
        self._applied = applied

    # ---------------------------------------------------------------- outputs
    def update(self) -> Costmap | None:
        """Rebuild the master from the layers; returns (and keeps) a copy, or None before there is one."""
        if self.layered is None:
            return None
        robot = None
        if self.params.rolling_window:
            pose = self.robot_pose()
            if pose is None:
                return None
            robot = (pose[0], pose[1])
            # Before marking, so the scans land in the window the layers are rebuilt in (the
            # layered update's own recentre then finds nothing to move).
            self.layered.master.recentre(robot[0], robot[1], self.layered.default_value)
        self._mark(self.layered)
        master = self.layered.update(robot)
        last = self.costmap
        if (last is None or last.origin != master.origin or last.resolution != master.resolution
                or not np.array_equal(last.costs, master.costs)):
            self.costmap = Costmap(master.costs.copy(), master.resolution, master.origin, master.frame_id)
        return self.costmap

    def publish(self) -> None:
        if self.costmap is None:
            return
        stamp = self.get_clock().now().to_msg()
        if self._message is None or self._message[0] is not self.costmap:
            self._message = (self.costmap, grid_message(self.costmap.to_occupancy_grid(), stamp))
        msg = self._message[1]
        msg.header.stamp = msg.info.map_load_time = stamp
        self.pub.publish(msg)

    def clear(self) -> None:
        for layer in self.obstacles:
            layer.clear()
        self._observations.clear()
        self._applied = None
        self.update()

    def _get_costmap(self, request: GetCostmap.Request, response: GetCostmap.Response) -> GetCostmap.Response:
        """Nav2's ``get_costmap``: the whole master grid as nav2_msgs/Costmap (Nav2's costs, 0–255,
        row-major from cell (0, 0)); an empty one before the first update. ``specs`` is not
        used, as in Nav2."""
        costmap = self.costmap
        if costmap is None:
            self.get_logger().warning(f"get_costmap: {self.costmap_name} has no costmap yet")
            return response
        now = self.get_clock().now().to_msg()
        response.map = costmap_message(costmap, now)
        return response

    def clear_square(self, side_m: float, inside: bool) -> bool:
        """Clear the obstacle layers in the square of side ``side_m`` around the robot
        (``inside=False``: outside it); False without a robot pose or with a bad side."""
        if not (math.isfinite(side_m) and side_m >= 0):
            self.get_logger().warning(f"{self.costmap_name}: reset_distance must be a number >= 0, not {side_m}")
            return False
        pose = self.robot_pose()
        if pose is None:
            return False
        for layer in self.obstacles:
            layer.clear_square((pose[0], pose[1]), side_m, inside)
        self.update()
        return True

    def _clear_around(self, request: ClearCostmapAroundRobot.Request,
                      response: ClearCostmapAroundRobot.Response) -> ClearCostmapAroundRobot.Response:
        if self.clear_square(float(request.reset_distance), inside=True):
            self.get_logger().info(f"{self.costmap_name}: cleared within {request.reset_distance:g} m of the robot")
        return response

    def _clear_except(self, request: ClearCostmapExceptRegion.Request,
                      response: ClearCostmapExceptRegion.Response) -> ClearCostmapExceptRegion.Response:
        if self.clear_square(float(request.reset_distance), inside=False):
            self.get_logger().info(f"{self.costmap_name}: cleared beyond {request.reset_distance:g} m of the robot")
        return response

    def _clear(self, request: ClearEntireCostmap.Request,
               response: ClearEntireCostmap.Response) -> ClearEntireCostmap.Response:
        self.clear()
        self.get_logger().info(f"{self.costmap_name}: cleared")
        return response
