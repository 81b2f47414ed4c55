"""``diff_drive_controller``: Jazzy's diff_drive_controller (with its joint-state wiring) for pppbot.

Node name ``diff_drive_base_controller``. Takes ``~/cmd_vel`` (TwistStamped, Jazzy's
default) or, with ``use_stamped_vel: false`` as ppp_bot's file sets it,
``~/cmd_vel_unstamped`` (Twist, what ppp_bot's twist_mux feeds it). A stamped command
older than ``cmd_vel_timeout`` when it arrives is dropped with a warning (a zero stamp
counts as now), as Jazzy's does. It limits the command per axis (Jazzy's signs:
:mod:`pppbot_common.limits`); integrates odometry from the wheels (positions, or
velocities, or the command in open loop) and publishes it on ``~/odom`` and TF ``odom →
base_link``. With no command for ``cmd_vel_timeout`` it brakes to zero within its
deceleration limits. A parameter set at run time takes effect without resetting the
odometry. ``deactivate()`` (controller_manager's switch) commands the wheels to zero and
ignores commands until ``activate()``.

Two ways to run, as ros2_control has them:

* **hosted** (what ``launch_sim`` does): the simulator loads it in its own process, as
  gz_ros2_control loads controllers into Gazebo, and calls :meth:`DiffDriveController.update`
  every ``update_rate`` of sim time with the wheels read directly (:class:`HostedWheels`):
  it never misses a period, however busy the machine;
* **standalone** (``pppbot run pppbot_control diff_drive_controller``): its own process,
  reading ``/joint_states`` and sending wheel velocities by joint name on ``/joint_commands``
  on a timer.
"""
from __future__ import annotations

import math
import sys
from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol

from builtin_interfaces.msg import Time as TimeMsg
from geometry_msgs.msg import TransformStamped, Twist, TwistStamped
from nav_msgs.msg import Odometry as OdometryMsg
from sensor_msgs.msg import JointState
from tf2_msgs.msg import TFMessage

from pppbot_common.kinematics import DiffDriveGeometry, Odometry
from pppbot_common.limits import AxisLimits, SpeedLimiter
from pppbot_common.params import ParameterError, check_finite_range, param, parameter_fields, ros_name
from pppbot_common.ros.params import declare_parameters, fixed_parameters
from pppbot_common.ros.wire import MessageTemplate, stamp_fields, stamp_values
from pppbot_common.se2 import quaternion_from_yaw
from pppbot_lockstep.ros.node import StepNode
from pppbot_lockstep.ros.runner import Warnings, guarded, run_node

NAN = math.nan
WARN_PERIOD_S = 5.0
NODE_NAME = "diff_drive_base_controller"


