"""Gazebo's differential-drive plugins, read as Gazebo reads them, and what they do each period.

Two plugins drive a model's wheels from a ``geometry_msgs/Twist`` topic and publish odometry:

- Gazebo's (Fortress and later) ``DiffDrive`` system: ``gz::sim::systems::DiffDrive``
  (``gz-sim-diff-drive-system``) or ``ignition::gazebo::systems::DiffDrive``
  (``ignition-gazebo-diff-drive-system``), on a world model or in a URDF ``<gazebo>`` block.
  ``<left_joint>``/``<right_joint>`` (each at least once), ``<wheel_separation>`` (1.0 m),
  ``<wheel_radius>`` (0.2 m), ``<topic>`` (``/model/<model>/cmd_vel``), ``<odom_topic>``
  (``/model/<model>/odometry``), ``<tf_topic>`` (``/model/<model>/tf``), ``<frame_id>``
  (``<model>/odom``), ``<child_frame_id>`` (``<model>/<canonical link>``),
  ``<odom_publish_frequency>`` (50 Hz), and the linear/angular ``min_``/``max_`` velocity,
  acceleration and jerk limits. Topics keep their names over ros_gz_bridge (a relative
  ``cmd_vel`` is ``/cmd_vel``). Commands have no timeout: the last one holds.
- Gazebo classic's ROS 2 plugin ``libgazebo_ros_diff_drive.so``: ``<ros><namespace>`` and
  ``<remapping>`` for its ``cmd_vel`` and ``odom`` topics, ``<wheel_separation>`` (0.34 m),
  ``<wheel_diameter>`` (0.15 m), ``<max_wheel_torque>`` (5 N·m), ``<max_wheel_acceleration>``
  (m/s², 0: none), ``<update_rate>`` (100 Hz), ``<odometry_frame>`` (``odom``),
  ``<robot_base_frame>`` (``base_footprint``), ``<publish_odom>``, ``<publish_odom_tf>`` (false),
  ``<odometry_source>`` (1: the model's true pose in the world; 0: wheel encoders).

Elements a plugin does not read are named once with file and line (a ``<odom_publisher_frequency>``
written for ``<odom_publish_frequency>`` changes nothing in Gazebo either).
"""
from __future__ import annotations

import dataclasses
import enum
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from lxml import etree

from pppbot_common.kinematics import DiffDriveGeometry, Odometry
from pppbot_common.limits import AxisLimits, SpeedLimiter
from pppbot_description.urdf_model import GazeboPlugin
from pppbot_sim.errors import PluginError
from pppbot_sim.sdf_model import ModelPlugin

GZ_NAMES = ("gz::sim::systems::DiffDrive", "ignition::gazebo::systems::DiffDrive")
CLASSIC_FILE = "gazebo_ros_diff_drive"


class Flavor(enum.Enum):
    GZ = "gz"  # Gazebo (Fortress and later): the DiffDrive system
    CLASSIC = "classic"  # Gazebo classic's libgazebo_ros_diff_drive.so


_GZ_LIMITS = {f"{bound}_{axis}_{kind}" for bound in ("min", "max") for axis in ("linear", "angular")
              for kind in ("velocity", "acceleration", "jerk")}
_GZ_KNOWN = {"left_joint", "right_joint", "wheel_separation", "wheel_radius", "odom_publish_frequency", "topic",
             "odom_topic", "tf_topic", "frame_id", "child_frame_id", *_GZ_LIMITS,
             *(f"{bound}_{kind}" for bound in ("min", "max") for kind in ("velocity", "acceleration", "jerk"))}
_CLASSIC_KNOWN = {"left_joint", "right_joint", "num_wheel_pairs", "wheel_separation", "wheel_diameter",
                  "max_wheel_torque", "max_wheel_acceleration", "update_rate", "odometry_frame", "robot_base_frame",
                  "publish_odom", "publish_odom_tf", "publish_wheel_tf", "odometry_source", "ros", "covariance_x",
                  "covariance_y", "covariance_yaw"}


def flavor_of(filename: str, name: str) -> Flavor | None:
    """Which DiffDrive plugin a ``<plugin filename name>`` is (None: another plugin)."""
    if name in GZ_NAMES or "diff-drive-system" in filename or "diff_drive_system" in filename:
        return Flavor.GZ
    if CLASSIC_FILE in filename:
        return Flavor.CLASSIC
    return None


