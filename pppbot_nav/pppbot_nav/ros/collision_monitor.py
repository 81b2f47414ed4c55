"""``collision_monitor``: Nav2's collision monitor (:mod:`pppbot_nav.collision_monitor`) as a lifecycle node.

While active, each command on ``cmd_vel_in_topic`` (geometry_msgs/Twist, or TwistStamped with
``enable_stamped_cmd_vel``) is checked against the zones (``polygons``) with the newest points of
the ``observation_sources`` and sent on ``cmd_vel_out_topic`` as the strongest triggered action
leaves it (stop, slowdown, limit, approach). A new action is logged in Nav2's words and, when
``state_topic`` is set, published as nav2_msgs/CollisionMonitorState. Zones with ``visualize``
are published as geometry_msgs/PolygonStamped in ``base_frame_id`` on ``polygon_pub_topic``.

Sources are LaserScans (``<source>.type: scan``), their points placed in ``base_frame_id`` with
TF: with ``base_shift_correction`` as the sensor was at the scan's stamp and the robot is now
(through ``odom_frame_id``), transforms up to ``transform_tolerance`` s older than asked for
accepted. A source without a scan newer than ``source_timeout`` s (per source, default the
node's; 0 disables it), or whose scan cannot be placed, stops the robot, as in Nav2 Jazzy.

Zone parameters as Nav2 Jazzy's (``<zone>.type`` polygon | circle, ``points`` as
``"[[x, y], ...]"`` or a flat ``[x1, y1, ...]`` list, ``radius``, ``action_type``, ``min_points``,
...). Dynamic polygons (``polygon_sub_topic``, ``footprint_topic``) and other source types are
refused at configure, naming the parameter. A command with a NaN or infinite component is
dropped with a throttled warning.
"""
from __future__ import annotations

import functools
import sys
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np
from geometry_msgs.msg import Point32, PolygonStamped, Twist, TwistStamped
from nav2_msgs.msg import CollisionMonitorState
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node
from sensor_msgs.msg import LaserScan

from pppbot_common.params import (
    ParameterError,
    check_finite_range,
    description,
    field_default,
    from_values,
    param,
    parameter_fields,
    ros_name,
)
from pppbot_common.ros.params import refuse_sets
from pppbot_common.ros.planar import stamp_seconds
from pppbot_common.ros.qos import DEFAULT, LATCHED, SENSOR
from pppbot_common.transforms import Pose2D, TransformError, compose, inverse
from pppbot_lockstep.ros.lifecycle import ManagedNode
from pppbot_lockstep.ros.runner import Warnings, guarded, run_nodes
from pppbot_lockstep.ros.tf_listener import TfListener
from pppbot_nav.collision_monitor import (
    ACTION_NAMES,
    INVALID_SOURCE,
    ActionType,
    CircleShape,
    Decision,
    PolygonShape,
    StopRepeat,
    Velocity,
    Zone,
    decide,
    describe,
    fresh,
    parse_points,
    scan_points,
    transformed,
)
from pppbot_nav.errors import CollisionMonitorError

T = TypeVar("T")


