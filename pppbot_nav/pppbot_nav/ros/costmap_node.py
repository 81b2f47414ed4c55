"""A costmap as a ROS node: Nav2's ``Costmap2DROS``, run inside the planner and controller servers.

The node is named after its costmap (``global_costmap`` or ``local_costmap``) in a namespace of
the same name, as Nav2's, so its parameters sit under ``global_costmap: global_costmap:
ros__parameters:`` in ``config/nav2_params.yaml`` and it publishes ``/global_costmap/costmap``
(nav_msgs/OccupancyGrid, Nav2's cost translation, transient local) and, while someone listens,
``/global_costmap/published_footprint`` (geometry_msgs/PolygonStamped, the padded footprint at
the robot's pose), and serves
``/global_costmap/clear_entirely_global_costmap`` (nav2_msgs/ClearEntireCostmap).

Layers (``plugins``, applied in order) are Nav2's plugin types, each chosen by its
``<name>.plugin`` (:mod:`pppbot_nav.costmap.layer_settings`: ``nav2_costmap_2d::StaticLayer``,
``ObstacleLayer``, ``VoxelLayer`` projected to 2D, ``InflationLayer``; ``static_layer``,
``obstacle_layer``, ``voxel_layer`` and ``inflation_layer`` without one get those types). A
static layer takes the map on its ``map_topic`` (or the costmap's); the costmap takes the map's
size and origin unless it rolls. An obstacle or voxel layer marks and clears from each of its
``observation_sources`` (LaserScan topics, each with its ranges and marking/clearing). A rolling
window (``rolling_window``) is ``width`` × ``height`` m centred on the robot (``global_frame`` →
``robot_base_frame`` from TF). The master is rebuilt at ``update_frequency`` and published at
``publish_frequency``.

Live parameters (``ros2 param set``), as Nav2's: ``robot_radius``, ``publish_frequency`` and
``update_frequency``, each layer's ``enabled``, the obstacle layers' ``footprint_clearing_enabled``
and ``combination_method``, and the inflation layer's radius, scaling and unknown handling apply
at once, keeping what the layers have seen; everything else is refused with the reason.

As Nav2's observation buffer, scans are kept (with the sensor's pose at their stamp) and
applied when the layers update, not as they come: with ``observation_persistence`` 0 (Nav2's
default) the newest scan only, else every scan of the last that many seconds. A global
costmap updating at 1 Hz marks one scan a second, not the lidar's ten.
"""
from __future__ import annotations

import dataclasses
import math
from collections import deque
from dataclasses import dataclass, field
from functools import partial
from typing import Any

import numpy as np
from geometry_msgs.msg import Point32, PolygonStamped
from nav2_msgs.msg import Costmap as Nav2Costmap
from nav2_msgs.msg import CostmapFilterInfo
from nav2_msgs.msg import SpeedLimit as SpeedLimitMsg
from nav2_msgs.srv import ClearCostmapAroundRobot, ClearCostmapExceptRegion, ClearEntireCostmap, GetCostmap
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from sensor_msgs.msg import LaserScan

from pppbot_common.params import ParameterError, check_finite_range, param
from pppbot_common.ros.maps import grid_from_message, grid_message
from pppbot_common.ros.params import LiveParameters, declare_parameters, serve_live_parameters
from pppbot_common.ros.planar import stamp_seconds
from pppbot_common.ros.qos import DEFAULT, LATCHED, MAP_VOLATILE, SENSOR
from pppbot_common.transforms import TransformError
from pppbot_lockstep.ros.node import StepNode
from pppbot_lockstep.ros.runner import Warnings, guarded
from pppbot_lockstep.ros.tf_listener import TfListener
from pppbot_nav.costmap.costs import NO_INFORMATION
from pppbot_nav.costmap.filters import CostmapFilter, FilterInfo, FilterMask, KeepoutFilter, SpeedFilter
from pppbot_nav.costmap.footprint import circle_footprint, placed
from pppbot_nav.costmap.grid import Costmap
from pppbot_nav.costmap.interface import LayerContext
from pppbot_nav.costmap.layer_settings import DEFAULT_TYPES, NO_EFFECT, SourceParameters, StaticLayerParameters
from pppbot_nav.costmap.layers import InflationLayer, Layer, LayeredCostmap, ObstacleLayer, StaticLayer
from pppbot_nav.plugins import AnyOf, plugins
from pppbot_nav.ros.plugins import Plugin, live_fields, live_plugin_parameters, load_plugin

