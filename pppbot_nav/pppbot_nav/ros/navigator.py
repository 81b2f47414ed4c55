"""``bt_navigator``: goals to the robot's arrival, in Nav2's ``bt_navigator`` place.

Accepts goals as the ``navigate_to_pose`` action (nav2_msgs/action/NavigateToPose), on
``goal_pose`` (geometry_msgs/PoseStamped, RViz's "2D Goal Pose") and as the
``navigate_through_poses`` action (nav2_msgs/action/NavigateThroughPoses: through each pose in
turn, planned by ``compute_path_through_poses``; a pose the robot has come within
:data:`PASSED_GOAL_M` of is dropped before the next plan, as Nav2's ``RemovePassedGoals``, and
the feedback counts the poses remaining); a new goal of either preempts the running one,
cancel stops the robot. It runs Nav2's default tree
(``navigate_to_pose_w_replanning_and_recovery``) as a loop:

* plan (``compute_path_to_pose``) at ``replanning_frequency`` (1 Hz) and hand each path to the
  controller (``follow_path``), which takes a new path as an update of the one it follows;
* a failed plan clears the global costmap and tries once more, a failed follow clears the
  local costmap and tries once more; then one recovery of the round robin (clear both
  costmaps, then the behavior_server's actions: ``spin`` by ``spin_dist``, ``wait``
  ``wait_duration``, ``backup`` ``backup_dist`` at ``backup_speed``) and the loop again, at most
  ``number_of_retries`` recoveries per goal. These decisions are
  :class:`pppbot_nav.navigation_policy.NavigationPolicy`'s (no ROS, unit-tested); this node
  carries them out.

Feedback: the robot's pose in ``global_frame``, the navigation time, the distance left along
the path, an estimated time remaining, and the recoveries so far. A goal that fails carries
the failing server's error code and message. The navigator commands no velocity itself: the
controller and the behaviours do (and stop the robot when their goal ends or is canceled).
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from nav2_msgs.action import BackUp as BackUpAction
from nav2_msgs.action import (
    ComputePathThroughPoses,
    ComputePathToPose,
    FollowPath,
    NavigateThroughPoses,
    NavigateToPose,
)
from nav2_msgs.action import Spin as SpinAction
from nav2_msgs.action import Wait as WaitAction
from nav2_msgs.srv import ClearEntireCostmap
from nav_msgs.msg import Path
from rclpy.action.server import ServerGoalHandle
from rclpy.duration import Duration
from rclpy.task import Future

from pppbot_common.params import check_finite_range, param
from pppbot_common.ros.params import declare_parameters, fixed_parameters
from pppbot_common.se2 import quaternion_from_yaw
from pppbot_common.transforms import TransformError
from pppbot_common.upright import UPRIGHT_STATUS
from pppbot_lockstep.ros.action_client import ActionClient
from pppbot_lockstep.ros.goals import (
    Cancels,
    Flow,
    GoalEnd,
    GoalServer,
    Sleep,
    Step,
    Stopped,
    check_running,
    send_feedback,
    stopped_end,
)
from pppbot_lockstep.ros.lifecycle import ManagedNode
from pppbot_lockstep.ros.runner import Warnings, guarded, run_nodes
from pppbot_lockstep.ros.tf_listener import TfListener
from pppbot_nav.behaviors import Recovery
from pppbot_nav.navigation_policy import FollowDecision, NavigationPolicy, PlanDecision, PolicySettings


@dataclass(frozen=True)
class NavigatorParameters:
    global_frame: str = param("map", "frame of goals and feedback")
    robot_base_frame: str = param("base_link", "the robot's frame")
    replanning_frequency: float = param(1.0, "plans per second while following (Hz, sim time)")
    number_of_retries: int = param(6, "recoveries per goal before it fails")
    server_timeout: float = param(10.0, "wait this long for the planner and controller servers (s)")
    spin_dist: float = param(1.57, "spin recovery: angle (rad)")
    wait_duration: float = param(5.0, "wait recovery: duration (s)")
    backup_dist: float = param(0.30, "backup recovery: distance (m)")
    backup_speed: float = param(0.05, "backup recovery: speed (m/s)")

    def validate(self) -> None:
        check_finite_range("replanning_frequency", self.replanning_frequency, 0.0, 100.0, low_open=True)
        check_finite_range("server_timeout", self.server_timeout, 0.0, 3600.0, low_open=True)
        check_finite_range("spin_dist", self.spin_dist, -2 * math.pi, 2 * math.pi)
        check_finite_range("wait_duration", self.wait_duration, 0.0, 3600.0)
        check_finite_range("backup_dist", self.backup_dist, 0.0, 10.0)
        check_finite_range("backup_speed", self.backup_speed, 0.0, 2.0, low_open=True)
        check_finite_range("number_of_retries", self.number_of_retries, 0, 1000)


#: a planned path ending further than this from the goal means the planner moved the goal (m)
GOAL_MOVED_M = 0.05


class NotUpright(Exception):  # noqa: N818 (a signal of the navigator's own, not an error record)
    """The robot's base reports it is not upright: the goal ends at once, with no recovery."""