@dataclass(frozen=True)
class CollisionMonitorParameters:
    base_frame_id: str = param("base_link", "the robot's frame: zones are in it")
    odom_frame_id: str = param("odom", "the fixed frame for base_shift_correction")
    cmd_vel_in_topic: str = param("cmd_vel_smoothed", "commands to check")
    cmd_vel_out_topic: str = param("cmd_vel", "commands as checked")
    state_topic: str = param("collision_monitor_state", "nav2_msgs/CollisionMonitorState on a new action ('': none)")
    transform_tolerance: float = param(0.1, "transforms this much older than asked for are used (s)")
    source_timeout: float = param(1.0, "data older than this stops the robot (s; 0: never)")
    base_shift_correction: bool = param(True, "place points as the robot has moved since their stamp")
    stop_pub_timeout: float = param(2.0, "a stop is repeated this long, then no longer sent (s)")
    enable_stamped_cmd_vel: bool = param(False, "input and output geometry_msgs/TwistStamped (else Twist)")
    polygons: list = param([], "zone names, in order")
    observation_sources: list = param([], "source names")

    def validate(self) -> None:
        for name in ("base_frame_id", "odom_frame_id", "cmd_vel_in_topic", "cmd_vel_out_topic"):
            if not getattr(self, name):
                raise ParameterError(name, getattr(self, name), "must not be empty")
        for name in ("transform_tolerance", "source_timeout", "stop_pub_timeout"):
            check_finite_range(name, getattr(self, name), 0.0, 3600.0)
        for name in ("polygons", "observation_sources"):
            names = getattr(self, name)
            if not names or not all(isinstance(n, str) and n for n in names) or len(set(names)) != len(names):
                raise ParameterError(name, names, "must be a non-empty list of distinct names")


@dataclass(frozen=True)
class ZoneParameters:
    """``<zone>.*``: one of Nav2's polygons."""
    type: str = param("", "polygon or circle")
    points: Any = param(None, "polygon: '[[x, y], [x, y], ...]' or [x1, y1, x2, y2, ...] (m, base frame)")
    radius: float = param(0.0, "circle: radius around the base frame's origin (m)")
    action_type: str = param("", "stop, slowdown, limit or approach")
    min_points: int = param(4, "the zone triggers with at least this many points inside")
    max_points: int = param(-1, "Nav2 Humble's name, refused: min_points is max_points + 1")
    slowdown_ratio: float = param(0.5, "slowdown: the command times this")
    linear_limit: float = param(0.5, "limit: largest linear speed (m/s)")
    angular_limit: float = param(0.5, "limit: largest turn rate (rad/s)")
    time_before_collision: float = param(2.0, "approach: keep this long from a collision (s)")
    simulation_time_step: float = param(0.1, "approach: simulation step (s)")
    visualize: bool = param(False, "publish the zone as geometry_msgs/PolygonStamped")
    polygon_pub_topic: str = param("", "where the zone is published (default: its name)")
    enabled: bool = param(True, "whether the zone is checked")
    polygon_sub_topic: str = param("", "a polygon from a topic: not supported")
    footprint_topic: str = param("", "the footprint from a topic: not supported")
    sources_names: list = param([], "the sources whose points count (default: all)")

    def validate(self) -> None:
        for name in ("polygon_sub_topic", "footprint_topic"):
            if getattr(self, name):
                raise ParameterError(name, getattr(self, name), "zones from topics are not supported by pppbot's "
                                                                "collision monitor: give points or a radius")
        if self.max_points != -1:
            raise ParameterError("max_points", self.max_points, "renamed in Nav2 Jazzy: set min_points "
                                                                "(= max_points + 1) instead")
        try:
            self.zone("zone")
        except CollisionMonitorError as exc:
            name = exc.parameter or "type"
            raise ParameterError(name, getattr(self, name, ""), str(exc)) from exc

    def zone(self, name: str) -> Zone:
        """Raises:
            CollisionMonitorError: a bad shape or action, naming the parameter.
        """
        shape: PolygonShape | CircleShape
        if self.type == "polygon":
            if self.points is None:
                raise CollisionMonitorError("a polygon needs points", "points")
            shape = PolygonShape(parse_points(self.points))
        elif self.type == "circle":
            shape = CircleShape(self.radius)
        else:
            raise CollisionMonitorError(f"type '{self.type}' is not one of polygon, circle", "type")
        if self.action_type not in ACTION_NAMES:
            raise CollisionMonitorError(f"action_type '{self.action_type}' is not one of "
                                        f"{', '.join(ACTION_NAMES)}", "action_type")
        zone = Zone(name, shape, ACTION_NAMES[self.action_type], self.min_points, self.slowdown_ratio,
                    self.linear_limit, self.angular_limit, self.time_before_collision, self.simulation_time_step,
                    self.enabled, tuple(self.sources_names))
        zone.validate()
        return zone