#: Scans that may wait for their transform: two seconds of a 10 Hz lidar (AMCL stamps map → odom
#: ahead by its transform_tolerance, but a busy machine can still hold it back).
SCAN_QUEUE = 20


@dataclass(frozen=True, eq=False)
class _Observation:
    """A scan and the sensor's (x, y, yaw) in the costmap's frame at its stamp."""
    stamp_s: float
    scan: LaserScan
    sensor: tuple[float, float, float]


@dataclass(eq=False)
class _Source:
    """One observation source of an obstacle layer, with the scans waiting for their transform
    and those kept (Nav2's ObservationBuffer)."""
    name: str  # <layer>.<source>
    layer: ObstacleLayer
    params: SourceParameters
    topic: str
    pending: deque[LaserScan] = field(default_factory=deque)
    observations: deque[_Observation] = field(default_factory=deque)


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
    robot_radius: float = param(0.3, "the robot's radius (m): the inscribed zone (ppp_bot's; Nav2's default 0.1)")
    track_unknown_space: bool = param(False, "unknown cells stay unknown (else free)")
    lethal_cost_threshold: int = param(100, "map values at or above this are lethal")
    map_topic: str = param("/map", "the static layers' map topic when they name none")
    footprint_padding: float = param(0.01, "added to robot_radius for the controller's footprint check (DWB's "
                                           "ObstacleFootprint), as Nav2 pads its footprint")
    plugins: list = param(["static_layer", "obstacle_layer", "inflation_layer"],
                          "layers in order; each's type is its <name>.plugin")
    filters: list = param([], "costmap filters applied after the layers, in order (Nav2's KeepoutFilter, "
                              "SpeedFilter); each's type is its <name>.plugin")

    def validate(self) -> None:
        for name in ("update_frequency", "publish_frequency", "resolution"):
            check_finite_range(name, getattr(self, name), 0.0, 1000.0, low_open=True)
        check_finite_range("robot_radius", self.robot_radius, 0.0, 100.0)
        if self.rolling_window and not (self.width > 0 and self.height > 0):
            raise ParameterError("width", f"{self.width} × {self.height}", "a rolling window needs a positive size")
        if not 1 <= self.lethal_cost_threshold <= 100:
            raise ParameterError("lethal_cost_threshold", self.lethal_cost_threshold, "must be in [1, 100]")
        if not self.plugins or len(set(self.plugins)) != len(self.plugins):
            raise ParameterError("plugins", self.plugins, "must name at least one layer, each once")
        if len(set(self.filters)) != len(self.filters) or set(self.filters) & set(self.plugins):
            raise ParameterError("filters", self.filters, "must name each filter once, none of them a layer")
        for name in ("global_frame", "robot_base_frame"):
            if not getattr(self, name):
                raise ParameterError(name, getattr(self, name), "must not be empty")


#: What a costmap may change while it runs; the rest is refused (Nav2 reads it once).
LIVE_COSTMAP = {"robot_radius", "footprint_padding", "publish_frequency", "update_frequency"}


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