class Failed(Exception):
    """A navigation step failed: ``code`` and ``message`` of the server that failed it."""

    def __init__(self, code: int, message: str) -> None:
        super().__init__(message)
        self.code = code


def path_length_from(path: np.ndarray, xy: tuple[float, float]) -> float:
    """Length (m) along ``path`` (K, 2) from its point closest to ``xy`` to its end."""
    if len(path) == 0:
        return 0.0
    i = int(np.argmin(np.hypot(path[:, 0] - xy[0], path[:, 1] - xy[1])))
    rest = path[i:]
    return float(math.hypot(rest[0, 0] - xy[0], rest[0, 1] - xy[1]) + np.hypot(*np.diff(rest, axis=0).T).sum())


#: A pose of a navigate_through_poses goal is passed once the robot comes this close (m; Nav2's
#: RemovePassedGoals radius).
PASSED_GOAL_M = 0.5
#: The navigator's loop period (sim s): feedback, goal checks, recovery commands.
TICK_S = 0.05


_NO_TREE = "no behaviour tree is loaded: the default tree's logic is fixed code"
#: bt_navigator keys that mean nothing here, with the reason (named in the start-up warning when given).
NO_EFFECT = {
    "plugin_lib_names": _NO_TREE, "default_nav_to_pose_bt_xml": _NO_TREE, "default_nav_through_poses_bt_xml": _NO_TREE,
    "default_bt_xml_filename": _NO_TREE, "navigators": _NO_TREE, "navigate_to_pose.*": _NO_TREE,
    "navigate_through_poses.*": _NO_TREE, "error_code_names": _NO_TREE, "error_code_name_prefixes": _NO_TREE,
    "bt_loop_duration": "the navigator ticks on its replanning_frequency and each server's answers",
    "default_server_timeout": "server_timeout is pppbot's name for how long it waits for the servers",
    "enable_groot_monitoring": "no Groot: no behaviour tree to monitor",
    "groot_*": "no Groot: no behaviour tree to monitor",
    "odom_topic": "the navigator reads the robot's pose from TF, not odometry",
    "transform_tolerance": "the navigator uses the newest transform",
    "filter_duration": "the navigator reads the robot's pose from TF, not odometry",
    "use_sim_time": "",
}