@dataclass(frozen=True)
class SourceParameters:
    """``<source>.*``: one of Nav2's observation sources (pppbot: LaserScans only)."""
    type: str = param("scan", "scan (sensor_msgs/LaserScan)")
    topic: str = param("scan", "the source's topic")
    enabled: bool = param(True, "whether the source is used")
    source_timeout: float = param(1.0, "data older than this stops the robot (s; 0: never); default the node's")

    def validate(self) -> None:
        if self.type != "scan":
            raise ParameterError("type", self.type, "pppbot's collision monitor takes scan sources only")
        if not self.topic:
            raise ParameterError("topic", self.topic, "must not be empty")
        check_finite_range("source_timeout", self.source_timeout, 0.0, 3600.0)


def read_group(node: Node, cls: type[T], prefix: str = "", defaults: dict[str, Any] | None = None) -> T:
    """``cls`` from the node's ``<prefix><name>`` parameters, declared on first use (``defaults``
    replaces field defaults by name).

    Raises:
        ParameterError: naming the full parameter.
    """
    values = {}
    for field in parameter_fields(cls):
        name = ros_name(field)
        if node.has_parameter(prefix + name):
            values[name] = node.get_parameter(prefix + name).value
        else:
            default = (defaults or {}).get(name, field_default(field))
            descriptor = ParameterDescriptor(description=description(cls, field), dynamic_typing=True)
            values[name] = node.declare_parameter(prefix + name, default, descriptor).value
    try:
        return from_values(cls, values)
    except ParameterError as exc:
        raise ParameterError(prefix + exc.name, exc.value, exc.allowed) from exc


@dataclass(frozen=True)
class _Config:
    """Everything configure reads: the node's parameters, and each zone's and source's by name."""
    node: CollisionMonitorParameters
    zones: tuple[tuple[str, ZoneParameters], ...]
    sources: tuple[tuple[str, SourceParameters], ...]


def _twist(msg: Any) -> Velocity:
    t = msg.twist if isinstance(msg, TwistStamped) else msg
    return Velocity(float(t.linear.x), float(t.linear.y), float(t.angular.z))