@dataclass(frozen=True)
class DiffDriveSpec:
    """One DiffDrive plugin as configured; joint names as the simulation knows them."""

    flavor: Flavor
    model: str
    left_joints: tuple[str, ...]
    right_joints: tuple[str, ...]
    wheel_separation_m: float
    wheel_radius_m: float
    topic: str
    odom_topic: str
    tf_topic: str | None  # None: no transform published
    frame_id: str
    child_frame_id: str
    update_rate_hz: float  # commands and limits
    odom_rate_hz: float
    publish_odom: bool
    linear: AxisLimits = AxisLimits()
    angular: AxisLimits = AxisLimits()
    wheel_acceleration: float = 0.0  # classic: m/s² at the wheel rim, 0 = none
    max_wheel_torque: float = math.inf  # classic: N·m
    odometry_from_world: bool = False  # classic odometry_source 1
    #: the world body whose pose is the model's (``model::link``); empty for the robot's root
    body: str = ""
    where: str = ""
    warnings: tuple[str, ...] = field(default=(), compare=False)

    @property
    def joints(self) -> tuple[str, ...]:
        return (*self.left_joints, *self.right_joints)


def _topic(text: str) -> str:
    return "/" + text.strip().strip("/")


class _Fields:
    """A plugin element's children, read with errors naming the file and line."""

    def __init__(self, element: etree._Element, where: Callable[[etree._Element | None], str]) -> None:
        self.element = element
        self.where = where

    def texts(self, tag: str) -> list[str]:
        return [(e.text or "").strip() for e in self.element.findall(tag)]

    def text(self, tag: str, default: str) -> str:
        found = self.element.find(tag)
        return default if found is None or not (found.text or "").strip() else (found.text or "").strip()

    def number(self, tag: str, default: float, positive: bool = False) -> float:
        found = self.element.find(tag)
        if found is None:
            return default
        try:
            value = float((found.text or "").strip())
        except ValueError:
            value = math.nan
        if not math.isfinite(value) or (positive and value <= 0):
            rule = "a positive number" if positive else "a number"
            raise PluginError(f"{self.where(found)}: <{tag}> must be {rule}, not '{(found.text or '').strip()}'")
        return value

    def flag(self, tag: str, default: bool) -> bool:
        text = self.text(tag, "").lower()
        if not text:
            return default
        if text not in ("true", "false", "1", "0"):
            raise PluginError(f"{self.where(self.element.find(tag))}: <{tag}> must be true or false, not '{text}'")
        return text in ("true", "1")

    def unknown(self, known: set[str], plugin: str) -> tuple[str, ...]:
        return tuple(f"{self.where(child)}: <{child.tag}> is not a parameter of {plugin}: ignored (as Gazebo does)"
                     for child in self.element if isinstance(child.tag, str) and child.tag not in known)


def read_diff_drive(element: etree._Element, flavor: Flavor, model: str, canonical_link: str,
                    qualify: Callable[[str], str], where: Callable[[etree._Element | None], str]) -> DiffDriveSpec:
    """The DiffDrive plugin ``element`` of ``model``: ``qualify`` turns a joint name as written
    into the simulation's; ``where(element)`` gives ``file:line`` for messages.

    Raises:
        PluginError: no left or right joint, a bad number or flag.
    """
    f = _Fields(element, where)
    left, right = f.texts("left_joint"), f.texts("right_joint")
    if not left or not right or not all(left + right):
        raise PluginError(f"{where(element)}: the DiffDrive plugin of '{model}' needs at least one <left_joint> and "
                          "one <right_joint>")
    if flavor is Flavor.GZ:
        return _gz(f, model, canonical_link, (tuple(map(qualify, left)), tuple(map(qualify, right))), where(element))
    return _classic(f, model, (tuple(map(qualify, left)), tuple(map(qualify, right))), where(element))


