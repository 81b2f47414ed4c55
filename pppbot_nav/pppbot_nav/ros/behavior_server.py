"""``behavior_server``: Nav2's behaviours as actions, each a plugin by type: by default ``spin``,
``backup``, ``drive_on_heading``, ``assisted_teleop`` and ``wait`` (nav2_msgs/action/*, with their
feedback and error codes; :mod:`pppbot_nav.ros.behavior_plugins`).

Behaviours are Nav2's plugins by type, found in the ``pppbot_nav.behaviors`` entry-point group
(pppbot's own, ``nav2_behaviors::Spin``, ``BackUp``, ``DriveOnHeading``, ``Wait`` and
``AssistedTeleop``; a user's from their package: :mod:`pppbot_nav.ros.behavior_interface`):
each name of ``behavior_plugins`` is loaded as its ``<name>.plugin`` says (one of Nav2's default
ids without one: its Nav2 type), its parameters under ``<name>.``, and served as an action of
that name. A type no installed package exports stops the node, naming the group and what is
installed in it.

A lifecycle node: goals only while active. One behaviour runs at a time (one robot, one
``cmd_vel``): a new goal of any behaviour ends the running one (aborted, "preempted"). Each
runs at ``cycle_frequency`` in sim time, commands ``cmd_vel`` (Jazzy's bringup remaps it to
``cmd_vel_nav``, into the velocity smoother) and stops the robot when it ends. A command the
behaviour's collision check refuses (Nav2's: simulated ``simulate_ahead_time`` ahead on the
local costmap, in ``local_frame``) ends it with COLLISION_AHEAD. Past ``time_allowance``:
TIMEOUT. No robot pose in ``local_frame`` within ``transform_tolerance`` of the start: TF_ERROR.
A goal the behaviour refuses: INVALID_INPUT.
"""
from __future__ import annotations

import math
import sys
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import Any

from geometry_msgs.msg import Twist
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from rclpy.action.server import ServerGoalHandle
from rclpy.duration import Duration

from pppbot_common.maps import OccupancyGrid
from pppbot_common.params import ParameterError, check_finite_range, param
from pppbot_common.ros.maps import grid_from_message
from pppbot_common.ros.params import LiveParameters, declare_parameters, refuse_sets, serve_live_parameters
from pppbot_common.ros.qos import LATCHED
from pppbot_common.transforms import TransformError
from pppbot_lockstep.ros.goals import GoalEnd, GoalServer, send_feedback, stopped_end
from pppbot_lockstep.ros.lifecycle import ManagedNode
from pppbot_lockstep.ros.runner import Warnings, guarded, run_nodes
from pppbot_lockstep.ros.tf_listener import TfListener
from pppbot_nav.behaviors import Outcome
from pppbot_nav.plugins import plugins
from pppbot_nav.ros.behavior_interface import (
    Behavior,
    BehaviorContext,
    BehaviorRun,
    BehaviorSettings,
    InvalidInput,
)
from pppbot_nav.ros.behavior_plugins import DEFAULT_BEHAVIOR_TYPES, seconds
from pppbot_nav.ros.plugins import Plugin, load_plugin


@dataclass(frozen=True)
class BehaviorServerParameters:
    behavior_plugins: list = param(list(DEFAULT_BEHAVIOR_TYPES), "the behaviours served, each an action of its "
                                   "name; its type is its <name>.plugin (nav2_behaviors::Spin, ...)")
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

    def validate(self) -> None:
        if not self.behavior_plugins or len(set(self.behavior_plugins)) != len(self.behavior_plugins):
            raise ParameterError("behavior_plugins", self.behavior_plugins, "must name behaviours, each once")
        if not all(isinstance(name, str) and name for name in self.behavior_plugins):
            raise ParameterError("behavior_plugins", self.behavior_plugins, "must be names (strings)")
        check_finite_range("cycle_frequency", self.cycle_frequency, 0.0, 1000.0, low_open=True)
        check_finite_range("transform_tolerance", self.transform_tolerance, 0.0, 60.0)
        check_finite_range("simulate_ahead_time", self.simulate_ahead_time, 0.0, 60.0)
        check_finite_range("max_rotational_vel", self.max_rotational_vel, 0.0, 100.0, low_open=True)
        check_finite_range("min_rotational_vel", self.min_rotational_vel, 0.0, self.max_rotational_vel)
        check_finite_range("rotational_acc_lim", self.rotational_acc_lim, 0.0, 1000.0, low_open=True)

    def settings(self) -> BehaviorSettings:
        return BehaviorSettings(self.cycle_frequency, self.simulate_ahead_time, self.max_rotational_vel,
                                self.min_rotational_vel, self.rotational_acc_lim)


class _Running:
    """The goal being carried out: its handle, behaviour name, run and start."""

    def __init__(self, handle: ServerGoalHandle, name: str, start_s: float, time_allowance_s: float) -> None:
        self.handle, self.name = handle, name
        self.start_s, self.time_allowance_s = start_s, time_allowance_s
        self.run: BehaviorRun | None = None  # None: the behaviour refused the goal
        self.started = False  # the run has the start pose