class CollisionMonitor(ManagedNode):
    """A lifecycle node, as Nav2's: checks and publishes commands only while active."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("collision_monitor", **kwargs)
        refuse_sets(self, "it is read at configure: deactivate and clean up the node, set it, then configure it",
                    allowed=lambda name: name == "use_sim_time" or self.state == "unconfigured")
        self._warn = Warnings(self, settling=("source",))
        self.tf = TfListener(self, self._warn).buffer
        self.config: _Config | None = None
        self.zones: list[Zone] = []
        self.latest: dict[str, LaserScan | None] = {}  # each source's newest scan
        self._endpoints: list[Any] = []
        self.polygon_pubs: dict[str, Any] = {}
        self.state_pub: Any = None
        self._previous = Decision(ActionType.DO_NOTHING, "", Velocity())
        self._repeat = StopRepeat(0.0)
        #: Commands received while not active: dropped, as by Nav2's inactive node.
        self.ignored_inactive = 0
        try:
            config = self._read()
        except ParameterError:
            return  # configure reads them again and fails naming the bad one
        # Made now, not at configure, so that lockstep sees them from the start (see lifecycle).
        self._make_endpoints(config)

    # ------------------------------------------------------------- lifecycle
    def _read(self) -> _Config:
        """Raises:
            ParameterError: naming the bad parameter in full (``PolygonStop.action_type``).
        """
        p = read_group(self, CollisionMonitorParameters)
        zones = tuple((name, read_group(self, ZoneParameters, f"{name}.")) for name in p.polygons)
        sources = tuple((name, read_group(self, SourceParameters, f"{name}.", {"source_timeout": p.source_timeout}))
                        for name in p.observation_sources)
        for name, zone in zones:
            unknown = [s for s in zone.sources_names if s not in p.observation_sources]
            if unknown:
                raise ParameterError(f"{name}.sources_names", zone.sources_names,
                                     f"{', '.join(unknown)} not in observation_sources {p.observation_sources}")
        return _Config(p, zones, sources)

    def configure(self) -> None:
        config = self._read()
        if config != self.config:
            self._make_endpoints(config)
        self.zones = [zone.zone(name) for name, zone in config.zones]
        self._repeat = StopRepeat(config.node.stop_pub_timeout)
        summary = ", ".join(f"{z.name} ({z.action.name.lower()})" for z in self.zones)
        self.get_logger().info(f"checking {config.node.cmd_vel_in_topic} → {config.node.cmd_vel_out_topic} in "
                               f"'{config.node.base_frame_id}': {summary}; sources: "
                               f"{', '.join(name for name, _ in config.sources)}")

    def activate(self) -> None:
        self._previous = Decision(ActionType.DO_NOTHING, "", Velocity())
        self._repeat = StopRepeat(self._repeat.timeout_s)

    def cleanup(self) -> None:
        self.zones = []
        self.latest = dict.fromkeys(self.latest)

    def _make_endpoints(self, config: _Config) -> None:
        """(Re)make the topics for ``config``."""
        for endpoint in self._endpoints:
            if hasattr(endpoint, "publish"):
                self.destroy_publisher(endpoint)
            else:
                self.destroy_subscription(endpoint)
        self.config = p = config
        self.msg_type = TwistStamped if p.node.enable_stamped_cmd_vel else Twist
        self.output = self.create_publisher(self.msg_type, p.node.cmd_vel_out_topic, 1)
        self.port.require_match(self, self.output)
        commands = self.create_subscription(self.msg_type, p.node.cmd_vel_in_topic,
                                            guarded(self, self._on_command, "command"), 1, data_path=True,
                                            at_step=True, needs_publisher=False)
        self._endpoints = [self.output, commands]
        self.state_pub = None
        if p.node.state_topic:
            self.state_pub = self.create_publisher(CollisionMonitorState, p.node.state_topic, DEFAULT)
            self._endpoints.append(self.state_pub)
        self.polygon_pubs = {}
        for name, zone in p.zones:
            if zone.visualize:
                self.polygon_pubs[name] = self.create_publisher(PolygonStamped, zone.polygon_pub_topic or name, LATCHED)
                self._endpoints.append(self.polygon_pubs[name])
        self.latest = {}
        for name, source in p.sources:
            self.latest[name] = None
            if source.enabled:
                on_scan = guarded(self, functools.partial(self._on_scan, name), "LaserScan")
                scans = self.create_subscription(LaserScan, source.topic, on_scan, SENSOR, data_path=True)
                self._endpoints.append(scans)

    # ---------------------------------------------------------------- inputs
    def _now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _on_scan(self, name: str, msg: LaserScan) -> None:
        self.latest[name] = msg

    def _on_command(self, msg: Any) -> None:
        if not self.active or self.config is None:
            self.ignored_inactive += 1
            return
        command = _twist(msg)
        if not command.is_finite():
            self._warn("command", f"dropping a command with a component that is not finite: {command}")
            return
        now_s = self._now_s()
        points, invalid = self.source_points(now_s)
        decision = decide(self.zones, command, points, invalid)
        self._report(decision)
        if self._repeat.allow(decision.velocity, now_s):
            out = self.msg_type()
            twist = out.twist if isinstance(out, TwistStamped) else out
            twist.linear.x, twist.linear.y = decision.velocity.x_mps, decision.velocity.y_mps
            twist.angular.z = decision.velocity.yaw_radps
            if isinstance(out, TwistStamped):
                out.header = msg.header
            self.output.publish(out)
        self._publish_polygons()

    def _report(self, decision: Decision) -> None:
        """Log and publish a decision that differs from the last one."""
        previous, self._previous = self._previous, decision
        if (decision.action, decision.polygon_name) == (previous.action, previous.polygon_name):
            return
        text = describe(decision, self.zones)
        if decision.polygon_name == INVALID_SOURCE:
            self.get_logger().warning(text)
        else:
            self.get_logger().info(text)
        if self.state_pub is not None:
            self.state_pub.publish(CollisionMonitorState(action_type=int(decision.action),
                                                         polygon_name=decision.polygon_name))

    # --------------------------------------------------------------- sources
    def source_points(self, now_s: float) -> tuple[dict[str, np.ndarray], list[str]]:
        """Each enabled source's points in the base frame, and the sources without usable data
        (missing, stale, or not placeable: these stop the robot unless their timeout is 0)."""
        assert self.config is not None
        points: dict[str, np.ndarray] = {}
        invalid: list[str] = []
        for name, source in self.config.sources:
            if not source.enabled:
                continue
            try:
                points[name] = self._scan_in_base(name, source, now_s)
            except (CollisionMonitorError, TransformError) as exc:
                points[name] = np.empty((0, 2))
                if source.source_timeout != 0.0:
                    invalid.append(name)
                    self._warn("source", f"source '{name}': {exc}")
        return points, invalid

    def _scan_in_base(self, name: str, source: SourceParameters, now_s: float) -> np.ndarray:
        """Raises:
            CollisionMonitorError: no scan yet, or the newest is older than the source's timeout.
            TransformError: the scan cannot be placed in the base frame.
        """
        assert self.config is not None
        p = self.config.node
        msg = self.latest.get(name)
        if msg is None:
            raise CollisionMonitorError(f"no scan yet on '{source.topic}'")
        stamp_s = stamp_seconds(msg.header.stamp)
        if not fresh(stamp_s, now_s, source.source_timeout):
            raise CollisionMonitorError(f"the newest scan is {now_s - stamp_s:.3f} s old "
                                        f"(source_timeout {source.source_timeout:g} s)")
        frame = msg.header.frame_id.lstrip("/")
        if p.base_shift_correction:
            sensor_then = self._lookup(p.odom_frame_id, frame, stamp_s)
            base_now = self._lookup(p.odom_frame_id, p.base_frame_id, now_s)
            sensor = compose(inverse(base_now), sensor_then)
        else:
            sensor = self.tf.lookup(p.base_frame_id, frame)
        self._warn.settled("source")
        return transformed(scan_points(msg.ranges, msg.angle_min, msg.angle_increment, msg.range_min,
                                       msg.range_max), sensor)

    def _lookup(self, target: str, source: str, time_s: float) -> Pose2D:
        """The transform at ``time_s``, or the newest when it is at most ``transform_tolerance`` older.

        Raises:
            TransformError: neither.
        """
        assert self.config is not None
        try:
            return self.tf.lookup(target, source, time_s)
        except TransformError:
            newest = self.tf.latest_time(target, source)
            if newest is None or not 0.0 <= time_s - newest <= self.config.node.transform_tolerance:
                raise
            return self.tf.lookup(target, source, newest)

    # ---------------------------------------------------------- visualization
    def _publish_polygons(self) -> None:
        assert self.config is not None
        stamp = self.get_clock().now().to_msg()
        for zone in self.zones:
            publisher = self.polygon_pubs.get(zone.name)
            if publisher is None:
                continue
            msg = PolygonStamped()
            msg.header.frame_id = self.config.node.base_frame_id
            msg.header.stamp = stamp
            msg.polygon.points = [Point32(x=float(x), y=float(y), z=0.0) for x, y in zone.outline()]
            publisher.publish(msg)


def main(args: list[str] | None = None) -> int:
    return run_nodes([CollisionMonitor], "collision_monitor", args)


if __name__ == "__main__":
    sys.exit(main())