@dataclass(frozen=True)
class DiffDriveParameters:
    left_wheel_names: list = param(["left_wheel_joint"], "joints of the left wheels")
    right_wheel_names: list = param(["right_wheel_joint"], "joints of the right wheels")
    wheel_separation: float = param(0.35, "distance between the wheels (m)")
    wheel_radius: float = param(0.05, "wheel radius (m)")
    wheel_separation_multiplier: float = param(1.0, "correction factor of wheel_separation")
    left_wheel_radius_multiplier: float = param(1.0, "correction factor of the left radius")
    right_wheel_radius_multiplier: float = param(1.0, "correction factor of the right radius")
    odom_frame_id: str = param("odom", "frame of the odometry")
    base_frame_id: str = param("base_link", "frame of the robot base")
    tf_frame_prefix_enable: bool = param(True, "prefix frames with tf_frame_prefix (or the node's namespace)")
    tf_frame_prefix: str = param("", "frame prefix; empty = the node's namespace")
    pose_covariance_diagonal: list = param([0.001, 0.001, 0.001, 0.001, 0.001, 0.01], "x y z roll pitch yaw")
    twist_covariance_diagonal: list = param([0.001, 0.001, 0.001, 0.001, 0.001, 0.01], "vx vy vz wx wy wz")
    open_loop: bool = param(False, "integrate the command instead of wheel feedback")
    position_feedback: bool = param(True, "odometry from wheel positions (else from wheel velocities)")
    enable_odom_tf: bool = param(True, "publish odom → base frame on /tf")
    cmd_vel_timeout: float = param(0.5, "seconds without a command before braking to zero; a stamped command "
                                        "older than this on arrival is dropped")
    use_stamped_vel: bool = param(True, "true: TwistStamped on ~/cmd_vel; false: Twist on ~/cmd_vel_unstamped")
    publish_limited_velocity: bool = param(False, "publish the limited command on ~/cmd_vel_out")
    publish_rate: float = param(50.0, "odometry and TF rate (Hz)")
    update_rate: float = param(100.0, "control loop rate (Hz); controller_manager's update_rate")
    velocity_rolling_window_size: int = param(10, "samples averaged for the odometry twist")
    linear_has_velocity_limits: bool = param(True, "legacy switch", "linear.x.has_velocity_limits")
    linear_has_acceleration_limits: bool = param(True, "legacy switch", "linear.x.has_acceleration_limits")
    linear_has_jerk_limits: bool = param(True, "legacy switch", "linear.x.has_jerk_limits")
    linear_max_velocity: float = param(NAN, "m/s; NaN = unlimited", "linear.x.max_velocity")
    linear_min_velocity: float = param(NAN, "m/s; NaN = unlimited", "linear.x.min_velocity")
    linear_max_acceleration: float = param(NAN, "m/s², > 0: speeding up forwards", "linear.x.max_acceleration")
    linear_max_deceleration: float = param(NAN, "m/s², < 0: slowing down forwards", "linear.x.max_deceleration")
    linear_max_acceleration_reverse: float = param(NAN, "m/s², < 0: speeding up backwards",
        "linear.x.max_acceleration_reverse")
    linear_max_deceleration_reverse: float = param(NAN, "m/s², > 0: slowing down backwards",
        "linear.x.max_deceleration_reverse")
    linear_min_acceleration: float = param(NAN, "m/s², negative (legacy)", "linear.x.min_acceleration")
    linear_max_jerk: float = param(NAN, "m/s³", "linear.x.max_jerk")
    linear_min_jerk: float = param(NAN, "m/s³, negative", "linear.x.min_jerk")
    angular_has_velocity_limits: bool = param(True, "legacy switch", "angular.z.has_velocity_limits")
    angular_has_acceleration_limits: bool = param(True, "legacy switch", "angular.z.has_acceleration_limits")
    angular_has_jerk_limits: bool = param(True, "legacy switch", "angular.z.has_jerk_limits")
    angular_max_velocity: float = param(NAN, "rad/s; NaN = unlimited", "angular.z.max_velocity")
    angular_min_velocity: float = param(NAN, "rad/s; NaN = unlimited", "angular.z.min_velocity")
    angular_max_acceleration: float = param(NAN, "rad/s², > 0: speeding up forwards", "angular.z.max_acceleration")
    angular_max_deceleration: float = param(NAN, "rad/s², < 0: slowing down forwards", "angular.z.max_deceleration")
    angular_max_acceleration_reverse: float = param(NAN, "rad/s², < 0: speeding up backwards",
        "angular.z.max_acceleration_reverse")
    angular_max_deceleration_reverse: float = param(NAN, "rad/s², > 0: slowing down backwards",
        "angular.z.max_deceleration_reverse")
    angular_min_acceleration: float = param(NAN, "rad/s², negative (legacy)", "angular.z.min_acceleration")
    angular_max_jerk: float = param(NAN, "rad/s³", "angular.z.max_jerk")
    angular_min_jerk: float = param(NAN, "rad/s³, negative", "angular.z.min_jerk")

    def limits(self, axis: str) -> AxisLimits:
        """The limits of ``linear`` or ``angular``, with the legacy has_* switches applied."""
        def get(name: str) -> float:
            return float(getattr(self, f"{axis}_{name}"))

        velocity = getattr(self, f"{axis}_has_velocity_limits")
        acceleration = getattr(self, f"{axis}_has_acceleration_limits")
        jerk = getattr(self, f"{axis}_has_jerk_limits")
        return AxisLimits(
            max_velocity=get("max_velocity") if velocity else NAN,
            min_velocity=get("min_velocity") if velocity else NAN,
            max_acceleration=get("max_acceleration") if acceleration else NAN,
            max_deceleration=get("max_deceleration") if acceleration else NAN,
            max_acceleration_reverse=get("max_acceleration_reverse") if acceleration else NAN,
            max_deceleration_reverse=get("max_deceleration_reverse") if acceleration else NAN,
            min_acceleration=get("min_acceleration") if acceleration else NAN,
            max_jerk=get("max_jerk") if jerk else NAN,
            min_jerk=get("min_jerk") if jerk else NAN,
        )

    def geometry(self) -> DiffDriveGeometry:
        return DiffDriveGeometry(self.wheel_separation, self.wheel_radius, self.wheel_separation_multiplier,
                                 self.left_wheel_radius_multiplier, self.right_wheel_radius_multiplier)

    def validate(self) -> None:
        for name in ("left_wheel_names", "right_wheel_names"):
            names = getattr(self, name)
            if not names or not all(isinstance(n, str) and n for n in names):
                raise ParameterError(name, names, "must be a non-empty list of joint names")
        for name in ("wheel_separation", "wheel_radius", "wheel_separation_multiplier",
                     "left_wheel_radius_multiplier", "right_wheel_radius_multiplier"):
            check_finite_range(name, getattr(self, name), 0.0, 1000.0, low_open=True)
        check_finite_range("cmd_vel_timeout", self.cmd_vel_timeout, 0.0, 3600.0)
        check_finite_range("publish_rate", self.publish_rate, 0.0, 1000.0, low_open=True)
        check_finite_range("update_rate", self.update_rate, 0.0, 1000.0, low_open=True)
        if not 1 <= self.velocity_rolling_window_size <= 1000:
            raise ParameterError("velocity_rolling_window_size", self.velocity_rolling_window_size,
                                 "must be in [1, 1000]")
        for name in ("pose_covariance_diagonal", "twist_covariance_diagonal"):
            values = getattr(self, name)
            if len(values) != 6 or not all(isinstance(v, (int, float)) and v >= 0 for v in values):
                raise ParameterError(name, values, "must be 6 non-negative numbers")
        for axis, prefix in (("linear", "linear.x"), ("angular", "angular.z")):
            for name, value, rule in self.limits(axis).problems(prefix):
                raise ParameterError(name, value, rule)