def _params_of(plugin: Plugin) -> Any:
    return plugin.params


def _keep(_: Any) -> None:
    """Nothing to apply: every parameter of the server and its behaviours is fixed while it runs."""


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
        #: Each served name's type and parameters, from its <name>.plugin.
        self.plugins = {name: load_plugin(self, name, plugins("behavior"), DEFAULT_BEHAVIOR_TYPES.get(name))
                        for name in p.behavior_plugins}
        # Nav2's has no dynamic parameters: each group is refused whole.
        serve_live_parameters(self, [LiveParameters("", lambda: self.params, _keep, ()),
                                     *(LiveParameters(f"{name}.", partial(_params_of, plugin), _keep, ())
                                       for name, plugin in self.plugins.items())])
        types = {f"{name}.plugin" for name in p.behavior_plugins}
        refuse_sets(self, "a behaviour's type is read once, at start-up (as in Nav2); restart the node to change it",
                    allowed=lambda key: key not in types)
        self._warn = Warnings(self)
        self.tf = TfListener(self, self._warn).buffer
        self.cmd_pub = self.create_publisher(Twist, "cmd_vel", 1)
        self.port.require_match(self, self.cmd_pub)
        self._costmap: OccupancyGrid | None = None
        self.create_subscription(OccupancyGridMsg, p.local_costmap_topic,
                                 guarded(self, self._on_costmap, "OccupancyGrid"), LATCHED, data_path=True,
                                 needs_publisher=False)
        self._running: _Running | None = None
        settings = p.settings()
        #: Each served name's behaviour and the action type it serves.
        self.behaviors: dict[str, Behavior] = {
            name: plugin.params.make(BehaviorContext(self, name, settings, self._latest_costmap))
            for name, plugin in self.plugins.items()}
        self.actions: dict[str, Any] = {name: type(plugin.params).ACTION for name, plugin in self.plugins.items()}
        self.servers = {name: GoalServer(self, action, name, self._starter(name), accept=self.taking_goals)
                        for name, action in self.actions.items()}
        self.timer = self.step_timer(1.0 / p.cycle_frequency, self._cycle)
        self.timer.cancel()
        kinds = ", ".join(f"'{name}' ({plugin.type_name})" for name, plugin in self.plugins.items())
        self.get_logger().info(f"behaviours {kinds} once active")

    def destroy_node(self) -> None:
        for server in self.servers.values():
            server.destroy()
        super().destroy_node()

    def deactivate(self) -> None:
        if self._running is not None:
            self._end(self._running, GoalEnd.ABORTED, 0, "the behavior_server was deactivated")

    # ----------------------------------------------------------------- inputs
    def _on_costmap(self, msg: OccupancyGridMsg) -> None:
        self._costmap = grid_from_message(msg)

    def _latest_costmap(self) -> OccupancyGrid | None:
        return self._costmap

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
        running = _Running(handle, name, self._now_s(), allowance)
        try:
            running.run = self.behaviors[name].begin(request, allowance)
        except InvalidInput as exc:
            codes = self.actions[name].Result
            self._end(running, GoalEnd.ABORTED, getattr(codes, "INVALID_INPUT", getattr(codes, "UNKNOWN", 0)),
                      str(exc), stop=False)
            return
        self._running = running
        self.get_logger().info(f"{name} started")
        self.timer.reset()
        self._cycle()

    def _end(self, running: _Running, end: GoalEnd, code: int, message: str, stop: bool = True) -> None:
        if self._running is running:
            self._running = None
            self.timer.cancel()
        if stop:
            self.cmd_pub.publish(Twist())
        handle = running.handle
        if end is GoalEnd.ABORTED:
            end = stopped_end(handle) if handle.is_cancel_requested else GoalEnd.ABORTED
        result = self.actions[running.name].Result()
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
        codes = self.actions[running.name].Result
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
        run = running.run
        assert run is not None
        if not running.started:
            run.start(pose, now)
            running.started = True
        command = run.step(pose, now)
        if command is Outcome.DONE:
            self._end(running, GoalEnd.SUCCEEDED, 0, "")
            return
        if command is Outcome.TIMEOUT:
            self._end(running, GoalEnd.ABORTED, getattr(codes, "TIMEOUT", 0),
                      f"{running.name} exceeded its time allowance of {running.time_allowance_s:g} s")
            return
        assert not isinstance(command, Outcome)
        collision = run.collision_ahead(self._costmap, pose, command)
        if collision is not None:
            self._end(running, GoalEnd.ABORTED, getattr(codes, "COLLISION_AHEAD", 0), collision)
            return
        twist = Twist()
        twist.linear.x, twist.angular.z = command
        self.cmd_pub.publish(twist)
        fb = self.actions[running.name].Feedback()
        run.feedback(fb, max(0.0, now - running.start_s))
        send_feedback(self.port, running.handle, fb)


def main(args: list[str] | None = None) -> int:
    return run_nodes([BehaviorServer], "behavior_server", args)


if __name__ == "__main__":
    sys.exit(main())