def _gz(f: _Fields, model: str, canonical_link: str, joints: tuple[tuple[str, ...], tuple[str, ...]],
        where: str) -> DiffDriveSpec:
    def limits(axis: str) -> AxisLimits:
        def get(name: str) -> float:
            generic = f.number(name.replace(f"_{axis}", ""), math.nan) if axis == "linear" else math.nan
            return f.number(name, generic)
        low_jerk = get(f"min_{axis}_jerk")
        return AxisLimits(max_velocity=get(f"max_{axis}_velocity"), min_velocity=get(f"min_{axis}_velocity"),
                          max_acceleration=get(f"max_{axis}_acceleration"),
                          min_acceleration=get(f"min_{axis}_acceleration"),
                          max_jerk=get(f"max_{axis}_jerk"), min_jerk=low_jerk)
    rate = f.number("odom_publish_frequency", 50.0, positive=True)
    linear, angular = limits("linear"), limits("angular")
    problems = [*linear.problems("linear"), *angular.problems("angular")]
    if problems:
        name, value, rule = problems[0]
        axis, _, setting = name.partition(".")
        bound, _, kind = setting.partition("_")
        raise PluginError(f"{where}: the DiffDrive plugin of '{model}': <{bound}_{axis}_{kind}> {value} {rule}")
    return DiffDriveSpec(
        Flavor.GZ, model, *joints, f.number("wheel_separation", 1.0, positive=True),
        f.number("wheel_radius", 0.2, positive=True), _topic(f.text("topic", f"/model/{model}/cmd_vel")),
        _topic(f.text("odom_topic", f"/model/{model}/odometry")), _topic(f.text("tf_topic", f"/model/{model}/tf")),
        f.text("frame_id", f"{model}/odom"), f.text("child_frame_id", f"{model}/{canonical_link}"),
        max(100.0, rate), rate, True, linear, angular, where=where,
        warnings=f.unknown(_GZ_KNOWN, "Gazebo's DiffDrive system"))


def _classic(f: _Fields, model: str, joints: tuple[tuple[str, ...], tuple[str, ...]], where: str) -> DiffDriveSpec:
    namespace, remaps = "", {}
    ros = f.element.find("ros")
    if ros is not None:
        namespace = (ros.findtext("namespace") or "").strip().strip("/")
        for remap in ros.findall("remapping"):
            old, sep, new = (remap.text or "").strip().partition(":=")
            if not sep:
                raise PluginError(f"{f.where(remap)}: <remapping> must be from:=to, not '{(remap.text or '').strip()}'")
            remaps[old.strip().strip("/")] = new.strip()

    def topic(name: str) -> str:
        target = remaps.get(name, name)
        return target if target.startswith("/") else _topic(f"{namespace}/{target}")

    warnings = list(f.unknown(_CLASSIC_KNOWN, "libgazebo_ros_diff_drive"))
    if f.flag("publish_wheel_tf", False):
        warnings.append(f"{f.where(f.element.find('publish_wheel_tf'))}: <publish_wheel_tf> is not simulated "
                        "(robot_state_publisher publishes the wheels' transforms from /joint_states)")
    source = f.number("odometry_source", 1.0)
    if source not in (0.0, 1.0):
        raise PluginError(f"{f.where(f.element.find('odometry_source'))}: <odometry_source> must be 0 (encoder) or "
                          f"1 (world), not {source:g}")
    rate = f.number("update_rate", 100.0, positive=True)
    return DiffDriveSpec(
        Flavor.CLASSIC, model, *joints, f.number("wheel_separation", 0.34, positive=True),
        f.number("wheel_diameter", 0.15, positive=True) / 2.0, topic("cmd_vel"), topic("odom"),
        "/tf" if f.flag("publish_odom_tf", False) else None, f.text("odometry_frame", "odom"),
        f.text("robot_base_frame", "base_footprint"), rate, rate, f.flag("publish_odom", False),
        wheel_acceleration=f.number("max_wheel_acceleration", 0.0),
        max_wheel_torque=f.number("max_wheel_torque", 5.0, positive=True), odometry_from_world=source == 1.0,
        where=where, warnings=tuple(warnings))


@dataclass(frozen=True)
class Pose2D:
    x: float
    y: float
    yaw: float
    v: float  # m/s forward
    w: float  # rad/s


