"""``velocity_smoother``: Nav2's velocity smoother (:mod:`pppbot_nav.velocity_smoothing`) as a lifecycle node.

Subscribes ``cmd_vel`` (geometry_msgs/Twist, or TwistStamped with ``enable_stamped_cmd_vel``; the
bringup remaps it to ``cmd_vel_nav``, as Nav2 Jazzy's does) and, while active, publishes
``cmd_vel_smoothed``: the last command within the velocity, acceleration and deadband limits,
one smoothing period (``1 / smoothing_frequency`` s of sim time) per output. Each command is
smoothed as it comes (at the step it arrives in lockstep), and the node's timer, running at
``smoothing_frequency`` from the start, smooths again when no command came within a period (Nav2
publishes on its timer only: with the controller at the smoothing frequency the outputs are the
same; in lockstep a relay on the command's own step keeps runs identical, which a timer-only
relay did not, measured by tests/integration/test_busy_machine.py). With
``feedback: CLOSED_LOOP`` the current velocity is the odometry on ``odom_topic`` averaged over
``odom_duration`` s. A command that is ``velocity_timeout`` s old is replaced by zero; once the
output is zero the node is quiet until the next command.

Parameters are Nav2's; bad ones fail ``configure`` with a message naming them. A command with a
NaN or infinite component is dropped with a throttled warning.
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from typing import Any

from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry

from pppbot_common.params import ParameterError, from_values, param, parameter_fields, ros_name
from pppbot_common.ros.params import LiveParameters, declare_parameters, serve_live_parameters
from pppbot_common.ros.planar import stamp_seconds
from pppbot_lockstep.ros.lifecycle import ManagedNode
from pppbot_lockstep.ros.runner import Warnings, guarded, run_nodes
from pppbot_nav.errors import VelocitySmootherError
from pppbot_nav.velocity_smoothing import (
    Feedback,
    OdomAverage,
    SmootherLimits,
    Velocity3,
    VelocitySmoothing,
    feedback_of,
    vector3,
)


@dataclass(frozen=True)
class VelocitySmootherParameters:
    smoothing_frequency: float = param(20.0, "outputs per second (Hz, sim time)")
    scale_velocities: bool = param(False, "scale all axes by one factor to keep the commanded direction")
    feedback: str = param("OPEN_LOOP", "the current velocity: OPEN_LOOP (the last output) or CLOSED_LOOP (odometry)")
    max_velocity: list = param([0.5, 0.0, 2.0], "largest velocity (x m/s, y m/s, theta rad/s)")
    min_velocity: list = param([-0.5, 0.0, -2.0], "smallest velocity (x m/s, y m/s, theta rad/s)")
    max_accel: list = param([2.5, 0.0, 3.2], "largest acceleration, >= 0 (m/s², m/s², rad/s²)")
    max_decel: list = param([-2.5, 0.0, -3.2], "largest deceleration, <= 0 (m/s², m/s², rad/s²)")
    odom_topic: str = param("odom", "closed loop: nav_msgs/Odometry")
    odom_duration: float = param(0.1, "closed loop: odometry averaged over this long (s)")
    deadband_velocity: list = param([0.0, 0.0, 0.0], "output axes smaller than this are sent as zero")
    velocity_timeout: float = param(1.0, "a command this old (s) is replaced by a stop")
    enable_stamped_cmd_vel: bool = param(False, "input and output geometry_msgs/TwistStamped (else Twist)")

    def validate(self) -> None:
        try:
            feedback_of(self.feedback)
            VelocitySmoothing(self.limits(), self.velocity_timeout)
            if self.closed_loop():
                OdomAverage(self.odom_duration)
        except VelocitySmootherError as exc:
            name = exc.parameter or "velocity_smoother"
            raise ParameterError(name, getattr(self, name, ""), str(exc)) from exc
        if self.closed_loop() and not self.odom_topic:
            raise ParameterError("odom_topic", self.odom_topic, "closed loop needs an odometry topic")

    def closed_loop(self) -> bool:
        return self.feedback == Feedback.CLOSED_LOOP.value

    def limits(self) -> SmootherLimits:
        """Raises:
            VelocitySmootherError: a vector that is not three finite numbers.
        """
        return SmootherLimits(self.smoothing_frequency, vector3("max_velocity", self.max_velocity),
                              vector3("min_velocity", self.min_velocity), vector3("max_accel", self.max_accel),
                              vector3("max_decel", self.max_decel),
                              vector3("deadband_velocity", self.deadband_velocity), self.scale_velocities)


def _twist(msg: Any) -> Velocity3:
    """(vx, vy, wz) of a Twist or TwistStamped."""
    t = msg.twist if isinstance(msg, TwistStamped) else msg
    return float(t.linear.x), float(t.linear.y), float(t.angular.z)


#: What may change while the smoother runs (Nav2's dynamic parameters); the rest is read at configure.
LIVE = {"max_velocity", "min_velocity", "max_accel", "max_decel", "deadband_velocity", "velocity_timeout",
        "scale_velocities", "odom_duration"}


class VelocitySmoother(ManagedNode):
    """A lifecycle node, as Nav2's: smooths and publishes only while active."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("velocity_smoother", **kwargs)
        self._warn = Warnings(self)
        self.params: VelocitySmootherParameters | None = None
        self.smoothing: VelocitySmoothing | None = None
        self.odometry: OdomAverage | None = None
        self._endpoints: list[Any] = []
        self.timer: Any = None
        self._frame_id = ""  # of the last stamped command, for the stamped output
        self._output_s = -math.inf  # when the last output was computed (sim s)
        #: Commands received while not active: dropped, as by Nav2's inactive node.
        self.ignored_inactive = 0
        try:
            params = declare_parameters(self, VelocitySmootherParameters)
        except ParameterError:
            return  # declared all the same: configure reads them again and fails naming the bad one
        # Made now, not at configure, so that lockstep sees them from the start (see lifecycle).
        self._make_endpoints(params)
        serve_live_parameters(self, [LiveParameters(
            "", lambda: self.params, self._set_limits, LIVE, fixed_while=lambda: self.state != "unconfigured",
            why_not="it is read at configure: deactivate and clean up the node, set it, then configure it")])

    # ------------------------------------------------------------- lifecycle
    def _read_parameters(self) -> VelocitySmootherParameters:
        """Raises:
            ParameterError: naming the bad parameter.
        """
        names = [ros_name(f) for f in parameter_fields(VelocitySmootherParameters)]
        return from_values(VelocitySmootherParameters, {n: self.get_parameter(n).value for n in names})

    def configure(self) -> None:
        p = self._read_parameters()
        if p != self.params:
            self._make_endpoints(p)
        self.smoothing = VelocitySmoothing(p.limits(), p.velocity_timeout)
        self.odometry = OdomAverage(p.odom_duration) if p.closed_loop() else None
        self.get_logger().info(f"smoothing {self._input.topic_name} → {self.output.topic_name} at "
                               f"{p.smoothing_frequency:g} Hz, {p.feedback.lower().replace('_', ' ')}")

    def _set_limits(self, new: VelocitySmootherParameters) -> None:
        """Live limits (Nav2's dynamic parameters): the running smoothing takes them, its last
        output and command kept."""
        self.params = new
        if self.smoothing is not None:
            self.smoothing.limits = new.limits()
            self.smoothing.timeout_s = new.velocity_timeout
        if self.odometry is not None:
            self.odometry.window_s = new.odom_duration

    def activate(self) -> None:
        if self.smoothing is not None:
            self.smoothing.reset()

    def deactivate(self) -> None:
        if self.smoothing is not None:
            self.smoothing.reset()

    def cleanup(self) -> None:
        self.smoothing = self.odometry = None

    def _make_endpoints(self, p: VelocitySmootherParameters) -> None:
        """(Re)make the topics and the timer for ``p``."""
        for endpoint in self._endpoints:
            if hasattr(endpoint, "publish"):
                self.destroy_publisher(endpoint)
            else:
                self.destroy_subscription(endpoint)
        if self.timer is not None:
            self.destroy_step_timer(self.timer)
        self.params = p
        msg_type = TwistStamped if p.enable_stamped_cmd_vel else Twist
        self.msg_type = msg_type
        self.output = self.create_publisher(msg_type, "cmd_vel_smoothed", 1)
        self.port.require_match(self, self.output)
        # Handled at a step in lockstep: the command's time is the step's,
        # whichever side of the step message the command arrives on.
        self._input = self.create_subscription(msg_type, "cmd_vel", guarded(self, self._on_command, "command"), 1,
                                               data_path=True, at_step=True, needs_publisher=False)
        self._endpoints = [self.output, self._input]
        if p.closed_loop():
            odom = self.create_subscription(Odometry, p.odom_topic, guarded(self, self._on_odom, "Odometry"), 10,
                                            data_path=True, needs_publisher=False)
            self._endpoints.append(odom)
        # Runs from the start and is never stopped, as Nav2's: its periods keep one phase, so in
        # lockstep they fall on the same steps on every run (a timer restarted by the first command
        # would take that step's time as its phase).
        self._period_s = 1.0 / p.smoothing_frequency
        self.timer = self.step_timer(self._period_s, self.tick)

    # ---------------------------------------------------------------- inputs
    def _now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _on_command(self, msg: Any) -> None:
        if not self.active or self.smoothing is None:
            self.ignored_inactive += 1
            return
        if isinstance(msg, TwistStamped):
            self._frame_id = msg.header.frame_id
        now_s = self._now_s()
        try:
            self.smoothing.command(_twist(msg), now_s)
        except VelocitySmootherError as exc:
            self._warn("command", f"dropping a command: {exc}")
            return
        # A command is smoothed as it comes, the timer covering the gaps; at most one output per
        # instant: commands arriving faster than sim time moves (a wall-clock publisher in lockstep)
        # each replace the last, and the newest goes out at the next period, as with Nav2's timer.
        if now_s > self._output_s:
            self._output(now_s)

    def _on_odom(self, msg: Odometry) -> None:
        if self.odometry is not None:
            self.odometry.add(stamp_seconds(msg.header.stamp), _twist(msg.twist.twist))

    # ---------------------------------------------------------------- output
    def tick(self) -> None:
        """One smoothing period without a command: publish the next output (nothing while
        inactive, idle, or when a command was smoothed within the period)."""
        if self.smoothing is None or not self.active:
            return
        now_s = self._now_s()
        if now_s - self._output_s < self._period_s - 1e-9:
            return
        self._output(now_s)

    def _output(self, now_s: float) -> None:
        """Publish one smoothing period's output (none when idle)."""
        assert self.smoothing is not None
        measured = self.odometry.velocity() if self.odometry is not None else None
        out = self.smoothing.tick(now_s, measured)
        self._output_s = now_s
        if out is None:
            return
        msg = self.msg_type()
        twist = msg.twist if isinstance(msg, TwistStamped) else msg
        twist.linear.x, twist.linear.y, twist.angular.z = out
        if isinstance(msg, TwistStamped):
            msg.header.stamp = self.get_clock().now().to_msg()
            msg.header.frame_id = self._frame_id
        self.output.publish(msg)


def main(args: list[str] | None = None) -> int:
    return run_nodes([VelocitySmoother], "velocity_smoother", args)


if __name__ == "__main__":
    sys.exit(main())
