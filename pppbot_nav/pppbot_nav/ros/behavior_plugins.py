"""The behavior_server's plugins by Nav2's type name, on the cores of :mod:`pppbot_nav.behaviors`.

* ``nav2_behaviors::Spin`` (action ``Spin``): turn ``target_yaw`` (relative, signed) at up to the
  server's ``max_rotational_vel``, slowing with ``rotational_acc_lim`` near the end; feedback
  ``angular_distance_traveled``;
* ``nav2_behaviors::BackUp`` / ``nav2_behaviors::DriveOnHeading``: drive ``target.x`` metres
  along the heading at ``speed`` (backup: backwards, whatever the signs); ``target.y`` or
  ``target.z`` other than 0, or a drive_on_heading whose distance and speed differ in sign, is
  INVALID_INPUT; feedback ``distance_traveled``;
* ``nav2_behaviors::Wait``: stand still for ``time``; feedback ``time_left``;
* ``nav2_behaviors::AssistedTeleop``: forward the teleop commands on ``<name>.cmd_vel_teleop``
  scaled down by how soon they would collide (:func:`pppbot_nav.behaviors.assisted`) until a
  message on ``preempt_teleop`` (std_msgs/Empty: success), a cancel, or ``time_allowance`` runs
  out (TIMEOUT, as Nav2's).

Spin, backup and drive_on_heading stop with COLLISION_AHEAD where Nav2's collision check would
(:func:`pppbot_nav.behaviors.collision_ahead`); wait and assisted teleop check none. Each is
registered in the ``pppbot_nav.behaviors`` entry-point group (``pppbot_nav/setup.py``), as a
user's behaviour is (:mod:`pppbot_nav.ros.behavior_interface`).
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

from geometry_msgs.msg import Twist
from nav2_msgs.action import AssistedTeleop, BackUp, DriveOnHeading, Spin, Wait
from rclpy.duration import Duration
from std_msgs.msg import Empty

from pppbot_common.maps import OccupancyGrid
from pppbot_common.params import ParameterError, check_finite_range, param
from pppbot_lockstep.ros.runner import Warnings, guarded
from pppbot_nav import behaviors
from pppbot_nav.behaviors import Outcome, Pose, Velocity
from pppbot_nav.ros.behavior_interface import BehaviorContext, BehaviorRun, BehaviorSettings, InvalidInput

SPIN = "nav2_behaviors::Spin"
BACK_UP = "nav2_behaviors::BackUp"
DRIVE_ON_HEADING = "nav2_behaviors::DriveOnHeading"
WAIT = "nav2_behaviors::Wait"
ASSISTED_TELEOP = "nav2_behaviors::AssistedTeleop"

#: Nav2's default behaviour ids and their types: such a name without a ``plugin`` is that type.
DEFAULT_BEHAVIOR_TYPES = {"spin": SPIN, "backup": BACK_UP, "drive_on_heading": DRIVE_ON_HEADING,
                          "assisted_teleop": ASSISTED_TELEOP, "wait": WAIT}


def seconds(duration: Any) -> float:
    """A builtin_interfaces/Duration in seconds."""
    return float(duration.sec + duration.nanosec * 1e-9)


class CoreRun:
    """A goal carried out by a core of :mod:`pppbot_nav.behaviors`."""

    def __init__(self, core: behaviors.Behavior, settings: BehaviorSettings) -> None:
        self.core = core
        self.settings = settings

    def start(self, pose: Pose, now_s: float) -> None:
        self.core.start(pose, now_s)

    def step(self, pose: Pose, now_s: float) -> Velocity | Outcome:
        return self.core.step(pose, now_s)

    def collision_ahead(self, costmap: OccupancyGrid | None, pose: Pose, command: Velocity) -> str | None:
        return behaviors.collision_ahead(self.core, costmap, pose, command,
                                         simulate_ahead_time_s=self.settings.simulate_ahead_time_s,
                                         cycle_frequency_hz=self.settings.cycle_frequency_hz)

    def feedback(self, feedback: Any, elapsed_s: float) -> None:
        core = self.core
        if isinstance(core, behaviors.Spin):
            feedback.angular_distance_traveled = float(core.progress)
        elif isinstance(core, behaviors.DriveOnHeading):
            feedback.distance_traveled = float(core.progress)
        else:
            feedback.time_left = Duration(seconds=core.remaining).to_msg()


#: Makes a core from a goal, its time allowance (s), the behaviour's name and the server's settings.
CoreMaker = Callable[[Any, float, str, BehaviorSettings], behaviors.Behavior]


class CoreBehavior:
    """A behaviour whose goals are cores of :mod:`pppbot_nav.behaviors`, made by ``make_core``."""

    def __init__(self, context: BehaviorContext, make_core: CoreMaker) -> None:
        self.context = context
        self.make_core = make_core

    def begin(self, request: Any, time_allowance_s: float) -> BehaviorRun:
        """Raises: InvalidInput (from ``make_core``)."""
        settings = self.context.settings
        return CoreRun(self.make_core(request, time_allowance_s, self.context.name, settings), settings)


def spin_core(request: Any, time_allowance_s: float, name: str, s: BehaviorSettings) -> behaviors.Spin:
    return behaviors.Spin(float(request.target_yaw), s.max_rotational_vel, s.min_rotational_vel,
                          s.rotational_acc_lim, time_allowance_s)


def _drive(request: Any, time_allowance_s: float, name: str, backwards: bool) -> behaviors.DriveOnHeading:
    """Raises: InvalidInput (a sideways target, signs that differ, a zero or non-finite speed)."""
    target, speed = request.target, float(request.speed)
    if target.y != 0.0 or target.z != 0.0:
        raise InvalidInput(f"{name} drives along the heading only: target.y and target.z must be 0 "
                           f"(got {target.y:g}, {target.z:g})")
    core = behaviors.back_up(float(target.x), speed, time_allowance_s) if backwards \
        else behaviors.DriveOnHeading(float(target.x), speed, time_allowance_s)
    problem = behaviors.drive_on_heading_problem(core.distance_m, core.speed)
    if problem is not None:
        raise InvalidInput(problem)
    return core


def back_up_core(request: Any, time_allowance_s: float, name: str, s: BehaviorSettings) -> behaviors.DriveOnHeading:
    """Raises: InvalidInput (see :func:`_drive`)."""
    return _drive(request, time_allowance_s, name, backwards=True)


def drive_on_heading_core(request: Any, time_allowance_s: float, name: str,
                          s: BehaviorSettings) -> behaviors.DriveOnHeading:
    """Raises: InvalidInput (see :func:`_drive`)."""
    return _drive(request, time_allowance_s, name, backwards=False)


def wait_core(request: Any, time_allowance_s: float, name: str, s: BehaviorSettings) -> behaviors.Wait:
    return behaviors.Wait(seconds(request.time))


@dataclass(frozen=True)
class SpinPlugin:
    """``nav2_behaviors::Spin``: its settings are the server's (Nav2's node-level ones)."""

    ACTION: ClassVar[Any] = Spin

    def validate(self) -> None:
        """No parameters of its own."""

    def make(self, context: BehaviorContext) -> CoreBehavior:
        return CoreBehavior(context, spin_core)


@dataclass(frozen=True)
class BackUpPlugin:
    """``nav2_behaviors::BackUp``."""

    ACTION: ClassVar[Any] = BackUp

    def validate(self) -> None:
        """No parameters of its own."""

    def make(self, context: BehaviorContext) -> CoreBehavior:
        return CoreBehavior(context, back_up_core)


@dataclass(frozen=True)
class DriveOnHeadingPlugin:
    """``nav2_behaviors::DriveOnHeading``."""

    ACTION: ClassVar[Any] = DriveOnHeading

    def validate(self) -> None:
        """No parameters of its own."""

    def make(self, context: BehaviorContext) -> CoreBehavior:
        return CoreBehavior(context, drive_on_heading_core)


@dataclass(frozen=True)
class WaitPlugin:
    """``nav2_behaviors::Wait``."""

    ACTION: ClassVar[Any] = Wait

    def validate(self) -> None:
        """No parameters of its own."""

    def make(self, context: BehaviorContext) -> CoreBehavior:
        return CoreBehavior(context, wait_core)


@dataclass(frozen=True)
class AssistedTeleopPlugin:
    """``nav2_behaviors::AssistedTeleop``'s parameters, under its name."""

    ACTION: ClassVar[Any] = AssistedTeleop

    projection_time: float = param(1.0, "how far ahead a teleop command is projected (s)")
    simulation_time_step: float = param(0.1, "projection step (s)")
    cmd_vel_teleop: str = param("cmd_vel_teleop", "the teleop commands' topic")

    def validate(self) -> None:
        check_finite_range("projection_time", self.projection_time, 0.0, 60.0, low_open=True)
        check_finite_range("simulation_time_step", self.simulation_time_step, 0.0, self.projection_time,
                           low_open=True)
        if not self.cmd_vel_teleop:
            raise ParameterError("cmd_vel_teleop", self.cmd_vel_teleop, "must name a topic")

    def make(self, context: BehaviorContext) -> AssistedTeleopBehavior:
        return AssistedTeleopBehavior(self, context)


