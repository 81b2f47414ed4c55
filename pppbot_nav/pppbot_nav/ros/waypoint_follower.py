"""``waypoint_follower``: goes through a list of poses, in Nav2's ``waypoint_follower`` place.

Serves ``follow_waypoints`` (nav2_msgs/action/FollowWaypoints) while active: each pose from
``goal_index`` on is sent in turn as a ``navigate_to_pose`` goal (stamped with the node's time,
as Nav2 stamps it), then ``number_of_loops`` more times from the first. At each reached pose the
waypoint task executor runs (``waypoint_task_executor_plugin``: ``wait_at_waypoint``, Nav2's
``nav2_waypoint_follower::WaitAtWaypoint``, pauses ``waypoint_pause_duration`` ms of the node's
clock). Feedback gives the index of the pose being handled. What comes after each pose is
:class:`pppbot_nav.waypoints.WaypointRun`'s decision (no ROS, unit-tested); this node carries it
out on its clock (sim time under ``use_sim_time``) without blocking its executor.

Missed poses (navigation failed: ``navigate_to_pose`` aborted, canceled or refused, or no
navigator within :data:`NAVIGATOR_WAIT_S`; or the task failed) are listed in the result's
``missed_waypoints`` with the navigator's error code (TASK_EXECUTOR_FAILED for a task). With
``stop_on_failure`` the first miss aborts the goal: STOP_ON_MISSED_WAYPOINT or
TASK_EXECUTOR_FAILED. A goal without poses or with ``goal_index`` out of range aborts with
NO_VALID_WAYPOINTS. Jazzy's FollowWaypoints has no NO_VALID_WAYPOINTS nor
STOP_ON_MISSED_WAYPOINT (Nav2 from Kilted on has): with Jazzy's messages those goals end with
UNKNOWN and a message that says which. A cancel cancels the running ``navigate_to_pose`` goal
and ends canceled; a new goal preempts the running one, which aborts.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import Any

from action_msgs.msg import GoalStatus
from geometry_msgs.msg import PoseStamped
from nav2_msgs.action import FollowWaypoints, NavigateToPose
from nav2_msgs.msg import MissedWaypoint as MissedWaypointMsg
from rclpy.action.server import ServerGoalHandle
from rclpy.task import Future

from pppbot_common.params import ParameterError, check_finite_range, param
from pppbot_common.ros.params import declare_parameters, fixed_parameters
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
from pppbot_lockstep.ros.runner import run_nodes
from pppbot_nav.waypoints import (
    WAIT_AT_WAYPOINT,
    Decision,
    MissReason,
    Next,
    TaskExecutor,
    TaskStatus,
    WaypointRun,
    load_task_executor,
)

TASK_EXECUTOR_NAME = "wait_at_waypoint"
#: How long a waypoint waits for the navigate_to_pose server to show up before it is missed (s, the node's clock).
NAVIGATOR_WAIT_S = 10.0

Result = FollowWaypoints.Result
#: Nav2's codes for these ends, where the message has them (Kilted on); UNKNOWN with Jazzy's.
NO_VALID_WAYPOINTS: int = getattr(Result, "NO_VALID_WAYPOINTS", Result.UNKNOWN)
STOP_ON_MISSED_WAYPOINT: int = getattr(Result, "STOP_ON_MISSED_WAYPOINT", Result.UNKNOWN)


@dataclass(frozen=True)
class WaypointFollowerParameters:
    stop_on_failure: bool = param(True, "a missed waypoint aborts the goal (else the next one is taken)")
    loop_rate: int = param(20, "checks per second of the running navigation and task (Hz, the node's clock)")
    waypoint_task_executor_plugin: str = param(TASK_EXECUTOR_NAME, "the task executor's name "
                                               f"(pppbot has one: {TASK_EXECUTOR_NAME})")
    plugin: str = param(WAIT_AT_WAYPOINT, "the task executor's Nav2 plugin type", f"{TASK_EXECUTOR_NAME}.plugin")
    enabled: bool = param(True, "pause at each waypoint", f"{TASK_EXECUTOR_NAME}.enabled")
    waypoint_pause_duration: int = param(200, "how long to pause at each waypoint (ms)",
                                         f"{TASK_EXECUTOR_NAME}.waypoint_pause_duration")

    def validate(self) -> None:
        check_finite_range("loop_rate", self.loop_rate, 0, 1000, low_open=True)
        if self.waypoint_task_executor_plugin != TASK_EXECUTOR_NAME:
            raise ParameterError("waypoint_task_executor_plugin", self.waypoint_task_executor_plugin,
                                 f"must be '{TASK_EXECUTOR_NAME}'")
        check_finite_range(f"{TASK_EXECUTOR_NAME}.waypoint_pause_duration", self.waypoint_pause_duration,
                           0, 24 * 3600 * 1000)


class StopOnFailure(Exception):  # noqa: N818 (a goal's end, not an error record)
    """The run stopped at a missed waypoint (``stop_on_failure``): the result's ``code`` and the message."""

    def __init__(self, code: int, message: str) -> None:
        super().__init__(message)
        self.code = code


