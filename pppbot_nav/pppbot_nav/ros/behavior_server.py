"""``behavior_server``: Nav2's behaviours as actions: ``spin``, ``backup``, ``drive_on_heading``,
``wait`` and ``assisted_teleop`` (nav2_msgs/action/*, with their feedback and error codes).

A lifecycle node: goals only while active. One behaviour runs at a time (one robot, one
``cmd_vel``): a new goal of any behaviour ends the running one (aborted, "preempted"). Each
runs at ``cycle_frequency`` in sim time, commands ``cmd_vel`` (Jazzy's bringup remaps it to
``cmd_vel_nav``, into the velocity smoother) and stops the robot when it ends.

* ``spin``: turn ``target_yaw`` (relative, signed) at up to ``max_rotational_vel``, slowing with
  ``rotational_acc_lim`` near the end; feedback ``angular_distance_traveled``.
* ``backup`` / ``drive_on_heading``: drive ``target.x`` metres along the heading at ``speed``
  (backup: backwards, whatever the signs); ``target.y``/``target.z`` other than 0, or a
  drive_on_heading whose distance and speed differ in sign, is INVALID_INPUT; feedback
  ``distance_traveled``.
* ``wait``: stand still for ``time``; feedback ``time_left``.
* ``assisted_teleop``: forward the teleop commands on ``cmd_vel_teleop`` scaled down by how soon
  they would collide (:func:`pppbot_nav.behaviors.assisted`) until a message on
  ``preempt_teleop`` (std_msgs/Empty: success), a cancel, or ``time_allowance`` runs out (TIMEOUT,
  as Nav2's).

Spin, backup and drive_on_heading stop with COLLISION_AHEAD where Nav2's collision check would:
the command simulated ``simulate_ahead_time`` ahead on the local costmap (in ``local_frame``)
puts the footprint circle on an obstacle. Past ``time_allowance``: TIMEOUT. No robot pose in
``local_frame`` within ``transform_tolerance`` of the start: TF_ERROR.
"""
from __future__ import annotations

import math
import sys
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from geometry_msgs.msg import Twist
from nav2_msgs.action import AssistedTeleop, BackUp, DriveOnHeading, Spin, Wait
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from rclpy.action.server import ServerGoalHandle
from rclpy.duration import Duration
from std_msgs.msg import Empty

from pppbot_common.params import ParameterError, check_finite_range, param
from pppbot_common.ros.maps import grid_from_message
from pppbot_common.ros.params import declare_parameters, fixed_parameters
from pppbot_common.ros.qos import LATCHED
from pppbot_common.transforms import TransformError
from pppbot_lockstep.ros.goals import GoalEnd, GoalServer, send_feedback, stopped_end
from pppbot_lockstep.ros.lifecycle import ManagedNode
from pppbot_lockstep.ros.runner import Warnings, guarded, run_nodes
from pppbot_lockstep.ros.tf_listener import TfListener
from pppbot_nav import behaviors
from pppbot_nav.behaviors import Behavior, Outcome
from pppbot_nav.ros.plugins import plugin_type

#: Nav2's behaviour plugins, by the names its bringup gives them, and their action types.
BEHAVIORS: dict[str, Any] = {"spin": Spin, "backup": BackUp, "drive_on_heading": DriveOnHeading,
                             "assisted_teleop": AssistedTeleop, "wait": Wait}
#: Nav2's behaviour plugin types and the behaviour each is; a behaviour named as one of
#: BEHAVIORS without a ``plugin`` is that one (Nav2's default ids).
BEHAVIOR_TYPES = {"nav2_behaviors::Spin": "spin", "nav2_behaviors::BackUp": "backup",
                  "nav2_behaviors::DriveOnHeading": "drive_on_heading",
                  "nav2_behaviors::AssistedTeleop": "assisted_teleop", "nav2_behaviors::Wait": "wait"}
DEFAULT_BEHAVIOR_TYPES = {kind: type_name for type_name, kind in BEHAVIOR_TYPES.items()}