class Navigator(ManagedNode):
    """Nav2's ``bt_navigator``: a lifecycle node that takes goals only while active."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("bt_navigator", **kwargs)
        self.params = declare_parameters(self, NavigatorParameters)
        self.parameter_notes = NO_EFFECT
        fixed_parameters(self, lambda: self.params)  # Nav2's has no dynamic parameters
        self._warn = Warnings(self)
        self.tf = TfListener(self, self._warn).buffer
        self.planner = ActionClient(self, ComputePathToPose, "compute_path_to_pose")
        self.planner_through = ActionClient(self, ComputePathThroughPoses, "compute_path_through_poses")
        self.controller = ActionClient(self, FollowPath, "follow_path")
        self.clear_global = self.create_client(ClearEntireCostmap, "global_costmap/clear_entirely_global_costmap")
        self.clear_local = self.create_client(ClearEntireCostmap, "local_costmap/clear_entirely_local_costmap")
        self.behaviors = {Recovery.SPIN: ActionClient(self, SpinAction, "spin"),
                          Recovery.BACKUP: ActionClient(self, BackUpAction, "backup"),
                          Recovery.WAIT: ActionClient(self, WaitAction, "wait")}
        self.port.require_when("the compute_path_to_pose server", self.planner.server_is_ready)
        self.port.require_when("the compute_path_through_poses server", self.planner_through.server_is_ready)
        self.port.require_when("the follow_path server", self.controller.server_is_ready)
        for recovery, client in self.behaviors.items():
            self.port.require_when(f"the {recovery.value} server", client.server_is_ready)
        self._active: tuple[ServerGoalHandle, Flow[None], _Progress] | None = None
        self._self_client = ActionClient(self, NavigateToPose, "navigate_to_pose")
        self.server = GoalServer(self, NavigateToPose, "navigate_to_pose", self._on_goal, accept=self.taking_goals)
        self.through_server = GoalServer(self, NavigateThroughPoses, "navigate_through_poses", self._on_through_goal,
                                         accept=self.taking_goals)
        self.create_subscription(PoseStamped, "goal_pose", guarded(self, self._on_goal_pose, "PoseStamped"), 10)
        #: why the robot is not upright, from its base's /diagnostics (the simulator's, or a driver's); None: upright
        self.not_upright: str | None = None
        on_diagnostics = guarded(self, self._on_diagnostics, "DiagnosticArray")
        self.create_subscription(DiagnosticArray, "/diagnostics", on_diagnostics, 10)
        # Ticks while a goal runs (an idle navigator makes no sync times in lockstep).
        self.timer = self.step_timer(TICK_S, self._tick)
        self.timer.cancel()
        self._cancels = Cancels(self._now_s, self.timer)  # FollowPath and behavior goals canceled, until they end
        self.get_logger().info("bt_navigator: navigate_to_pose and goal_pose once active")

    def destroy_node(self) -> None:
        self.server.destroy()
        self.through_server.destroy()
        super().destroy_node()

    # ----------------------------------------------------------------- inputs
    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        for status in msg.status:
            if status.name.endswith(UPRIGHT_STATUS):
                upright = status.level == DiagnosticStatus.OK
                self.not_upright = None if upright else f"{status.name.removesuffix(UPRIGHT_STATUS)} is not upright: " \
                                                        f"{status.message}"

    def _on_goal_pose(self, msg: PoseStamped) -> None:
        """As bt_navigator does: a goal on the topic becomes a goal of the action (while active)."""
        if not self.taking_goals():
            return
        goal = NavigateToPose.Goal()
        goal.pose = msg
        self.get_logger().info(f"goal_pose: ({msg.pose.position.x:.2f}, {msg.pose.position.y:.2f}) "
                               f"in '{msg.header.frame_id}'")
        self._self_client.send_goal_async(goal)

    def _on_goal(self, handle: ServerGoalHandle) -> None:
        """A navigate_to_pose goal."""
        self._start(handle, [handle.request.pose], through=False)

    def _on_through_goal(self, handle: ServerGoalHandle) -> None:
        """A navigate_through_poses goal."""
        self._start(handle, list(handle.request.poses), through=True)

    def _start(self, handle: ServerGoalHandle, goals: list[PoseStamped], through: bool) -> None:
        """A new goal preempts the running one (which aborts) and starts its flow."""
        previous = self._active
        for goal in goals:
            if not goal.header.frame_id:
                goal.header.frame_id = self.params.global_frame
        p = self.params
        state = _Progress(self._now_s(), NavigationPolicy(PolicySettings(
            number_of_retries=p.number_of_retries, server_timeout_s=p.server_timeout)), goals, through)
        if goals:
            at = goals[-1].pose.position
            self.get_logger().info(f"navigating to ({at.x:.2f}, {at.y:.2f}) in '{goals[-1].header.frame_id}'"
                                   + (f" through {len(goals) - 1} poses" if through else ""))
        flow: Flow[None] = Flow(self._navigate(handle, state), self._now_s,
                                lambda value, error: self._ended(handle, state, error),
                                check=lambda: self._check(handle), port=self.port)
        self._active = (handle, flow, state)
        if previous is not None:
            previous[1].tick()  # it sees the preemption now and ends
        else:
            self.timer.reset()
        flow.start()

    def _tick(self) -> None:
        if self._active is None:
            if not self._cancels.tick():
                self.timer.cancel()
            return
        handle, flow, state = self._active
        flow.tick()
        if not flow.ended:  # recoveries included: a client sees the robot and the count all along
            self._feedback(handle, state)

    # ---------------------------------------------------------------- helpers
    def _now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _pose(self, frame: str) -> tuple[float, float, float]:
        return self.tf.lookup(frame, self.params.robot_base_frame)

    def _check(self, handle: ServerGoalHandle) -> None:
        check_running(handle, None if self._active is None else self._active[0])
        if self.not_upright is not None:  # no goal succeeds with a robot on its side
            raise NotUpright(self.not_upright)

    def _ended(self, handle: ServerGoalHandle, state: _Progress, error: BaseException | None) -> None:
        """The goal's flow ended: success, a stop (cancel or preemption) or a failure."""
        if self._active is not None and self._active[0] is handle:
            self._active = None
        result = state.action.Result()
        server = self.through_server if state.through else self.server
        if error is None:
            self.get_logger().info(f"goal reached in {self._now_s() - state.start_s:.1f} s "
                                   f"({state.recoveries} recoveries)")
            result.error_msg = state.moved_note or ""
            server.finish(handle, GoalEnd.SUCCEEDED, result)
            return
        self._cancel_follow(state)
        if isinstance(error, Stopped):
            result.error_msg = str(error)
            server.finish(handle, stopped_end(handle), result)
            return
        if isinstance(error, Failed):
            result.error_code, result.error_msg = error.code, str(error)
        elif isinstance(error, NotUpright):
            result.error_code, result.error_msg = 0, str(error)
        else:
            result.error_code, result.error_msg = 0, f"{type(error).__name__}: {error}"
        self.get_logger().warning(f"navigation failed: {result.error_msg}")
        server.finish(handle, GoalEnd.ABORTED, result)

    def _cancel_follow(self, state: _Progress) -> None:
        if state.follow is not None:
            self._cancels.cancel(state.follow, state.follow_result)
            state.follow = None
            state.follow_result = None

    def _sleep(self, seconds: float) -> Sleep:
        return Sleep(self._now_s() + seconds)

    # ------------------------------------------------------------ navigation
    def _navigate(self, handle: ServerGoalHandle, state: _Progress) -> Step[None]:
        p = self.params
        if not state.goals:
            raise Failed(0, "no poses to navigate through")
        while self._now_s() <= 0.0:
            # On sim time with no /clock heard yet (a process started a moment ago, its clock's
            # reader not matched yet) the clock reads 0: a deadline from it would pass at the first
            # /clock. The goal waits for the clock instead.
            yield self._sleep(TICK_S)
        deadline = self._now_s() + p.server_timeout
        planner = (self.planner_through, "compute_path_through_poses") if state.through \
            else (self.planner, "compute_path_to_pose")
        for client, name in (planner, (self.controller, "follow_path")):
            while not client.server_is_ready():
                if self._now_s() > deadline:
                    raise Failed(0, f"the {name} server is not available")
                yield self._sleep(TICK_S)
        yield from self._wait_for_pose()
        while True:
            try:
                yield from self._plan_and_follow(state)
                return
            except Failed as exc:
                recovery = state.policy.after_failure(exc.code)
                if recovery is None:
                    raise Failed(exc.code, f"{exc} (after {state.recoveries} recoveries)") from exc
                self._cancel_follow(state)
                self.get_logger().info(f"recovery {state.recoveries}/{p.number_of_retries}: {recovery.value} "
                                       f"(after: {exc})")
                yield from self._recover(recovery)

    def _wait_for_pose(self) -> Step[None]:
        """As bt_navigator does before it navigates: wait (up to ``server_timeout``) for the robot's pose
        in the global frame, which a just-started stack may not have yet."""
        deadline = self._now_s() + self.params.server_timeout
        while True:
            try:
                self._pose(self.params.global_frame)
                return
            except TransformError as exc:
                if self._now_s() > deadline:
                    raise Failed(ComputePathToPose.Result.TF_ERROR, f"no robot pose: {exc}") from exc
            yield self._sleep(0.1)

    def _plan(self, state: _Progress) -> Step[Path]:
        """A path from the planner. A planner that is not ready yet (no robot pose, no map: TF_ERROR
        or UNKNOWN, as a just-started stack's may be) is asked again every half second for up to
        ``server_timeout`` s; any other failure once more after clearing the global costmap.

        Raises:
            Failed: with the planner's error code.
        """
        policy = state.policy
        action, client = (ComputePathThroughPoses, self.planner_through) if state.through \
            else (ComputePathToPose, self.planner)
        goal = action.Goal()
        if state.through:
            goal.goals = list(state.goals)
        else:
            goal.goal = state.goals[0]
        not_ready = (action.Result.TF_ERROR, action.Result.UNKNOWN)
        started_s = self._now_s()
        cleared = False
        while True:
            handle = yield client.send_goal_async(goal)
            if handle is None or not handle.accepted:
                raise Failed(action.Result.UNKNOWN, "the planner refused the goal")
            response = yield handle.get_result_async()
            res = response.result
            if res.error_code == action.Result.NONE and res.path.poses:
                return res.path
            decision = policy.after_plan_failure(res.error_code in not_ready, self._now_s() - started_s, cleared)
            if decision is PlanDecision.RETRY_LATER:
                yield self._sleep(policy.settings.planner_not_ready_retry_s)
            elif decision is PlanDecision.CLEAR_AND_RETRY:
                yield from self._clear(self.clear_global)
                cleared = True
            else:
                raise Failed(res.error_code, f"planning: {res.error_msg}")

    def _plan_and_follow(self, state: _Progress) -> Step[None]:
        follow_failures = 0
        next_plan = -math.inf
        while True:
            now = self._now_s()
            if now >= next_plan:
                next_plan = now + 1.0 / self.params.replanning_frequency
                self._drop_passed_goals(state)
                path = yield from self._plan(state)
                state.path = np.array([[ps.pose.position.x, ps.pose.position.y] for ps in path.poses])
                self._note_moved_goal(state.goals[-1], state)
                follow = FollowPath.Goal()
                follow.path = path
                handle = yield self.controller.send_goal_async(follow, feedback_callback=state.on_feedback)
                if handle is None or not handle.accepted:
                    raise Failed(FollowPath.Result.UNKNOWN, "the controller refused the path")
                state.follow, state.follow_result = handle, handle.get_result_async()
            if state.follow_result is not None and state.follow_result.done():
                res = state.follow_result.result().result
                state.follow, state.follow_result = None, None
                if res.error_code == FollowPath.Result.NONE:
                    return
                follow_failures += 1
                if state.policy.after_follow_failure(follow_failures) is FollowDecision.FAIL:
                    raise Failed(res.error_code, f"following: {res.error_msg}")
                yield from self._clear(self.clear_local)
                next_plan = -math.inf
                continue
            # Until the follow ends or the next plan is due, whichever comes first.
            yield Sleep(next_plan, wake=state.follow_result)

    def _drop_passed_goals(self, state: _Progress) -> None:
        """Nav2's RemovePassedGoals: the poses before the last that the robot has come within
        :data:`PASSED_GOAL_M` of (in their frame) are done."""
        while state.through and len(state.goals) > 1:
            goal = state.goals[0]
            try:
                x, y, _ = self._pose(goal.header.frame_id)
            except TransformError:
                return
            if math.hypot(goal.pose.position.x - x, goal.pose.position.y - y) > PASSED_GOAL_M:
                return
            state.goals.pop(0)

    def _note_moved_goal(self, request: PoseStamped, state: _Progress) -> None:
        """The planner moved an unreachable goal to the nearest free pose within its tolerance: say so
        once (the log, and the result's message)."""
        assert state.path is not None
        end = state.path[-1]
        moved = math.hypot(end[0] - request.pose.position.x, end[1] - request.pose.position.y)
        if moved > GOAL_MOVED_M and state.moved_note is None:
            state.moved_note = (f"the goal ({request.pose.position.x:.2f}, {request.pose.position.y:.2f}) is in an "
                                f"obstacle: navigating to the nearest free pose ({end[0]:.2f}, {end[1]:.2f}), "
                                f"{moved:.2f} m away (the planner's tolerance)")
            self.get_logger().info(state.moved_note)

    def _feedback(self, handle: ServerGoalHandle, state: _Progress) -> None:
        try:
            x, y, yaw = self._pose(self.params.global_frame)
        except TransformError:
            return  # no pose yet (a stack starting): the flow says so if it lasts
        fb = state.action.Feedback()
        if state.through:
            fb.number_of_poses_remaining = len(state.goals)
        fb.current_pose.header.frame_id = self.params.global_frame
        fb.current_pose.header.stamp = self.get_clock().now().to_msg()
        fb.current_pose.pose.position.x, fb.current_pose.pose.position.y = x, y
        o = fb.current_pose.pose.orientation
        o.x, o.y, o.z, o.w = quaternion_from_yaw(yaw)
        fb.navigation_time = Duration(seconds=max(0.0, self._now_s() - state.start_s)).to_msg()
        fb.number_of_recoveries = state.recoveries
        remaining = path_length_from(state.path, (x, y)) if state.path is not None else 0.0
        fb.distance_remaining = float(remaining)
        speed = state.speed if state.speed > 0.05 else 0.0
        fb.estimated_time_remaining = Duration(seconds=remaining / speed if speed else 0.0).to_msg()
        send_feedback(self.port, handle, fb)

    def _clear(self, client: Any) -> Step[None]:
        if not client.service_is_ready():
            self._warn("clear", f"{client.srv_name} is not available: not cleared")
            return
        yield client.call_async(ClearEntireCostmap.Request())

    # ------------------------------------------------------------ recoveries
    def _recover(self, recovery: Recovery) -> Step[None]:
        """One recovery of the round robin: clear both costmaps, or the behavior_server's spin, wait
        or backup action (its failure, a collision ahead or a timeout, is logged; the round robin
        goes on)."""
        p = self.params
        if recovery is Recovery.CLEAR_COSTMAPS:
            yield from self._clear(self.clear_local)
            yield from self._clear(self.clear_global)
            return
        client = self.behaviors[recovery]
        goal: Any
        if recovery is Recovery.SPIN:
            goal = SpinAction.Goal(target_yaw=p.spin_dist,
                                   time_allowance=Duration(seconds=BEHAVIOR_ALLOWANCE_S).to_msg())
            allowance = BEHAVIOR_ALLOWANCE_S
        elif recovery is Recovery.BACKUP:
            goal = BackUpAction.Goal(speed=p.backup_speed,
                                     time_allowance=Duration(seconds=BEHAVIOR_ALLOWANCE_S).to_msg())
            goal.target.x = p.backup_dist
            allowance = BEHAVIOR_ALLOWANCE_S
        else:
            goal = WaitAction.Goal(time=Duration(seconds=p.wait_duration).to_msg())
            allowance = p.wait_duration
        if not client.server_is_ready():
            self._warn("behavior", f"{recovery.value} skipped: the behavior_server's {recovery.value} action "
                                   "is not available")
            return
        handle = yield client.send_goal_async(goal)
        if handle is None or not handle.accepted:
            self._warn("behavior", f"{recovery.value} skipped: the behavior_server refused it (not active?)")
            return
        result = handle.get_result_async()
        try:
            deadline = self._now_s() + allowance + BEHAVIOR_ALLOWANCE_S
            while not result.done() and self._now_s() < deadline:
                yield Sleep(deadline, wake=result)
        finally:
            if not result.done():  # the goal was canceled or preempted meanwhile, or the server hangs
                self._cancels.cancel(handle, result)
        if result.done() and result.result().result.error_code != 0:
            res = result.result().result
            self.get_logger().info(f"{recovery.value} ended early: {res.error_msg}")


#: The time a spin or backup recovery is allowed (s; Nav2's default tree's time_allowance).
BEHAVIOR_ALLOWANCE_S = 10.0


class _Progress:
    """One goal's running state."""

    def __init__(self, start_s: float, policy: NavigationPolicy, goals: list[PoseStamped], through: bool) -> None:
        self.start_s = start_s
        self.policy = policy
        self.goals = goals  # the poses still to reach, the goal last
        self.through = through  # a navigate_through_poses goal
        self.action: Any = NavigateThroughPoses if through else NavigateToPose
        self.path: np.ndarray | None = None
        self.follow: Any = None
        self.follow_result: Future | None = None
        self.speed = 0.0
        self.moved_note: str | None = None  # set when the planner moved an unreachable goal

    @property
    def recoveries(self) -> int:
        return self.policy.recoveries

    def on_feedback(self, msg: Any) -> None:
        self.speed = float(msg.feedback.speed)


def main(args: list[str] | None = None) -> int:
    return run_nodes([Navigator], "bt_navigator", args)


if __name__ == "__main__":
    sys.exit(main())
