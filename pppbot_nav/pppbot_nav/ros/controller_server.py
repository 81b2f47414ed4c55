"""``controller_server``: follows paths, in Nav2's ``controller_server`` place.

Runs the ``local_costmap`` (:mod:`pppbot_nav.ros.costmap_node`, rolling in ``odom``) in the same
process, as Nav2 does. Its plugins are Nav2's, by type (:mod:`pppbot_nav.controller.plugin_settings`):
``controller_plugins`` (``dwb_core::DWBLocalPlanner``, Nav2's default for ``FollowPath``, or
``nav2_regulated_pure_pursuit_controller::RegulatedPurePursuitController``),
``goal_checker_plugins`` and ``progress_checker_plugins`` (or Humble's one
``progress_checker_plugin``), each named plugin's parameters under its name. Serves
``follow_path`` (nav2_msgs/action/FollowPath; its ``controller_id``, ``goal_checker_id`` and
``progress_checker_id`` pick the plugins, empty the only one): at ``controller_frequency``
(sim time) it places the path in the local costmap's frame (TF), computes the command, publishes
it on ``cmd_vel`` (geometry_msgs/Twist) and the part of the path it follows on ``local_plan``,
and gives feedback (distance to goal, speed). The goal checker ends the goal with success; the
progress checker fails it with FAILED_TO_MAKE_PROGRESS; no command for longer than
``failure_tolerance`` fails it with NO_VALID_CONTROL. These per-period decisions are
:class:`pppbot_nav.controller.follow.Follower`'s (no ROS, unit-tested). A new path preempts the
one being followed and keeps the progress checker's history, as Nav2's path updates do. The
robot is stopped whenever a goal ends (``publish_zero_velocity``).

Live parameters: the server's thresholds, ``failure_tolerance`` and ``controller_frequency``,
every parameter of RPP and of the checkers, DWB's kinematic limits; each applies to the running
plugin (its path progress, the goal checker's latch and the progress baseline stay). The rest is
refused with the reason.
"""
from __future__ import annotations

import dataclasses
import math
import sys
from dataclasses import dataclass
from typing import Any

import numpy as np
from geometry_msgs.msg import Twist
from nav2_msgs.action import FollowPath
from nav2_msgs.msg import SpeedLimit as SpeedLimitMsg
from nav_msgs.msg import Odometry, Path
from rclpy.action.server import ServerGoalHandle

from pppbot_common.params import ParameterError, check_finite_range, param
from pppbot_common.ros.params import LiveParameters, declare_parameters, serve_live_parameters
from pppbot_common.se2 import yaw_from_quaternion
from pppbot_common.transforms import TransformError, compose
from pppbot_lockstep.ros.goals import GoalEnd, GoalServer, Stopped, check_running, send_feedback, stopped_end
from pppbot_lockstep.ros.lifecycle import ManagedNode
from pppbot_lockstep.ros.runner import Warnings, guarded, run_nodes
from pppbot_nav.controller.dwb_critic_plugins import critic_type
from pppbot_nav.controller.follow import FollowEnd, Follower
from pppbot_nav.controller.plugin_settings import DEFAULT_CHECKER_TYPES, DEFAULT_CONTROLLER_TYPES
from pppbot_nav.costmap.filters import NO_SPEED_LIMIT, SpeedLimit, limited
from pppbot_nav.errors import ControllerError
from pppbot_nav.plugins import PluginGroup, plugins
from pppbot_nav.ros.costmap_node import CostmapNode
from pppbot_nav.ros.planner_server import path_message
from pppbot_nav.ros.plugins import Plugin, live_plugin_parameters, load_plugin, plugin_class

Result = FollowPath.Result


def top_speed(controller: Any) -> float:
    """A controller's top forward speed (m/s), what a speed limit in % is of: RPP's
    ``desired_linear_vel``, DWB's ``max_vel_x``, or a plugin's ``top_speed_mps``."""
    own = getattr(controller, "top_speed_mps", None)
    if own is not None:
        return float(own)
    settings = getattr(controller, "settings", None)
    for name in ("desired_linear_vel", "max_vel_x"):
        if hasattr(settings, name):
            return float(getattr(settings, name))
    return math.inf