class _Following:
    """One goal's running state."""

    def __init__(self, poses: list[PoseStamped]) -> None:
        self.poses = poses
        self.run: WaypointRun | None = None
        self.index = 0  # the pose being handled (the feedback)
        self.navigation: Any = None  # the running navigate_to_pose goal's handle
        self.navigation_result: Future | None = None  # and its result


class WaypointFollower(ManagedNode):
    """Nav2's ``waypoint_follower``: a lifecycle node that takes goals only while active."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("waypoint_follower", **kwargs)
        self.params = declare_parameters(self, WaypointFollowerParameters)
        # stop_on_failure is read for each goal: it may change (as Jazzy's dynamic parameter).
        fixed_parameters(self, lambda: self.params, {"stop_on_failure"}, self._set_params)
        self.task: TaskExecutor | None = None
        self.navigator = ActionClient(self, NavigateToPose, "navigate_to_pose")
        self.port.require_when("the navigate_to_pose server", self.navigator.server_is_ready)
        self._active: tuple[ServerGoalHandle, Flow[None], _Following] | None = None
        self.server = GoalServer(self, FollowWaypoints, "follow_waypoints", self._on_goal, accept=self.taking_goals)
        # Ticks while a goal runs (an idle follower makes no sync times in lockstep).
        self.timer = self.step_timer(1.0 / self.params.loop_rate, self._tick)
        self.timer.cancel()
        self._cancels = Cancels(self._now_s, self.timer)  # navigations canceled, until they end
        self.get_logger().info(f"follow_waypoints once active ({TASK_EXECUTOR_NAME} at each waypoint)")

    def _set_params(self, new: WaypointFollowerParameters) -> None:
        self.params = new

    def destroy_node(self) -> None:
        self.server.destroy()
        super().destroy_node()

    # ------------------------------------------------------------- lifecycle
    def configure(self) -> None:
        p = self.params
        self.task = load_task_executor(p.plugin, enabled=p.enabled,
                                       waypoint_pause_duration_ms=p.waypoint_pause_duration)

    def deactivate(self) -> None:
        if self._active is not None:
            handle, flow, _ = self._active
            self._active = None
            flow.tick()  # it sees it is no longer the running goal and ends (aborted)

    def cleanup(self) -> None:
        self.task = None

    # ----------------------------------------------------------------- goals
    def _on_goal(self, handle: ServerGoalHandle) -> None:
        """A follow_waypoints goal preempts the running one (which aborts) and starts its flow."""
        previous = self._active
        state = _Following(list(handle.request.poses))
        flow: Flow[None] = Flow(self._follow(handle, state), self._now_s,
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
        if not flow.ended:
            self._feedback(handle, state)

    def _check(self, handle: ServerGoalHandle) -> None:
        if not self.active:
            raise Stopped("the waypoint follower was deactivated")
        check_running(handle, None if self._active is None else self._active[0])

    def _now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _period_s(self) -> float:
        return 1.0 / self.params.loop_rate

    def _feedback(self, handle: ServerGoalHandle, state: _Following) -> None:
        feedback = FollowWaypoints.Feedback(current_waypoint=state.index)
        send_feedback(self.port, handle, feedback)

    # ------------------------------------------------------------ following
    def _follow(self, handle: ServerGoalHandle, state: _Following) -> Step[None]:
        request = handle.request
        p = self.params
        state.run = run = WaypointRun(len(state.poses), goal_index=request.goal_index,
                                      number_of_loops=request.number_of_loops, stop_on_failure=p.stop_on_failure)
        self.get_logger().info(f"following {len(state.poses)} waypoints from {run.index}"
                               + (f", {run.number_of_loops} loops more" if run.number_of_loops else ""))
        decision = Decision(Next.NAVIGATE, run.index)
        while decision.next is Next.NAVIGATE:
            state.index = decision.index
            self._feedback(handle, state)
            reached, code = yield from self._navigate(state, state.poses[decision.index])
            if reached:
                self.get_logger().info(f"waypoint {decision.index} reached")
                task_ok = yield from self._run_task(decision.index)
                decision = run.reached(task_ok)
            else:
                self.get_logger().warning(f"waypoint {decision.index} missed (navigate_to_pose error {code})")
                decision = run.missed(code)
        if decision.next is Next.STOP_ON_MISSED_WAYPOINT:
            raise StopOnFailure(STOP_ON_MISSED_WAYPOINT, f"STOP_ON_MISSED_WAYPOINT: waypoint {decision.index} "
                                                         "was missed and stop_on_failure is set")
        if decision.next is Next.STOP_ON_TASK_FAILURE:
            raise StopOnFailure(Result.TASK_EXECUTOR_FAILED, f"the task at waypoint {decision.index} failed "
                                                             "and stop_on_failure is set")

    def _navigate(self, state: _Following, pose: PoseStamped) -> Step[tuple[bool, int]]:
        """navigate_to_pose to ``pose``: whether it succeeded, and the navigator's error code."""
        deadline = self._now_s() + NAVIGATOR_WAIT_S
        while not self.navigator.server_is_ready():
            if self._now_s() > deadline:
                self.get_logger().warning("the navigate_to_pose server is not available")
                return False, 0
            yield Sleep(self._now_s() + self._period_s())
        goal = NavigateToPose.Goal(pose=pose)
        goal.pose.header.stamp = self.get_clock().now().to_msg()
        handle = yield self.navigator.send_goal_async(goal)
        if handle is None or not handle.accepted:
            return False, 0
        done: Future = handle.get_result_async()
        state.navigation, state.navigation_result = handle, done
        while not done.done():
            yield Sleep(self._now_s() + self._period_s(), wake=done)
        state.navigation = state.navigation_result = None
        response = done.result()
        if response.status == GoalStatus.STATUS_SUCCEEDED:
            return True, 0
        if response.status == GoalStatus.STATUS_ABORTED:
            return False, int(response.result.error_code)
        return False, 0  # canceled (by someone else), or an unknown end

    def _run_task(self, index: int) -> Step[bool]:
        """The waypoint task at pose ``index``, stepped at ``loop_rate``: whether it succeeded."""
        task = self.task
        if task is None:
            raise RuntimeError("the waypoint task executor is not configured")
        task.start(index, self._now_s())
        while (status := task.step(self._now_s())) is TaskStatus.RUNNING:
            yield Sleep(self._now_s() + self._period_s())
        return status is TaskStatus.SUCCEEDED

    # ----------------------------------------------------------------- ends
    def _ended(self, handle: ServerGoalHandle, state: _Following, error: BaseException | None) -> None:
        """The goal's flow ended: success, a stop (cancel or preemption) or a failure."""
        if self._active is not None and self._active[0] is handle:
            self._active = None
        result = Result()
        if state.run is not None:
            result.missed_waypoints = [self._missed_message(state, m.index, m.reason, m.navigation_error_code)
                                       for m in state.run.missed_waypoints]
        if error is None:
            self.get_logger().info(f"all waypoints handled ({len(result.missed_waypoints)} missed)")
            self.server.finish(handle, GoalEnd.SUCCEEDED, result)
            return
        self._cancel_navigation(state)
        if isinstance(error, Stopped):
            result.error_msg = str(error)
            self.server.finish(handle, stopped_end(handle), result)
            return
        if isinstance(error, StopOnFailure):
            result.error_code, result.error_msg = error.code, str(error)
        elif state.run is None:  # WaypointRun refused the goal
            result.error_code, result.error_msg = NO_VALID_WAYPOINTS, f"NO_VALID_WAYPOINTS: {error}"
        else:
            result.error_code, result.error_msg = Result.UNKNOWN, f"{type(error).__name__}: {error}"
        self.get_logger().warning(f"waypoint following failed: {result.error_msg}")
        self.server.finish(handle, GoalEnd.ABORTED, result)

    @staticmethod
    def _missed_message(state: _Following, index: int, reason: MissReason, code: int) -> MissedWaypointMsg:
        error_code = Result.TASK_EXECUTOR_FAILED if reason is MissReason.TASK else code
        return MissedWaypointMsg(index=index, goal=state.poses[index], error_code=error_code)

    def _cancel_navigation(self, state: _Following) -> None:
        if state.navigation is not None:
            self._cancels.cancel(state.navigation, state.navigation_result)
            state.navigation = state.navigation_result = None


def main(args: list[str] | None = None) -> int:
    return run_nodes([WaypointFollower], "waypoint_follower", args)


if __name__ == "__main__":
    sys.exit(main())