@dataclass(frozen=True)
class BehaviorServerParameters:
    behavior_plugins: list = param(list(BEHAVIORS), "the behaviours served, each an action of its name; its "
                                                    "type is its <name>.plugin (nav2_behaviors::Spin, ...)")
    local_costmap_topic: str = param("local_costmap/costmap", "the local costmap (nav_msgs/OccupancyGrid) the "
                                     "collision checks read (Nav2: local_costmap/costmap_raw)")
    cycle_frequency: float = param(10.0, "behaviour steps per second (Hz, sim time)")
    local_frame: str = param("odom", "the frame behaviours measure the robot's motion in")
    global_frame: str = param("map", "the global frame (for Nav2's parameter set; unused by these behaviours)")
    robot_base_frame: str = param("base_link", "the robot's frame")
    transform_tolerance: float = param(0.1, "how long a behaviour waits for the robot's pose at its start (s)")
    simulate_ahead_time: float = param(2.0, "how far ahead a command is checked for collisions (s)")
    max_rotational_vel: float = param(1.0, "spin: top speed (rad/s)")
    min_rotational_vel: float = param(0.4, "spin: lowest speed (rad/s)")
    rotational_acc_lim: float = param(3.2, "spin: deceleration towards the target (rad/s²)")
    projection_time: float = param(1.0, "assisted_teleop: how far ahead a teleop command is projected (s)",
                                   "assisted_teleop.projection_time")
    simulation_time_step: float = param(0.1, "assisted_teleop: projection step (s)",
                                        "assisted_teleop.simulation_time_step")
    cmd_vel_teleop: str = param("cmd_vel_teleop", "assisted_teleop: the teleop commands' topic",
                                "assisted_teleop.cmd_vel_teleop")

    def validate(self) -> None:
        if not self.behavior_plugins or len(set(self.behavior_plugins)) != len(self.behavior_plugins):
            raise ParameterError("behavior_plugins", self.behavior_plugins, "must name behaviours, each once")
        check_finite_range("cycle_frequency", self.cycle_frequency, 0.0, 1000.0, low_open=True)
        check_finite_range("transform_tolerance", self.transform_tolerance, 0.0, 60.0)
        check_finite_range("simulate_ahead_time", self.simulate_ahead_time, 0.0, 60.0)
        check_finite_range("max_rotational_vel", self.max_rotational_vel, 0.0, 100.0, low_open=True)
        check_finite_range("min_rotational_vel", self.min_rotational_vel, 0.0, self.max_rotational_vel)
        check_finite_range("rotational_acc_lim", self.rotational_acc_lim, 0.0, 1000.0, low_open=True)
        check_finite_range("projection_time", self.projection_time, 0.0, 60.0, low_open=True)
        check_finite_range("simulation_time_step", self.simulation_time_step, 0.0, self.projection_time,
                           low_open=True)
        if not self.cmd_vel_teleop:
            raise ParameterError("assisted_teleop.cmd_vel_teleop", self.cmd_vel_teleop, "must name a topic")


def seconds(duration: Any) -> float:
    return duration.sec + duration.nanosec * 1e-9


class _InvalidInput(Exception):  # noqa: N818 (a request refused, Nav2's INVALID_INPUT)
    """A request the behaviour cannot carry out as given."""


class _Running:
    """The behaviour being carried out: its goal, name, core (None: assisted teleop) and start."""

    def __init__(self, handle: ServerGoalHandle, name: str, core: Behavior | None, start_s: float,
                 time_allowance_s: float) -> None:
        self.handle, self.name, self.core = handle, name, core
        self.start_s, self.time_allowance_s = start_s, time_allowance_s
        self.started = False  # the core has the start pose
        self.preempt_teleop = False