def _mean(values: deque[float]) -> float:
    return sum(values) / len(values) if values else 0.0


class HostedWheels(Protocol):
    """The wheels as a simulator hosting the controller gives them (ros2_control's hardware interface)."""

    def read(self) -> tuple[Sequence[str], Sequence[float], Sequence[float], int]:
        """(joint names, positions, velocities, sim time in ns of the reading)."""

    def write(self, velocities: Mapping[str, float]) -> None:
        """Velocity targets (rad/s) by joint name."""


class DiffDriveController(StepNode):
    def __init__(self, hosted: HostedWheels | None = None, **kwargs: object) -> None:
        super().__init__(NODE_NAME, **kwargs)  # type: ignore[arg-type]
        self.params = declare_parameters(self, DiffDriveParameters)
        self._configure(self.params)
        self.hosted = hosted
        self.active = True  # controller_manager's state: inactive ignores commands and is not updated
        # In lockstep a step waits for the commands sent before it (a command may never come).
        if self.params.use_stamped_vel:
            self.cmd_sub = self.create_subscription(TwistStamped, "~/cmd_vel",
                                                    guarded(self, self.on_cmd_vel, "TwistStamped"), 10,
                                                    data_path=True, needs_publisher=False)
        else:
            self.cmd_sub = self.create_subscription(Twist, "~/cmd_vel_unstamped",
                                                    guarded(self, self.on_cmd_vel_unstamped, "Twist"), 10,
                                                    data_path=True, needs_publisher=False)
        if hosted is None:
            self.create_subscription(JointState, "/joint_states", guarded(self, self.on_joint_states, "JointState"),
                                     10, data_path=True, needs_publisher=False)
            self.command_pub = self.create_publisher(JointState, "/joint_commands", 10)
        self.odom_pub = self.create_publisher(OdometryMsg, "~/odom", 10)
        self.tf_pub = self.create_publisher(TFMessage, "/tf", 100)
        self.limited_pub = self.create_publisher(TwistStamped, "~/cmd_vel_out", 10)
        self._warn = Warnings(self, WARN_PERIOD_S)
        self._target = (0.0, 0.0)
        self._target_ns: int | None = None  # when the command came (node clock, ns)
        self._last_update_ns: int | None = None
        self._wheel_index: tuple[tuple[str, ...], list[list[int]]] | None = None  # joint names → indices
        self._next_odom_publish_ns = 0  # on a grid of publish periods, as ros2_control publishes
        self._wheels: tuple[float, float, float, float] | None = None  # left pos, right pos, left vel, right vel
        self._wheels_stamp_ns = 0  # when the wheels were measured (the joint states' stamp)
        self._odom_stamp_ns = -1  # the stamp of the odometry last published
        self.timer = None if hosted else self.step_timer(1.0 / self.params.update_rate, self.update)
        # The command topic's type is chosen once (ros2_control reads use_stamped_vel at configure).
        live = {ros_name(f) for f in parameter_fields(DiffDriveParameters)} - {"use_stamped_vel"}
        fixed_parameters(self, lambda: self.params, live, self._apply)
        feedback = "positions" if self.params.position_feedback else "velocities"
        self.get_logger().info(
            f"wheels {self.params.left_wheel_names} / {self.params.right_wheel_names}, separation "
            f"{self.params.wheel_separation} m, radius {self.params.wheel_radius} m; odometry "
            f"{'open loop' if self.params.open_loop else 'from wheel ' + feedback}"
            f"; {'in the simulator, ' if hosted else ''}{self.params.update_rate:g} Hz; commands on "
            f"{self.cmd_sub.topic_name}, odometry on {self.odom_pub.topic_name}")

    def _configure(self, params: DiffDriveParameters) -> None:
        """Geometry, limiters, frames and message templates from ``params``; the odometry (pose,
        last wheel angles), the limiters' last command and the velocity windows carry over."""
        self.geometry = params.geometry()
        old = getattr(self, "odometry", None)
        self.odometry = Odometry(self.geometry)
        if old is not None:
            self.odometry.carry_over(old)
        self.linear = _carry_over(getattr(self, "linear", None), SpeedLimiter(params.limits("linear")))
        self.angular = _carry_over(getattr(self, "angular", None), SpeedLimiter(params.limits("angular")))
        window = params.velocity_rolling_window_size
        self._v_window: deque[float] = deque(getattr(self, "_v_window", ()), maxlen=window)
        self._w_window: deque[float] = deque(getattr(self, "_w_window", ()), maxlen=window)
        namespace = self.get_namespace().strip("/")
        prefix = params.tf_frame_prefix or (namespace if params.tf_frame_prefix_enable else "")
        self.prefix = f"{prefix.rstrip('/')}/" if prefix else ""
        self._command_names = [*params.left_wheel_names, *params.right_wheel_names]
        self._wheel_index = None
        # Odometry and its transform as templates (bytes serialized once, values patched in).
        odom = OdometryMsg()
        odom.header.frame_id = self.prefix + params.odom_frame_id
        odom.child_frame_id = self.prefix + params.base_frame_id
        for i in range(6):
            odom.pose.covariance[i * 7] = float(params.pose_covariance_diagonal[i])
            odom.twist.covariance[i * 7] = float(params.twist_covariance_diagonal[i])
        self._odom_wire = MessageTemplate(odom, [*stamp_fields(), "pose.pose.position.x", "pose.pose.position.y",
                                                 "pose.pose.orientation.z", "pose.pose.orientation.w",
                                                 "twist.twist.linear.x", "twist.twist.angular.z"])
        transform = TransformStamped()
        transform.header.frame_id = odom.header.frame_id
        transform.child_frame_id = odom.child_frame_id
        self._tf_wire = MessageTemplate(TFMessage(transforms=[transform]), [
            *stamp_fields("transforms.0.header.stamp"), "transforms.0.transform.translation.x",
            "transforms.0.transform.translation.y", "transforms.0.transform.rotation.z",
            "transforms.0.transform.rotation.w"])

    def _apply(self, params: DiffDriveParameters) -> None:
        rate_changed = params.update_rate != self.params.update_rate
        self.params = params
        self._configure(params)
        if rate_changed and self.timer is not None:
            self.destroy_step_timer(self.timer)
            self.timer = self.step_timer(1.0 / params.update_rate, self.update)

    # ------------------------------------------------------------------ inputs

    def _set_target(self, v: float, w: float, stamp_ns: int | None = None) -> None:
        """Store a command; ``stamp_ns`` is when it was made (None: now)."""
        if not self.active:
            return
        if not (math.isfinite(v) and math.isfinite(w)):
            self._warn("nonfinite", f"dropping a velocity command with non-finite values (v={v}, w={w})")
            return
        self._target = (v, w)
        self._target_ns = self.get_clock().now().nanoseconds if stamp_ns is None else stamp_ns

    def on_cmd_vel(self, msg: TwistStamped) -> None:
        """A stamped command: its age counts from its stamp (zero: now); one already older than
        ``cmd_vel_timeout`` is dropped, as Jazzy's diff_drive_controller drops it."""
        stamp_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        if stamp_ns == 0:
            self._warn("zero_stamp", "a TwistStamped with a zero stamp counts as made now")
            stamp_ns = self.get_clock().now().nanoseconds
        age_s = (self.get_clock().now().nanoseconds - stamp_ns) * 1e-9
        timeout_s = self.params.cmd_vel_timeout
        if timeout_s > 0 and age_s >= timeout_s:
            self._warn("stale", f"dropping a velocity command stamped {stamp_ns * 1e-9:.6f} s: {age_s:.4f} s old, "
                                f"older than cmd_vel_timeout {timeout_s:g} s")
            return
        self._set_target(msg.twist.linear.x, msg.twist.angular.z, stamp_ns)

    def on_cmd_vel_unstamped(self, msg: Twist) -> None:
        self._set_target(msg.linear.x, msg.angular.z)

    def on_joint_states(self, msg: JointState) -> None:
        self._store_wheels(msg.name, msg.position, msg.velocity,
                           msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec)

    def _store_wheels(self, names: Sequence[str], positions: Sequence[float], velocities: Sequence[float],
                      stamp_ns: int) -> None:
        key = tuple(names)
        if self._wheel_index is None or self._wheel_index[0] != key:
            index = {name: i for i, name in enumerate(names)}
            wanted = [*self.params.left_wheel_names, *self.params.right_wheel_names]
            missing = [n for n in wanted if n not in index]
            if missing:
                if not any(n in index for n in wanted):
                    return  # another robot part's joint states
                self._warn("missing", f"joint states lack wheel joint(s) {', '.join(missing)}")
                return
            self._wheel_index = (key, [[index[n] for n in self.params.left_wheel_names],
                                       [index[n] for n in self.params.right_wheel_names]])
        left, right = self._wheel_index[1]

        def side(indices: list[int], values: Sequence[float]) -> float:
            if len(indices) == 1:
                return float(values[indices[0]]) if indices[0] < len(values) else math.nan
            picked = [values[i] for i in indices if i < len(values)]
            return sum(picked) / len(picked) if len(picked) == len(indices) else math.nan

        sample = (side(left, positions), side(right, positions), side(left, velocities), side(right, velocities))
        needed = sample[:2] if self.params.position_feedback else sample[2:]
        if not all(math.isfinite(v) for v in needed):
            self._warn("feedback", "ignoring joint states without finite wheel "
                       + ("positions" if self.params.position_feedback else "velocities"))
            return
        self._wheels = sample
        self._wheels_stamp_ns = stamp_ns

    # ------------------------------------------------------------- lifecycle
    def deactivate(self) -> None:
        """controller_manager's deactivate: wheels commanded to zero, commands ignored, no updates."""
        self.active = False
        self._target, self._target_ns = (0.0, 0.0), None
        self.linear.reset()
        self.angular.reset()
        self._send_wheels(0.0, 0.0, self.get_clock().now().nanoseconds)

    def activate(self) -> None:
        """controller_manager's activate: commands count again, from a standstill; odometry goes on."""
        self._target, self._target_ns = (0.0, 0.0), None
        self._last_update_ns = None
        self.active = True

    # ------------------------------------------------------------------- loop
    def update(self) -> None:
        """One control period: read the wheels (hosted), limit the command, send it, integrate odometry."""
        if not self.active:
            return
        if self.hosted is not None:
            names, positions, velocities, stamp_ns = self.hosted.read()
            self._store_wheels(names, positions, velocities, stamp_ns)
        now_ns = self.get_clock().now().nanoseconds
        dt = 0.0 if self._last_update_ns is None else (now_ns - self._last_update_ns) * 1e-9
        if dt < 0:  # time went back (sim reset): start over
            self.linear.reset()
            self.angular.reset()
            dt = 0.0
            self._odom_stamp_ns = -1
            self._next_odom_publish_ns = 0
        self._last_update_ns = now_ns
        v, w = self._target
        if self._target_ns is None or (now_ns - self._target_ns) * 1e-9 > self.params.cmd_vel_timeout:
            v, w = 0.0, 0.0
        v = self.linear.limit(v, dt)
        w = self.angular.limit(w, dt)
        self._send_wheels(*self.geometry.wheel_speeds(v, w), now_ns)
        p = self.params
        if p.publish_limited_velocity:
            out = TwistStamped()
            out.header.stamp = _time_msg(now_ns)
            out.header.frame_id = self.prefix + p.base_frame_id
            out.twist.linear.x, out.twist.angular.z = v, w
            self.limited_pub.publish(out)
        self._integrate(v, w, dt)
        if now_ns >= self._next_odom_publish_ns:
            # From wheel positions, the pose is the robot's when the wheels were measured: stamp
            # it with that time, not the update's (later by the joint states' trip here), so that
            # odom → base_link at a scan's stamp is where the robot was when it scanned. Nothing
            # new since the last odometry: nothing to publish (TF would see repeated data).
            stamp_ns = self._wheels_stamp_ns if (p.position_feedback and not p.open_loop
                                                 and self._wheels_stamp_ns > 0) else now_ns
            if stamp_ns > self._odom_stamp_ns:
                self._publish_odometry(stamp_ns)
                self._odom_stamp_ns = stamp_ns
            # The next multiple of the period: odometry at fixed times (a scan at 10 Hz finds the
            # transform at its own stamp when the rates divide).
            period_ns = max(1, round(1e9 / p.publish_rate))
            self._next_odom_publish_ns = (now_ns // period_ns + 1) * period_ns

    def _send_wheels(self, left: float, right: float, now_ns: int) -> None:
        """Wheel speeds (rad/s) to every left and right wheel: directly when hosted, else on /joint_commands."""
        p = self.params
        speeds = [left] * len(p.left_wheel_names) + [right] * len(p.right_wheel_names)
        if self.hosted is not None:
            self.hosted.write(dict(zip(self._command_names, speeds, strict=True)))
        else:
            command = JointState(name=self._command_names, velocity=speeds)
            command.header.stamp = _time_msg(now_ns)
            self.command_pub.publish(command)

    def _integrate(self, v: float, w: float, dt: float) -> None:
        if self.params.open_loop:
            self.odometry.update_open_loop(v, w, dt)
        elif self._wheels is not None:
            lp, rp, lv, rv = self._wheels
            if self.params.position_feedback:
                self.odometry.update_from_positions(lp, rp, dt)
            else:
                self.odometry.update_from_velocities(lv, rv, dt)
        if dt > 0:
            self._v_window.append(self.odometry.v)
            self._w_window.append(self.odometry.w)

    def _publish_odometry(self, stamp_ns: int) -> None:
        """/odom and odom → base on /tf at ``stamp_ns``, each only when somebody listens."""
        o = self.odometry
        _, _, qz, qw = quaternion_from_yaw(o.yaw)
        if self.odom_pub.get_subscription_count():
            self.odom_pub.publish(self._odom_wire.serialize({
                **stamp_values(stamp_ns), "pose.pose.position.x": o.x, "pose.pose.position.y": o.y,
                "pose.pose.orientation.z": qz, "pose.pose.orientation.w": qw,
                "twist.twist.linear.x": _mean(self._v_window), "twist.twist.angular.z": _mean(self._w_window)}))
        if self.params.enable_odom_tf and self.tf_pub.get_subscription_count():
            self.tf_pub.publish(self._tf_wire.serialize({
                **stamp_values(stamp_ns, "transforms.0.header.stamp"), "transforms.0.transform.translation.x": o.x,
                "transforms.0.transform.translation.y": o.y, "transforms.0.transform.rotation.z": qz,
                "transforms.0.transform.rotation.w": qw}))


def _carry_over(old: SpeedLimiter | None, new: SpeedLimiter) -> SpeedLimiter:
    """``new`` (new limits) starting from ``old``'s last command and acceleration."""
    if old is not None:
        new.previous, new.previous_acceleration = old.previous, old.previous_acceleration
    return new


def _time_msg(ns: int) -> TimeMsg:
    sec, nanosec = divmod(ns, 1_000_000_000)
    return TimeMsg(sec=sec, nanosec=nanosec)


def main(args: list[str] | None = None) -> int:
    return run_node(DiffDriveController, "diff_drive_base_controller", args, fatal=(ParameterError,))


if __name__ == "__main__":
    sys.exit(main())