class CostmapNode(StepNode):
    def __init__(self, name: str, **kwargs: Any) -> None:
        super().__init__(name, namespace=name, **kwargs)
        self.costmap_name = name
        self.params = p = declare_parameters(self, CostmapParameters)
        overrides = getattr(self, "_parameter_overrides", {}) or {}
        elsewhere = {name.split(".")[0] for name in overrides if "." in name} - set(p.plugins) - set(p.filters)
        self.parameter_notes = {**NO_EFFECT, **{f"{layer}.*": f"'{layer}' is not one of this costmap's plugins"
                                                for layer in sorted(elsewhere)}}
        self._warn = Warnings(self, settling=("robot pose", "scan transform"))
        self._applied: tuple[tuple[_Observation, ...], tuple[float, float]] | None = None  # and where
        self.tf = TfListener(self, self._warn, on_tf=self._drain, quiet=True).buffer  # the update timer reads it
        layers = plugins("costmap layer")
        self.plugins: dict[str, Plugin] = {layer: load_plugin(self, layer, layers, DEFAULT_TYPES.get(layer))
                                           for layer in p.plugins}
        self.sources: list[_Source] = []
        self.layer_by_name: dict[str, Layer] = {name: self._make_layer(pl) for name, pl in self.plugins.items()}
        self.layers: list[Layer] = list(self.layer_by_name.values())
        filter_types = AnyOf(plugins("costmap filter"), plugins("costmap layer"))
        for filter_name in p.filters:
            self.plugins[filter_name] = load_plugin(self, filter_name, filter_types, None)
        #: The filters in order: Nav2's costmap filters, and layers applied after them (an inflation
        #: layer round a keepout zone, as Nav2 suggests).
        self.filter_chain: dict[str, CostmapFilter | Layer] = {
            f: self.plugins[f].params.make(self._layer_context(f)) for f in p.filters}
        self.filters = {f: chained for f, chained in self.filter_chain.items() if isinstance(chained, CostmapFilter)}
        if p.rolling_window is False and not any(isinstance(la, StaticLayer) for la in self.layers):
            raise ParameterError("plugins", p.plugins, "a costmap that does not roll needs a static layer "
                                                       "(it takes the map's size)")
        self.static = next((la for la in self.layers if isinstance(la, StaticLayer)), None)
        self.obstacles = [la for la in self.layers if isinstance(la, ObstacleLayer)]
        self.layered: LayeredCostmap | None = None
        if p.rolling_window:
            size = (p.width, p.height)
            self.layered = LayeredCostmap(Costmap.filled(size[0], size[1], p.resolution, (0.0, 0.0), NO_INFORMATION,
                                                         p.global_frame), self.layers, rolling=True,
                                          default_value=NO_INFORMATION if p.track_unknown_space else 0)
        self.costmap: Costmap | None = None  # the last update, a copy owned by its readers
        #: Called when robot_radius or footprint_padding change (the controller's DWB takes them).
        self.footprint_listeners: list[Any] = []
        #: The message of the costmap last published: an unchanged costmap is sent again restamped.
        self._message: tuple[Costmap, OccupancyGridMsg] | None = None
        self.pub = self.create_publisher(OccupancyGridMsg, "costmap", LATCHED)
        self.footprint_pub = self.create_publisher(PolygonStamped, "published_footprint", DEFAULT)
        self._map_arrived: Any = None
        for plugin in self.plugins.values():
            if isinstance(plugin.params, StaticLayerParameters):
                topic = plugin.params.map_topic or p.map_topic
                self._map_arrived = self.port.require(f"a map on '{topic}'")
                qos = LATCHED if plugin.params.map_subscribe_transient_local else MAP_VOLATILE
                self.create_subscription(OccupancyGridMsg, topic, guarded(self, self._on_map, "OccupancyGrid"), qos)
        self._speed_pubs: dict[str, Any] = {}
        self._mask_subscriptions: dict[str, Any] = {}
        for filter_name, costmap_filter in self.filters.items():
            self.create_subscription(CostmapFilterInfo, self._in_parent(costmap_filter.filter_info_topic),
                                     guarded(self, partial(self._on_filter_info, filter_name), "CostmapFilterInfo"),
                                     LATCHED)
            if isinstance(costmap_filter, SpeedFilter):
                topic = self._in_parent(costmap_filter.speed_limit_topic)
                self._speed_pubs[filter_name] = self.create_publisher(SpeedLimitMsg, topic, 10)
        for source in self.sources:
            on_scan = guarded(self, partial(self._on_scan, source), "LaserScan")
            self.create_subscription(LaserScan, source.topic, on_scan, SENSOR, data_path=True, at_step=True)
        self.create_service(ClearEntireCostmap, f"clear_entirely_{name}", self._clear)
        self.create_service(GetCostmap, "get_costmap", self._get_costmap)
        self.create_service(ClearCostmapAroundRobot, f"clear_around_{name}", self._clear_around)
        self.create_service(ClearCostmapExceptRegion, f"clear_except_{name}", self._clear_except)
        self._update_timer = self.step_timer(1.0 / p.update_frequency, self.update)
        self._publish_timer = self.step_timer(1.0 / p.publish_frequency, self.publish)
        sources = {source.name: Plugin(source.name, "source", source.params) for source in self.sources}
        serve_live_parameters(self, [LiveParameters("", lambda: self.params, self._set_params, LIVE_COSTMAP),
                                     *live_plugin_parameters(self.plugins, self._set_layer_params),
                                     *live_plugin_parameters(sources, self._set_layer_params)])
        kinds = ", ".join(f"{pl.name} ({pl.type_name.split('::')[-1]})" for pl in self.plugins.values())
        self.get_logger().info(f"{name}: {kinds} in '{p.global_frame}'"
                               + (f", rolling {p.width} × {p.height} m" if p.rolling_window else ""))

    def _layer_context(self, name: str) -> LayerContext:
        p = self.params
        return LayerContext(name, p.global_frame, p.track_unknown_space, p.lethal_cost_threshold, p.robot_radius)

    def _make_layer(self, plugin: Plugin) -> Layer:
        """The layer of a loaded plugin; an obstacle or voxel layer's sources are declared too."""
        layer: Layer = plugin.params.make(self._layer_context(plugin.name))
        if not isinstance(layer, ObstacleLayer):
            return layer
        for source_name in plugin.params.sources():
            prefix = f"{plugin.name}.{source_name}"
            settings = declare_parameters(self, SourceParameters, prefix=f"{prefix}.")
            self.sources.append(_Source(prefix, layer, settings, settings.topic or source_name))
        return layer

    # ----------------------------------------------------------- parameters
    def _set_params(self, new: CostmapParameters) -> None:
        old, self.params = self.params, new
        if new.robot_radius != old.robot_radius:
            for layer in self.layers:
                if isinstance(layer, InflationLayer):
                    layer.inscribed_radius = new.robot_radius
                    layer.forget()
        for timer, rate, callback in ((self._update_timer, "update_frequency", self.update),
                                      (self._publish_timer, "publish_frequency", self.publish)):
            if getattr(new, rate) != getattr(old, rate):
                self.destroy_step_timer(timer)
                made = self.step_timer(1.0 / getattr(new, rate), callback)
                if rate == "update_frequency":
                    self._update_timer = made
                else:
                    self._publish_timer = made
        for listener in self.footprint_listeners:
            listener()
        self.update()

    def _set_layer_params(self, name: str, new: Any) -> None:
        """A layer's live parameters, set on the running layer (what it has seen stays)."""
        plugin = self.plugins[name]
        self.plugins[name] = Plugin(plugin.name, plugin.type_name, new)
        layer: Any = self.layer_by_name[name] if name in self.layer_by_name else self.filter_chain[name]
        live = live_fields(new)
        for key in [f.name for f in dataclasses.fields(new)] if live is None else live:
            setattr(layer, key, getattr(new, key))
        if isinstance(layer, InflationLayer):
            layer.forget()
        self.update()

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

    # --------------------------------------------------------------- filters
    def _on_filter_info(self, name: str, msg: CostmapFilterInfo) -> None:
        """A filter's info: its mask topic subscribed (again, when it changed)."""
        costmap_filter = self.filters[name]
        old = costmap_filter.info
        try:
            costmap_filter.set_info(FilterInfo(int(msg.type), msg.filter_mask_topic, float(msg.base),
                                               float(msg.multiplier)))
        except ValueError as exc:
            self._warn(f"filter {name}", str(exc))
            return
        if old is not None and old.mask_topic == msg.filter_mask_topic:
            return
        if name in self._mask_subscriptions:
            self.destroy_subscription(self._mask_subscriptions.pop(name))
        on_mask = guarded(self, partial(self._on_mask, name), "OccupancyGrid")
        self._mask_subscriptions[name] = self.create_subscription(
            OccupancyGridMsg, self._in_parent(msg.filter_mask_topic), on_mask, LATCHED)
        self.get_logger().info(f"{name}: {type(costmap_filter).__name__} on mask '{msg.filter_mask_topic}'")

    def _in_parent(self, topic: str) -> str:
        """A filter's relative topic in the costmap's parent namespace (the robot's), as Nav2's
        ``joinWithParentNamespace``: ``/global_costmap`` costmap's ``speed_limit`` is ``/speed_limit``."""
        if topic.startswith("/"):
            return topic
        parent = self.get_namespace().rstrip("/").rsplit("/", 1)[0]
        return f"{parent}/{topic}"

    def _on_mask(self, name: str, msg: OccupancyGridMsg) -> None:
        grid = grid_from_message(msg)
        self.filters[name].mask = FilterMask(grid.data, grid.resolution, grid.origin, msg.header.frame_id or "map")
        self.update()

    def _filter(self, master: Costmap, robot_xy: tuple[float, float] | None) -> None:
        """Apply the filters to the freshly built master (keepout) and give the speed limit at the robot."""
        for name, costmap_filter in self.filter_chain.items():
            if not isinstance(costmap_filter, CostmapFilter):
                if costmap_filter.enabled:
                    costmap_filter.update(master)
                continue
            if not costmap_filter.ready:
                continue
            assert costmap_filter.mask is not None
            try:
                to_mask = self.tf.lookup(costmap_filter.mask.frame_id, self.params.global_frame)
            except TransformError as exc:
                self._warn(f"filter {name}", f"{name}: no transform from '{self.params.global_frame}' to the "
                                             f"mask's '{costmap_filter.mask.frame_id}': {exc}")
                continue
            if isinstance(costmap_filter, KeepoutFilter):
                costmap_filter.apply(master, to_mask, robot_xy)
            elif isinstance(costmap_filter, SpeedFilter):
                pose = self.robot_pose() if robot_xy is None else robot_xy
                if pose is None:
                    continue
                limit = costmap_filter.update(to_mask, (pose[0], pose[1]))
                if costmap_filter.problem is not None:
                    self._warn(f"filter {name}", f"{name}: {costmap_filter.problem}")
                if limit is not None:
                    msg = SpeedLimitMsg(percentage=limit.percentage, speed_limit=limit.speed_limit)
                    msg.header.frame_id = self.params.global_frame
                    msg.header.stamp = self.get_clock().now().to_msg()
                    self._speed_pubs[name].publish(msg)

    def robot_pose(self) -> tuple[float, float, float] | None:
        """The robot's newest (x, y, yaw) in the costmap's frame, or None without TF."""
        try:
            pose = self.tf.lookup(self.params.global_frame, self.params.robot_base_frame)
        except TransformError as exc:
            self._warn("robot pose", f"no robot pose: {exc}")
            return None
        self._warn.settled("robot pose")
        return pose

    def _on_scan(self, source: _Source, msg: LaserScan) -> None:
        """As tf2's message filter: a scan is marked with the sensor's pose at its stamp, waiting
        for that transform if it is not there yet (up to :data:`SCAN_QUEUE` scans); never with an
        older pose, which smears walls across free space while the robot turns."""
        if self.layered is None:
            return
        source.pending.append(msg)
        if len(source.pending) > SCAN_QUEUE:
            old = source.pending.popleft()
            self._warn("scan transform", f"dropping a scan of '{old.header.frame_id}' at "
                                         f"{stamp_seconds(old.header.stamp):.3f} s: its transform to "
                                         f"'{self.params.global_frame}' did not arrive in time")
        self._drain()

    def _drain(self) -> None:
        """Mark the waiting scans whose transform has arrived, oldest first."""
        for source in self.sources:
            self._drain_source(source)

    def _drain_source(self, source: _Source) -> None:
        while source.pending and self.layered is not None:
            msg = source.pending[0]
            frame = source.params.sensor_frame or msg.header.frame_id.lstrip("/")
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
                source.pending.popleft()
                self._warn("scan transform", f"dropping a scan: {exc}")
                continue
            source.pending.popleft()
            self._warn.settled("scan transform")
            self._buffer(source, _Observation(stamp, msg, sensor))

    @staticmethod
    def _buffer(source: _Source, observation: _Observation) -> None:
        """Keep ``observation``, and of the older ones those within ``observation_persistence`` of it
        (Nav2's ObservationBuffer: with 0, the newest only)."""
        kept = source.observations
        kept.append(observation)
        keep_s = source.params.observation_persistence
        while len(kept) > 1 and (keep_s == 0.0 or kept[0].stamp_s < observation.stamp_s - keep_s):
            kept.popleft()

    def _mark(self, layered: LayeredCostmap, robot: tuple[float, float] | None) -> None:
        """Apply the kept scans, oldest first; not again when neither they nor the grid moved
        (clearing then marking the same scans gives the same cells). Then free the footprint."""
        observations = tuple(obs for source in self.sources for obs in source.observations)
        applied = (observations, layered.master.origin)  # scans compare by identity
        if not observations or applied == self._applied:
            return
        for source in self.sources:
            for obs in source.observations:
                msg, sensor = obs.scan, obs.sensor
                ranges = np.asarray(msg.ranges, dtype=float)
                bearings = sensor[2] + msg.angle_min + msg.angle_increment * np.arange(len(ranges))
                valid = ~(ranges < msg.range_min)  # NaN stays: no return
                ranges = np.where(np.isfinite(ranges) & (ranges < msg.range_max), ranges, np.inf)
                source.layer.observe(layered.master, (sensor[0], sensor[1]), bearings[valid], ranges[valid],
                                     source.params.source())
        if robot is not None:
            for layer in self.obstacles:
                layer.clear_footprint(robot, self.params.robot_radius)
        self._applied = applied

    # ---------------------------------------------------------------- outputs
    def update(self) -> Costmap | None:
        """Rebuild the master from the layers; returns (and keeps) a copy, or None before there is one."""
        if self.layered is None:
            return None
        robot = None
        if self.params.rolling_window or self.obstacles:
            pose = self.robot_pose()
            if pose is None and self.params.rolling_window:
                return None
            robot = None if pose is None else (pose[0], pose[1])
        if self.params.rolling_window and robot is not None:
            # Before marking, so the scans land in the window the layers are rebuilt in (the
            # layered update's own recentre then finds nothing to move).
            self.layered.master.recentre(robot[0], robot[1], self.layered.default_value)
        self._mark(self.layered, robot)
        master = self.layered.update(robot if self.params.rolling_window else None)
        self._filter(master, robot)
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
        self._publish_footprint(stamp)

    def _publish_footprint(self, stamp: Any) -> None:
        """Nav2's ``published_footprint``: the padded footprint at the robot's pose in the costmap's
        frame, for RViz (and the live view) to draw round the robot."""
        if self.footprint_pub.get_subscription_count() == 0:
            return
        pose = self.robot_pose()
        if pose is None:
            return
        p = self.params
        msg = PolygonStamped()
        msg.header.frame_id, msg.header.stamp = p.global_frame, stamp
        corners = placed(circle_footprint(p.robot_radius, p.footprint_padding), pose)
        msg.polygon.points = [Point32(x=float(x), y=float(y)) for x, y in corners]
        self.footprint_pub.publish(msg)

    def clear(self) -> None:
        for layer in self.obstacles:
            layer.clear()
        for source in self.sources:
            source.observations.clear()
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