class AssistedTeleopRun:
    """One assisted teleop goal: the latest teleop command, scaled, until preempted or out of time."""

    def __init__(self, behavior: AssistedTeleopBehavior, time_allowance_s: float) -> None:
        self.behavior = behavior
        self.time_allowance_s = time_allowance_s
        self.start_s = 0.0
        self.preempted = False  # a message on preempt_teleop came during the goal

    def start(self, pose: Pose, now_s: float) -> None:
        self.start_s = now_s

    def step(self, pose: Pose, now_s: float) -> Velocity | Outcome:
        if self.preempted:
            return Outcome.DONE
        if now_s - self.start_s > self.time_allowance_s:
            return Outcome.TIMEOUT
        b = self.behavior
        return behaviors.assisted(b.teleop, pose, b.context.costmap(), projection_time_s=b.params.projection_time,
                                  simulation_time_step_s=b.params.simulation_time_step)

    def collision_ahead(self, costmap: OccupancyGrid | None, pose: Pose, command: Velocity) -> str | None:
        return None  # the command is already scaled down before a collision: it never stops the goal

    def feedback(self, feedback: Any, elapsed_s: float) -> None:
        feedback.current_teleop_duration = Duration(seconds=elapsed_s).to_msg()


class AssistedTeleopBehavior:
    """Nav2's assisted teleop: reads ``<name>.cmd_vel_teleop`` and ``preempt_teleop``."""

    def __init__(self, params: AssistedTeleopPlugin, context: BehaviorContext) -> None:
        self.params, self.context = params, context
        self.teleop: Velocity = (0.0, 0.0)
        self.run: AssistedTeleopRun | None = None  # the latest goal's
        node = context.node
        self._warn = Warnings(node)
        node.create_subscription(Twist, params.cmd_vel_teleop, guarded(node, self._on_teleop, "Twist"), 10,
                                 data_path=True, needs_publisher=False)
        node.create_subscription(Empty, "preempt_teleop", guarded(node, self._on_preempt, "Empty"), 10,
                                 data_path=True, needs_publisher=False)

    def begin(self, request: Any, time_allowance_s: float) -> AssistedTeleopRun:
        self.run = AssistedTeleopRun(self, time_allowance_s)
        return self.run

    def _on_teleop(self, msg: Twist) -> None:
        if not all(math.isfinite(v) for v in (msg.linear.x, msg.angular.z)):
            self._warn("teleop", f"a teleop command with a non-finite speed ({msg.linear.x}, {msg.angular.z}) "
                                 "dropped")
            return
        self.teleop = (msg.linear.x, msg.angular.z)

    def _on_preempt(self, msg: Empty) -> None:
        if self.run is not None:
            self.run.preempted = True