class BehaviorServer(ManagedNode):
    """Nav2's ``behavior_server`` (see the module docstring)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("behavior_server", **kwargs)
        self.params = p = declare_parameters(self, BehaviorServerParameters)
        self.parameter_notes = {
            "costmap_topic": "Humble's name: the collision checks read local_costmap_topic (Jazzy's)",
            "footprint_topic": "the footprint is a circle of the costmap's robot_radius",
            "local_footprint_topic": "the footprint is a circle of the costmap's robot_radius",
            "global_footprint_topic": "the footprint is a circle of the costmap's robot_radius",
            "global_costmap_topic": "no behaviour here checks the global costmap",
            "use_sim_time": ""}
        fixed_parameters(self, lambda: self.params)  # Nav2's has no dynamic parameters
        self._warn = Warnings(self)
        self.tf = TfListener(self, self._warn).buffer
        self.cmd_pub = self.create_publisher(Twist, "cmd_vel", 1)
        self.port.require_match(self, self.cmd_pub)
        self._costmap: OccupancyGridMsg | None = None
        self.create_subscription(OccupancyGridMsg, p.local_costmap_topic,
                                 guarded(self, self._on_costmap, "OccupancyGrid"), LATCHED, data_path=True,
                                 needs_publisher=False)
        self._teleop = Twist()
        self.create_subscription(Twist, p.cmd_vel_teleop, guarded(self, self._on_teleop, "Twist"), 10, data_path=True,
                                 needs_publisher=False)
        self.create_subscription(Empty, "preempt_teleop", guarded(self, self._on_preempt, "Empty"), 10,
                                 data_path=True, needs_publisher=False)
        self._running: _Running | None = None
        #: Each served name's behaviour (a key of BEHAVIORS), from its <name>.plugin.
        self.kinds = {name: BEHAVIOR_TYPES[plugin_type(self, name, BEHAVIOR_TYPES, DEFAULT_BEHAVIOR_TYPES.get(name))]
                      for name in p.behavior_plugins}
        self.servers = {name: GoalServer(self, BEHAVIORS[kind], name, self._starter(name), accept=self.taking_goals)
                        for name, kind in self.kinds.items()}
        self.timer = self.step_timer(1.0 / p.cycle_frequency, self._cycle)
        self.timer.cancel()
        self.get_logger().info(f"behaviours: {', '.join(p.behavior_plugins)} once active")

    def destroy_node(self) -> None:
        for server in self.servers.values():
            server.destroy()
        super().destroy_node()

    def deactivate(self) -> None:
        if self._running is not None:
            self._end(self._running, GoalEnd.ABORTED, 0, "the behavior_server was deactivated")

    # ----------------------------------------------------------------- inputs
    def _on_costmap(self, msg: OccupancyGridMsg) -> None:
        self._costmap = msg

    def _on_teleop(self, msg: Twist) -> None:
        if not all(math.isfinite(v) for v in (msg.linear.x, msg.angular.z)):
            self._warn("teleop", f"a teleop command with a non-finite speed ({msg.linear.x}, {msg.angular.z}) "
                                 "dropped")
            return
        self._teleop = msg

    def _on_preempt(self, msg: Empty) -> None:
        if self._running is not None and self.kinds[self._running.name] == "assisted_teleop":
            self._running.preempt_teleop = True

    # ------------------------------------------------------------------ goals
    def _starter(self, name: str) -> Callable[[ServerGoalHandle], None]:
        return lambda handle: self._start(name, handle)

    def _now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _start(self, name: str, handle: ServerGoalHandle) -> None:
        previous = self._running
        if previous is not None:
            self._end(previous, GoalEnd.ABORTED, 0, f"preempted by a {name} goal", stop=False)
        request = handle.request
        allowance = seconds(request.time_allowance) if hasattr(request, "time_allowance") else math.inf
        running = _Running(handle, name, None, self._now_s(), allowance)
        try:
            running.core = self._core(name, request, allowance)
        except _InvalidInput as exc:
            self._end(running, GoalEnd.ABORTED, BEHAVIORS[self.kinds[name]].Result.INVALID_INPUT, str(exc),
                      stop=False)
            return
        self._running = running
        self.get_logger().info(f"{name} started")
        self.timer.reset()
        self._cycle()

    def _core(self, name: str, request: Any, allowance_s: float) -> Behavior | None:
        """The behaviour a request asks for (None: assisted teleop).

        Raises:
            _InvalidInput: a backup or drive_on_heading request Nav2 refuses with INVALID_INPUT.
        """
        p = self.params
        kind = self.kinds[name]
        if kind == "spin":
            return behaviors.Spin(float(request.target_yaw), p.max_rotational_vel, p.min_rotational_vel,
                                  p.rotational_acc_lim, allowance_s)
        if kind == "wait":
            return behaviors.Wait(seconds(request.time))
        if kind == "assisted_teleop":
            return None
        target, speed = request.target, float(request.speed)
        if target.y != 0.0 or target.z != 0.0:
            raise _InvalidInput(f"{name} drives along the heading only: target.y and target.z must be 0 "
                                f"(got {target.y:g}, {target.z:g})")
        core = behaviors.back_up(float(target.x), speed, allowance_s) if kind == "backup" \
            else behaviors.DriveOnHeading(float(target.x), speed, allowance_s)
        problem = behaviors.drive_on_heading_problem(core.distance_m, core.speed)
        if problem is not None:
            raise _InvalidInput(problem)
        return core

    def _end(self, running: _Running, end: GoalEnd, code: int, message: str, stop: bool = True) -> None:
        if self._running is running:
            self._running = None
            self.timer.cancel()
        if stop:
            self.cmd_pub.publish(Twist())
        handle = running.handle
        if end is GoalEnd.ABORTED:
            end = stopped_end(handle) if handle.is_cancel_requested else GoalEnd.ABORTED
        result = BEHAVIORS[self.kinds[running.name]].Result()
        result.error_code, result.error_msg = code, message
        result.total_elapsed_time = Duration(seconds=max(0.0, self._now_s() - running.start_s)).to_msg()
        if end is GoalEnd.ABORTED and message:
            self.get_logger().warning(f"{running.name} failed: {message}")
        elif end is GoalEnd.SUCCEEDED:
            self.get_logger().info(f"{running.name} done{f': {message}' if message else ''}")
        self.servers[running.name].finish(handle, end, result)

    # ------------------------------------------------------------------- loop
    def _cycle(self) -> None:
        running = self._running
        if running is None:
            self.timer.cancel()
            return
        try:
            self._step(running)
        except Exception as exc:  # a bug must end the goal, not the server
            self._end(running, GoalEnd.ABORTED, 0, f"{type(exc).__name__}: {exc}")

    def _step(self, running: _Running) -> None:
        action = BEHAVIORS[self.kinds[running.name]]
        codes = action.Result
        now = self._now_s()
        if running.handle.is_cancel_requested:
            self._end(running, GoalEnd.CANCELED, 0, f"{running.name} canceled")
            return
        try:
            pose = self.tf.lookup(self.params.local_frame, self.params.robot_base_frame)
        except TransformError as exc:
            if now - running.start_s > self.params.transform_tolerance:
                self._end(running, GoalEnd.ABORTED, getattr(codes, "TF_ERROR", 0),
                          f"no robot pose in '{self.params.local_frame}': {exc}")
            return
        if running.core is None:
            self._assist(running, pose, now)
            return
        if not running.started:
            running.core.start(pose, now)
            running.started = True
        command = running.core.step(pose, now)
        if command is Outcome.DONE:
            self._end(running, GoalEnd.SUCCEEDED, 0, "")
            return
        if command is Outcome.TIMEOUT:
            self._end(running, GoalEnd.ABORTED, getattr(codes, "TIMEOUT", 0),
                      f"{running.name} exceeded its time allowance of {running.time_allowance_s:g} s")
            return
        assert not isinstance(command, Outcome)
        costmap = grid_from_message(self._costmap) if self._costmap is not None else None
        collision = behaviors.collision_ahead(running.core, costmap, pose, command,
                                              simulate_ahead_time_s=self.params.simulate_ahead_time,
                                              cycle_frequency_hz=self.params.cycle_frequency)
        if collision is not None:
            self._end(running, GoalEnd.ABORTED, getattr(codes, "COLLISION_AHEAD", 0), collision)
            return
        twist = Twist()
        twist.linear.x, twist.angular.z = command
        self.cmd_pub.publish(twist)
        self._feedback(running, now)

    def _assist(self, running: _Running, pose: tuple[float, float, float], now: float) -> None:
        """One cycle of assisted teleop."""
        if running.preempt_teleop:
            self._end(running, GoalEnd.SUCCEEDED, 0, "preempted on preempt_teleop")
            return
        if now - running.start_s > running.time_allowance_s:
            self._end(running, GoalEnd.ABORTED, AssistedTeleop.Result.TIMEOUT,
                      f"assisted_teleop exceeded its time allowance of {running.time_allowance_s:g} s")
            return
        costmap = grid_from_message(self._costmap) if self._costmap is not None else None
        v, w = behaviors.assisted((self._teleop.linear.x, self._teleop.angular.z), pose, costmap,
                                  projection_time_s=self.params.projection_time,
                                  simulation_time_step_s=self.params.simulation_time_step)
        twist = Twist()
        twist.linear.x, twist.angular.z = v, w
        self.cmd_pub.publish(twist)
        self._feedback(running, now)

    def _feedback(self, running: _Running, now: float) -> None:
        action = BEHAVIORS[self.kinds[running.name]]
        fb = action.Feedback()
        core = running.core
        if isinstance(core, behaviors.Spin):
            fb.angular_distance_traveled = float(core.progress)
        elif isinstance(core, behaviors.DriveOnHeading):
            fb.distance_traveled = float(core.progress)
        elif isinstance(core, behaviors.Wait):
            fb.time_left = Duration(seconds=core.remaining).to_msg()
        else:
            fb.current_teleop_duration = Duration(seconds=max(0.0, now - running.start_s)).to_msg()
        send_feedback(self.port, running.handle, fb)


def main(args: list[str] | None = None) -> int:
    return run_nodes([BehaviorServer], "behavior_server", args)


if __name__ == "__main__":
    sys.exit(main())
