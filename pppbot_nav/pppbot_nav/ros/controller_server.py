"""``controller_server``: follows paths with regulated pure pursuit, in Nav2's ``controller_server`` place.

Runs the ``local_costmap`` (:mod:`pppbot_nav.ros.costmap_node`, rolling in ``odom``) in the same
process, as Nav2 does. Serves ``follow_path`` (nav2_msgs/action/FollowPath): at
``controller_frequency`` (sim time) it places the path in the local costmap's frame (TF),
computes the command (:mod:`pppbot_nav.controller.pure_pursuit`, parameters under
``FollowPath.``), publishes it on ``cmd_vel`` (geometry_msgs/Twist: twist_mux's
``navigation`` input) and the part of the path it follows on ``local_plan``, and gives
feedback (distance to goal, speed). The goal checker (``general_goal_checker.*``) ends the
goal with success; the progress checker (``progress_checker.*``) fails it with
FAILED_TO_MAKE_PROGRESS; a collision ahead that lasts longer than ``failure_tolerance`` fails
it with NO_VALID_CONTROL. These per-period decisions are
:class:`pppbot_nav.controller.follow.Follower`'s (no ROS, unit-tested). A new path preempts the
one being followed and keeps the progress checker's history, as Nav2's path updates do. The
robot is stopped whenever a goal ends.
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
from nav_msgs.msg import Odometry, Path
from rclpy.action.server import ServerGoalHandle

from pppbot_common.params import ParameterError, check_finite_range, param
from pppbot_common.ros.goals import GoalEnd, GoalServer, Stopped, check_running, stopped_end
from pppbot_common.ros.lifecycle import ManagedNode
from pppbot_common.ros.lockstep import create_timer, require_match
from pppbot_common.ros.node_main import Warnings, guarded, run_nodes
from pppbot_common.ros.params import declare_parameters
from pppbot_common.se2 import yaw_from_quaternion
from pppbot_common.transforms import TransformError, compose
from pppbot_nav.controller.checkers import SimpleGoalChecker, SimpleProgressChecker
from pppbot_nav.controller.follow import FollowEnd, Follower
from pppbot_nav.controller.pure_pursuit import PurePursuit, PurePursuitSettings
from pppbot_nav.errors import ControllerError
from pppbot_nav.ros.costmap_node import CostmapNode
from pppbot_nav.ros.planner_server import path_message

Result = FollowPath.Result
CONTROLLER_ID = "FollowPath"


@dataclass(frozen=True)
class ControllerServerParameters:
    controller_frequency: float = param(20.0, "control periods per second (Hz, sim time)")
    controller_plugins: list = param([CONTROLLER_ID], f"controller names (pppbot has one: {CONTROLLER_ID})")
    odom_topic: str = param("odom", "odometry: the robot's current speed")
    failure_tolerance: float = param(0.3, "how long the controller may fail before the goal does (s)")
    required_movement_radius: float = param(0.5, "progress checker: move this far (m) ...",
                                            "progress_checker.required_movement_radius")
    movement_time_allowance: float = param(10.0, "... within this time (s)", "progress_checker.movement_time_allowance")
    xy_goal_tolerance: float = param(0.25, "goal checker: distance (m)", "general_goal_checker.xy_goal_tolerance")
    yaw_goal_tolerance: float = param(0.25, "goal checker: heading (rad)", "general_goal_checker.yaw_goal_tolerance")
    stateful: bool = param(True, "goal checker: once within xy, only the heading is checked",
                           "general_goal_checker.stateful")

    def validate(self) -> None:
        check_finite_range("controller_frequency", self.controller_frequency, 0.0, 1000.0, low_open=True)
        check_finite_range("failure_tolerance", self.failure_tolerance, 0.0, 3600.0)
        if list(self.controller_plugins) != [CONTROLLER_ID]:
            raise ParameterError("controller_plugins", self.controller_plugins, f"must be ['{CONTROLLER_ID}']")
        try:
            self.goal_checker()
            self.progress_checker()
        except ControllerError as exc:
            raise ParameterError(exc.parameter or "general_goal_checker", "", str(exc)) from exc

    def goal_checker(self) -> SimpleGoalChecker:
        return SimpleGoalChecker(self.xy_goal_tolerance, self.yaw_goal_tolerance, self.stateful)

    def progress_checker(self) -> SimpleProgressChecker:
        return SimpleProgressChecker(self.required_movement_radius, self.movement_time_allowance)


def _follow_path_parameters() -> type:
    """``FollowPath.<name>`` parameters: every field of :class:`PurePursuitSettings`."""
    fields = [(f.name, f.type, param(f.default, f"regulated pure pursuit: {f.name}", f"{CONTROLLER_ID}.{f.name}"))
              for f in dataclasses.fields(PurePursuitSettings)]

    def validate(self: Any) -> None:
        try:
            self.settings().validate()
        except ControllerError as exc:
            name = f"{CONTROLLER_ID}.{exc.parameter}" if exc.parameter else CONTROLLER_ID
            raise ParameterError(name, getattr(self, exc.parameter or "", ""), str(exc)) from exc

    def settings(self: Any) -> PurePursuitSettings:
        return PurePursuitSettings(**{f.name: getattr(self, f.name) for f in dataclasses.fields(PurePursuitSettings)})

    return dataclasses.make_dataclass("FollowPathParameters", fields, frozen=True,
                                      namespace={"validate": validate, "settings": settings})


FollowPathParameters = _follow_path_parameters()


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
        self.rpp_settings: PurePursuitSettings = declare_parameters(self, FollowPathParameters).settings()
        self.costmap_node = CostmapNode("local_costmap")
        self.composed_nodes = [self.costmap_node]
        self.controller = PurePursuit(self.rpp_settings)
        self.goal_checker = p.goal_checker()
        self.progress_checker = p.progress_checker()
        self._warn = Warnings(self)
        self._speed = (0.0, 0.0)
        self._active: _Following | None = None
        self.cmd_pub = self.create_publisher(Twist, "cmd_vel", 1)
        require_match(self, self.cmd_pub)
        self.local_plan_pub = self.create_publisher(Path, "local_plan", 1)
        require_match(self, self.create_subscription(Odometry, p.odom_topic, guarded(self, self._on_odom, "Odometry"),
                                                     10))
        self.server = GoalServer(self, FollowPath, "follow_path", self._on_goal, accept=self.taking_goals)
        # The control loop runs while a path is followed (an idle controller makes no sync times).
        self.timer = create_timer(self, 1.0 / p.controller_frequency, self._control)
        self.timer.cancel()
        self.get_logger().info(f"controller '{CONTROLLER_ID}' (regulated pure pursuit) at "
                               f"{p.controller_frequency} Hz on local_costmap")

    def destroy_node(self) -> None:
        self.server.destroy()
        self.costmap_node.destroy_node()
        super().destroy_node()

    def _on_odom(self, msg: Odometry) -> None:
        t = msg.twist.twist
        self._speed = (t.linear.x, t.angular.z)

    def _now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def stop(self) -> None:
        self.cmd_pub.publish(Twist())

    # ------------------------------------------------------------------ goals
    def _on_goal(self, handle: ServerGoalHandle) -> None:
        """A new path: it preempts the one followed (whose goal aborts), keeping the progress
        checker's history, as Nav2's path updates do."""
        previous = self._active
        if previous is not None:
            self._end(previous, Result.UNKNOWN, "preempted by a new path", stop=False)
        else:
            self.progress_checker.reset()
        self.goal_checker.reset()
        problem = self._start(handle)
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

    def _start(self, handle: ServerGoalHandle) -> tuple[int, str] | None:
        request = handle.request
        if request.controller_id not in ("", CONTROLLER_ID):
            return Result.INVALID_CONTROLLER, f"unknown controller_id '{request.controller_id}'"
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
            self.controller.set_path(path3)
        except ControllerError as exc:
            return Result.INVALID_PATH, str(exc)
        p = self.params
        follower = Follower(self.controller, self.goal_checker, self.progress_checker, p.failure_tolerance,
                            p.required_movement_radius, p.movement_time_allowance)
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
        twist.linear.x, twist.angular.z = command.linear_mps, command.angular_radps
        self.cmd_pub.publish(twist)
        if self.local_plan_pub.get_subscription_count():
            self.local_plan_pub.publish(path_message(command.local_plan, 0.0, following.path_frame,
                                                     self.get_clock().now().to_msg()))
        feedback = FollowPath.Feedback()
        assert pose is not None
        feedback.distance_to_goal = float(math.hypot(following.goal[0] - pose[0], following.goal[1] - pose[1]))
        feedback.speed = float(abs(self._speed[0]))
        following.handle.publish_feedback(feedback)
        return None

def main(args: list[str] | None = None) -> int:
    return run_nodes([ControllerServer], "controller_server", args)


if __name__ == "__main__":
    sys.exit(main())