#: Nav2 keys that mean nothing here, with the reason (named in the start-up warning when given).
NO_EFFECT = {
    "*.debug_trajectory_details": "pppbot's DWB publishes no trajectory evaluation",
    "*.transform_tolerance": "the controller follows with the newest transform",
    "*.stateful": "DWB has no such parameter (the goal checker's 'stateful' is)",
    "*.publish_cost_grid_pc": "pppbot's DWB publishes no cost grid",
    "*.publish_evaluation": "pppbot's DWB publishes no trajectory evaluation",
    "*.publish_trajectories": "pppbot's DWB publishes no trajectories",
    "*.publish_local_plan": "the local plan is always published (local_plan)",
    "*.publish_global_plan": "the global plan is the planner's (plan)",
    "*.publish_transformed_plan": "the transformed plan is not published",
    "use_realtime_priority": "pppbot's nodes run at normal priority",
    "costmap_update_timeout": "the controller uses the local costmap as it is",
    "enable_stamped_cmd_vel": "the controller's commands are geometry_msgs/Twist (ppp_bot's, Nav2's default)",
    "use_sim_time": "",
}
#: What the server itself may change at run time (Nav2's, and controller_frequency).
LIVE_SERVER = {"controller_frequency", "failure_tolerance", "min_x_velocity_threshold",
               "min_y_velocity_threshold", "min_theta_velocity_threshold"}


@dataclass(frozen=True)
class ControllerServerParameters:
    controller_frequency: float = param(20.0, "control periods per second (Hz, sim time)")
    controller_plugins: list = param(["FollowPath"], "controller names; each's type is its <name>.plugin")
    goal_checker_plugins: list = param(["goal_checker"], "goal checker names; each's type is its <name>.plugin")
    progress_checker_plugins: list = param(["progress_checker"], "progress checker names (Jazzy)")
    progress_checker_plugin: str = param("", "one progress checker's name (Humble's key; wins when given)")
    odom_topic: str = param("odom", "odometry: the robot's current speed")
    speed_limit_topic: str = param("speed_limit", "speed limits (nav2_msgs/SpeedLimit, a costmap's SpeedFilter's): "
                                                  "each command is capped by the newest")
    failure_tolerance: float = param(0.3, "how long the controller may fail before the goal does (s; "
                                          "ppp_bot's 0.3, Nav2's default 0)")
    min_x_velocity_threshold: float = param(0.0001, "odometry speeds below this count as 0 (m/s)")
    min_y_velocity_threshold: float = param(0.0001, "(a differential drive has no y speed)")
    min_theta_velocity_threshold: float = param(0.0001, "odometry turn rates below this count as 0 (rad/s)")
    publish_zero_velocity: bool = param(True, "send a zero command when a goal ends")

    def validate(self) -> None:
        check_finite_range("controller_frequency", self.controller_frequency, 0.0, 1000.0, low_open=True)
        check_finite_range("failure_tolerance", self.failure_tolerance, -1.0, 3600.0)
        for name in ("min_x_velocity_threshold", "min_y_velocity_threshold", "min_theta_velocity_threshold"):
            check_finite_range(name, getattr(self, name), 0.0, 100.0)
        for name in ("controller_plugins", "goal_checker_plugins", "progress_checker_plugins"):
            names = getattr(self, name)
            if (not names and name != "progress_checker_plugins") or len(set(names)) != len(names):
                raise ParameterError(name, names, "must name at least one plugin, each once")
        if not self.progress_checkers():
            raise ParameterError("progress_checker_plugins", self.progress_checker_plugins, "must name one at least")

    def progress_checkers(self) -> list[str]:
        return [self.progress_checker_plugin] if self.progress_checker_plugin else list(self.progress_checker_plugins)


#: How each way a follow ends is answered (nav2_msgs/action/FollowPath result codes).
RESULT_CODES = {FollowEnd.SUCCEEDED: Result.NONE, FollowEnd.TF_ERROR: Result.TF_ERROR,
                FollowEnd.FAILED_TO_MAKE_PROGRESS: Result.FAILED_TO_MAKE_PROGRESS,
                FollowEnd.NO_VALID_CONTROL: Result.NO_VALID_CONTROL}


class _Following:
    """The goal being followed: its path (in its own frame), goal pose and its follow policy."""

    def __init__(self, handle: ServerGoalHandle, path3: np.ndarray, path_frame: str,
                 goal: tuple[float, float, float], follower: Follower) -> None:
        self.handle = handle
        self.path3 = path3
        self.path_frame = path_frame
        self.goal = goal
        self.follower = follower