class DiffDriveSystem:
    """What one DiffDrive plugin does each period: limit the last command, turn it into wheel
    speeds, and integrate odometry from the first left and right wheels' angles."""

    def __init__(self, spec: DiffDriveSpec) -> None:
        self.spec = spec
        self.geometry = DiffDriveGeometry(spec.wheel_separation_m, spec.wheel_radius_m)
        self.odometry = Odometry(self.geometry)
        self.linear = SpeedLimiter(spec.linear)
        self.angular = SpeedLimiter(spec.angular)
        wheel = AxisLimits(max_acceleration=spec.wheel_acceleration) if spec.wheel_acceleration > 0 else AxisLimits()
        self.wheels = (SpeedLimiter(wheel), SpeedLimiter(wheel))
        self.target = (0.0, 0.0)

    def command(self, v: float, w: float) -> None:
        """A Twist's ``linear.x`` (m/s) and ``angular.z`` (rad/s); it holds until the next.

        Raises:
            ValueError: a non-finite value (the last command stays).
        """
        if not (math.isfinite(v) and math.isfinite(w)):
            raise ValueError(f"non-finite velocity command (linear.x={v}, angular.z={w})")
        self.target = (v, w)

    def wheel_speeds(self, dt: float) -> dict[str, float]:
        """Wheel velocity targets (rad/s) by joint, after ``dt`` seconds of the limits."""
        v = self.linear.limit(self.target[0], dt)
        w = self.angular.limit(self.target[1], dt)
        left, right = self.geometry.wheel_speeds(v, w)
        radius = self.spec.wheel_radius_m
        left = self.wheels[0].limit(left * radius, dt) / radius
        right = self.wheels[1].limit(right * radius, dt) / radius
        return {**dict.fromkeys(self.spec.left_joints, left), **dict.fromkeys(self.spec.right_joints, right)}

    def integrate(self, left_rad: float, right_rad: float, dt: float) -> Pose2D:
        """Odometry after the first left and right wheels turned to these angles (cumulative)."""
        self.odometry.update_from_positions(left_rad, right_rad, dt)
        o = self.odometry
        return Pose2D(o.x, o.y, o.yaw, o.v, o.w)

    def reset(self) -> None:
        self.odometry.reset()
        self.linear.reset()
        self.angular.reset()
        for wheel in self.wheels:
            wheel.reset()
        self.target = (0.0, 0.0)


#: Robot plugins the simulator honours without a DiffDrive: gz_ros2_control (its controllers run in
#: the simulator) and the joint state publishers (the simulator's own /joint_states).
ROBOT_PLUGINS_HONOURED = ("ros2_control", "joint-state-publisher", "JointStatePublisher", "joint_state_publisher")


@dataclass(frozen=True)
class Plugins:
    """The DiffDrive plugins found, and one line for each plugin or element that is not simulated."""

    diff_drives: list[DiffDriveSpec]
    warnings: list[str]


def robot_plugins(plugins: Sequence[GazeboPlugin], robot: str, root_link: str) -> Plugins:
    """The DiffDrive plugins of a robot's ``<gazebo>`` blocks (joint names as the URDF's).

    Raises:
        PluginError: a DiffDrive plugin that cannot work as written.
    """
    found: list[DiffDriveSpec] = []
    warnings: list[str] = []
    for plugin in plugins:
        flavor = flavor_of(plugin.filename, plugin.name)
        if flavor is not None and plugin.element is not None:
            spec = read_diff_drive(plugin.element, flavor, robot, root_link, lambda joint: joint, plugin.where)
            found.append(spec)
            warnings += spec.warnings
        elif not any(part in plugin.filename or part in plugin.name for part in ROBOT_PLUGINS_HONOURED):
            warnings.append(f"{plugin.where()}: plugin '{plugin.name}' ({plugin.filename}) of robot '{robot}' is not "
                            "simulated: ignored")
    return Plugins(found, warnings)


def world_plugins(plugins: Sequence[ModelPlugin]) -> Plugins:
    """The DiffDrive plugins of a world's models (joint names scoped: ``model::joint``).

    Raises:
        PluginError: a DiffDrive plugin that cannot work as written.
    """
    found: list[DiffDriveSpec] = []
    warnings: list[str] = []
    for plugin in plugins:
        filename, name = plugin.element.get("filename", ""), plugin.element.get("name", "")
        flavor = flavor_of(filename, name)
        if flavor is None:
            warnings.append(f"{plugin.where()}: plugin '{name}' ({filename}) of model '{plugin.model}' is not "
                            "simulated: ignored")
            continue
        scope = f"{plugin.model}::"
        spec = read_diff_drive(plugin.element, flavor, plugin.model, plugin.canonical_link,
                               scope.__add__, plugin.where)
        spec = dataclasses.replace(spec, body=f"{plugin.model}::{plugin.canonical_link}")
        found.append(spec)
        warnings += spec.warnings
    return Plugins(found, warnings)