class ControllerServer(ManagedNode):
    """A lifecycle node, as Nav2's: it follows paths only while active."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("controller_server", **kwargs)
        self.params = p = declare_parameters(self, ControllerServerParameters)
        self.parameter_notes = NO_EFFECT
        self.costmap_node = CostmapNode("local_costmap", port=self.port)
        self.composed_nodes = [self.costmap_node]
        self.plugins: dict[str, Plugin] = {}
        self.critic_plugins: dict[str, Plugin] = {}  # a DWB-like controller's critics, by <controller>.<critic>
        self.controllers = self._load(p.controller_plugins, plugins("controller"), DEFAULT_CONTROLLER_TYPES)
        self.goal_checkers = self._load(p.goal_checker_plugins, plugins("goal checker"), DEFAULT_CHECKER_TYPES)
        self.progress_checkers = self._load(p.progress_checkers(), plugins("progress checker"), DEFAULT_CHECKER_TYPES)
        self.costmap_node.footprint_listeners.append(self._on_footprint)
        self._warn = Warnings(self)
        self._speed = (0.0, 0.0)
        self._active: _Following | None = None
        self.cmd_pub = self.create_publisher(Twist, "cmd_vel", 1)
        self.port.require_match(self, self.cmd_pub)
        self.local_plan_pub = self.create_publisher(Path, "local_plan", 1)
        self.create_subscription(Odometry, p.odom_topic, guarded(self, self._on_odom, "Odometry"), 10, data_path=True)
        self.speed_limit = SpeedLimit(NO_SPEED_LIMIT, True)
        self.create_subscription(SpeedLimitMsg, p.speed_limit_topic, guarded(self, self._on_speed_limit, "SpeedLimit"),
                                 10, data_path=True, quiet=True, needs_publisher=False)
        self.server = GoalServer(self, FollowPath, "follow_path", self._on_goal, accept=self.taking_goals)
        # The control loop runs while a path is followed (an idle controller makes no sync times).
        self.timer = self.step_timer(1.0 / p.controller_frequency, self._control)
        self.timer.cancel()
        serve_live_parameters(self, [LiveParameters("", lambda: self.params, self._set_params, LIVE_SERVER),
                                     *live_plugin_parameters(self.plugins, self._set_plugin_params),
                                     *live_plugin_parameters(self.critic_plugins, self._set_critic_params)])
        kinds = ", ".join(f"'{name}' ({self.plugins[name].type_name})" for name in self.controllers)
        self.get_logger().info(f"controllers {kinds} at {p.controller_frequency} Hz on local_costmap")

    def _load(self, names: list[str], types: PluginGroup, defaults: dict[str, str]) -> dict[str, Any]:
        """Each named plugin, made from its type's parameters (kept in ``plugins`` for live sets)."""
        made = {}
        for name in names:
            plugin = self.plugins[name] = load_plugin(self, name, types, defaults.get(name))
            given = self._from_costmap(plugin.params)
            critics = self._critics(name, plugin.params)
            made[name] = plugin.params.make(**given, **({"critics": critics} if critics else {}))
        return made

    def _from_costmap(self, params: Any) -> dict[str, float]:
        """What a plugin takes from the local costmap (its class's ``FROM_COSTMAP``): DWB its footprint."""
        cm = self.costmap_node.params
        costmap = {"robot_radius": cm.robot_radius, "footprint_padding": cm.footprint_padding}
        return {key: costmap[key] for key in getattr(type(params), "FROM_COSTMAP", ())}

    def _critics(self, name: str, params: Any) -> dict[str, Any]:
        """A DWB-like controller's critics (its ``critics``), each an installed plugin (DWB's own are
        too), made from its parameters under ``<name>.<critic>.`` (Nav2's)."""
        made = {}
        group = plugins("DWB critic")
        for critic in getattr(params, "critics", ()):
            type_name = critic_type(critic)
            if type_name is None:
                continue  # the controller's own validate() names it
            prefix = f"{name}.{critic}"
            settings: Any = declare_parameters(self, plugin_class(prefix, group, type_name), prefix=f"{prefix}.")
            self.critic_plugins[prefix] = Plugin(prefix, type_name, settings)
            made[critic] = settings.make(critic)
        return made

    def _on_footprint(self) -> None:
        """The local costmap's footprint changed: DWB's controllers take it (their critics rebuilt)."""
        for name, controller in self.controllers.items():
            given = self._from_costmap(self.plugins[name].params)
            if given and hasattr(controller, "set_footprint"):
                controller.set_footprint(**given)

    # ----------------------------------------------------------- parameters
    def _set_params(self, new: ControllerServerParameters) -> None:
        old, self.params = self.params, new
        if self._active is not None:
            self._active.follower.failure_tolerance_s = new.failure_tolerance
        if new.controller_frequency != old.controller_frequency:
            running = not self.timer.is_canceled()
            self.destroy_step_timer(self.timer)
            self.timer = self.step_timer(1.0 / new.controller_frequency, self._control)
            if not running:
                self.timer.cancel()

    def _set_plugin_params(self, name: str, new: Any) -> None:
        """A plugin's live parameters, set on the running plugin: a controller's path progress, a
        goal checker's latch and a progress checker's baseline stay."""
        old = self.plugins[name]
        self.plugins[name] = Plugin(name, old.type_name, new)
        if name in self.controllers:
            self.controllers[name].settings = new.settings(**self._from_costmap(new))
            return
        fresh = new.make()
        running = self.goal_checkers.get(name) or self.progress_checkers[name]
        for field in dataclasses.fields(new):
            setattr(running, field.name, getattr(fresh, field.name))

    def _set_critic_params(self, key: str, new: Any) -> None:
        """A critic's live parameters (its class's ``LIVE_PARAMETERS``; DWB's own have none): the
        critic is made again in its place."""
        controller, critic = key.split(".", 1)
        self.critic_plugins[key] = Plugin(key, self.critic_plugins[key].type_name, new)
        planner = self.controllers[controller]
        planner.critics = [new.make(critic) if c.name == critic else c for c in planner.critics]

    def destroy_node(self) -> None:
        self.server.destroy()
        self.costmap_node.destroy_node()
        super().destroy_node()

    def _on_speed_limit(self, msg: SpeedLimitMsg) -> None:
        """Nav2's ``speedLimitCallback``: 0 lifts the limit; a percentage in (0, 100] or m/s ≥ 0."""
        limit = float(msg.speed_limit)
        if not math.isfinite(limit) or limit < 0.0 or (msg.percentage and limit > 100.0):
            self._warn("speed limit", f"a speed limit of {limit}{' %' if msg.percentage else ' m/s'} ignored: it must "
                                      "be 0 (none), a percentage in (0, 100] or m/s ≥ 0")
            return
        self.speed_limit = SpeedLimit(limit, bool(msg.percentage))

    def _on_odom(self, msg: Odometry) -> None:
        """The robot's speed, each below its threshold taken as 0 (Nav2's min_*_velocity_threshold)."""
        t = msg.twist.twist
        p = self.params
        v = t.linear.x if abs(t.linear.x) >= p.min_x_velocity_threshold else 0.0
        w = t.angular.z if abs(t.angular.z) >= p.min_theta_velocity_threshold else 0.0
        self._speed = (v, w)

    def _now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def stop(self) -> None:
        if self.params.publish_zero_velocity:
            self.cmd_pub.publish(Twist())

    # ------------------------------------------------------------------ goals
    def _on_goal(self, handle: ServerGoalHandle) -> None:
        """A new path: it preempts the one followed (whose goal aborts), keeping the progress
        checker's history, as Nav2's path updates do."""
        previous = self._active
        if previous is not None:
            self._end(previous, Result.UNKNOWN, "preempted by a new path", stop=False)
        problem = self._start(handle, previous)
        if problem is not None:
            code, message = problem
            self.server.finish(handle, GoalEnd.ABORTED, Result(error_code=code, error_msg=message))
            self.get_logger().warning(f"following failed: {message}")
            if previous is not None:
                self.stop()
            return
        if self.timer.is_canceled():
            self.timer.reset()
        if previous is None:
            self._control()  # the first command now, not a period later

    def _start(self, handle: ServerGoalHandle, previous: _Following | None) -> tuple[int, str] | None:
        request = handle.request
        picked = [_pick(self.controllers, request.controller_id, "controller"),
                  _pick(self.goal_checkers, request.goal_checker_id, "goal checker"),
                  _pick(self.progress_checkers, request.progress_checker_id, "progress checker")]
        problem = next((found for found in picked if isinstance(found, str)), None)
        if problem is not None:
            code = Result.INVALID_CONTROLLER if problem.startswith("controller") else Result.UNKNOWN
            return code, problem
        controller, goal_checker, progress_checker = picked
        if previous is None or previous.follower.progress_checker is not progress_checker:
            progress_checker.reset()
        goal_checker.reset()
        path_msg: Path = request.path
        if not path_msg.poses:
            return Result.INVALID_PATH, "the path is empty"
        path_frame = path_msg.header.frame_id.lstrip("/") or "map"
        o = path_msg.poses[-1].pose.orientation
        path = np.array([[ps.pose.position.x, ps.pose.position.y] for ps in path_msg.poses], dtype=float)
        if not np.isfinite(path).all():
            return Result.INVALID_PATH, "the path has a point that is not finite"
        goal = (float(path[-1, 0]), float(path[-1, 1]), yaw_from_quaternion(o.x, o.y, o.z, o.w))
        path3 = np.column_stack([path, np.full(len(path), goal[2])])
        try:
            controller.set_path(path3)
        except ControllerError as exc:
            return Result.INVALID_PATH, str(exc)
        follower = Follower(controller, goal_checker, progress_checker, self.params.failure_tolerance)
        self._active = _Following(handle, path3, path_frame, goal, follower)
        return None

    def _end(self, following: _Following, code: int, message: str, stop: bool = True) -> None:
        """End the followed goal: success with ``Result.NONE``, else aborted (or canceled when asked)."""
        if self._active is following:
            self._active = None
            self.timer.cancel()
        if stop:
            self.stop()
        handle = following.handle
        end = GoalEnd.SUCCEEDED if code == Result.NONE else stopped_end(handle)
        if end is GoalEnd.ABORTED and code != Result.UNKNOWN:
            self.get_logger().warning(f"following failed: {message}")
        self.server.finish(handle, end, Result(error_code=code, error_msg=message))

    # ------------------------------------------------------------------- loop
    def _control(self) -> None:
        """One control period of the followed path (every 1 / controller_frequency of sim time)."""
        following = self._active
        if following is None:
            self.timer.cancel()
            return
        try:
            outcome = self._step(following)
        except Exception as exc:  # a bug must end the goal, not the server
            outcome = (Result.UNKNOWN, f"{type(exc).__name__}: {exc}")
        if outcome is not None:
            self._end(following, *outcome)

    def _step(self, following: _Following) -> tuple[int, str] | None:
        """Carry out this period's decision (:class:`Follower`): a command, a stop, or the end
        of the goal (code, message)."""
        try:
            check_running(following.handle, None if self._active is None else self._active.handle, "a new path")
        except Stopped as stopped:
            return Result.UNKNOWN, str(stopped)
        now = self._now_s()
        tf = self.costmap_node.tf
        local_frame = self.costmap_node.params.global_frame
        base = self.costmap_node.params.robot_base_frame
        pose = pose_in_costmap = None
        reason = ""
        try:
            pose = tf.lookup(following.path_frame, base)
            # The path stays in its frame (its progress with it); the costmap is looked up in odom.
            pose_in_costmap = compose(tf.lookup(local_frame, following.path_frame), pose)
        except TransformError as exc:
            pose, reason = None, str(exc)
        step = following.follower.step(now, pose, following.goal, following.path3, self._speed,
                                       self.costmap_node.costmap, 1.0 / self.params.controller_frequency,
                                       pose_in_costmap=pose_in_costmap, no_pose_reason=reason)
        if step.end is not None:
            return RESULT_CODES[step.end], step.message
        if step.command is None:
            self.stop()
            self._warn("control", step.problem)
            return None
        command = step.command
        twist = Twist()
        twist.linear.x, twist.angular.z = limited((command.linear_mps, command.angular_radps), self.speed_limit,
                                                  top_speed(following.follower.controller))
        self.cmd_pub.publish(twist)
        if self.local_plan_pub.get_subscription_count():
            self.local_plan_pub.publish(path_message(command.local_plan, 0.0, following.path_frame,
                                                     self.get_clock().now().to_msg()))
        feedback = FollowPath.Feedback()
        assert pose is not None
        feedback.distance_to_goal = float(math.hypot(following.goal[0] - pose[0], following.goal[1] - pose[1]))
        feedback.speed = float(abs(self._speed[0]))
        send_feedback(self.port, following.handle, feedback)
        return None

def _pick(plugins: dict[str, Any], name: str, what: str) -> Any:
    """The plugin a goal names; with one, an empty name names it (as Nav2). A string says why not."""
    if name in plugins:
        return plugins[name]
    if not name and len(plugins) == 1:
        return next(iter(plugins.values()))
    return f"{what} '{name}' is not one of this server's: {', '.join(plugins)}"


def main(args: list[str] | None = None) -> int:
    return run_nodes([ControllerServer], "controller_server", args)


if __name__ == "__main__":
    sys.exit(main())
