"""The waypoint follower over DDS against a fake navigate_to_pose server that ends each goal as told."""
from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import pytest
from action_msgs.msg import GoalStatus
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped
from lifecycle_msgs.msg import Transition
from nav2_msgs.action import FollowWaypoints, NavigateToPose
from rclpy.action import ActionClient
from rclpy.action.server import ServerGoalHandle
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock

from pppbot_common.params import ParameterError
from pppbot_common.ros.wait import change_state, send_goal, wait_until
from pppbot_lockstep.ros.goals import GoalEnd, GoalServer
from pppbot_nav.ros.waypoint_follower import WaypointFollower

pytestmark = pytest.mark.ros

Result = FollowWaypoints.Result
#: The navigator's error code of an aborted navigation (Nav2's FollowPath PATIENCE_EXCEEDED, say).
ABORT_CODE = 104
NO_PAUSE = {"wait_at_waypoint.waypoint_pause_duration": 0}


class FakeNavigator(Node):
    """navigate_to_pose whose goals end on its next tick (20 Hz), as ``ends`` says for the pose's x
    (the test puts waypoint i at x = i): succeeded (the default), aborted with ABORT_CODE, or
    never (None; such a goal ends only when canceled)."""

    def __init__(self, ends: dict[int, GoalEnd | None]) -> None:
        super().__init__("fake_navigator")
        self.ends = ends
        self.goals: list[tuple[int, float]] = []  # (waypoint, the goal's stamp in s), as received
        self.canceled: list[int] = []
        self.pending: list[ServerGoalHandle] = []
        self.server = GoalServer(self, NavigateToPose, "navigate_to_pose", self._on_goal)
        self.create_timer(0.05, self._tick)

    def _on_goal(self, handle: ServerGoalHandle) -> None:
        pose = handle.request.pose
        self.goals.append((int(pose.pose.position.x), pose.header.stamp.sec + pose.header.stamp.nanosec * 1e-9))
        self.pending.append(handle)

    def _tick(self) -> None:
        for handle in list(self.pending):
            index = int(handle.request.pose.pose.position.x)
            end = self.ends.get(index, GoalEnd.SUCCEEDED)
            if handle.is_cancel_requested:
                self.canceled.append(index)
                end = GoalEnd.CANCELED
            elif end is None:
                continue
            code = ABORT_CODE if end is GoalEnd.ABORTED else 0
            self.server.finish(handle, end, NavigateToPose.Result(error_code=code))
            self.pending.remove(handle)

    def indices(self) -> list[int]:
        return [index for index, _ in self.goals]


def waypoints(count: int) -> list[PoseStamped]:
    poses = []
    for i in range(count):
        pose = PoseStamped()
        pose.header.frame_id = "map"
        pose.pose.position.x = float(i)
        pose.pose.orientation.w = 1.0
        poses.append(pose)
    return poses


class Stack:
    """The follower and the fake navigator, spun in the background; the test's client on ``ros_node``."""

    def __init__(self, ros_node: Any, follower: WaypointFollower, navigator: FakeNavigator) -> None:
        self.node, self.follower, self.navigator = ros_node, follower, navigator
        self.client = ActionClient(ros_node, FollowWaypoints, "follow_waypoints")
        self.feedback: list[int] = []
        assert self.client.wait_for_server(timeout_sec=10)
        wait_until(follower.navigator.server_is_ready, 10, "the follower's navigate_to_pose client", node=ros_node)

    def change(self, transition: int) -> bool:
        return change_state(self.node, "waypoint_follower", transition)

    def activate(self) -> None:
        assert self.change(Transition.TRANSITION_CONFIGURE)
        assert self.change(Transition.TRANSITION_ACTIVATE)

    def send(self, count: int = 3, **fields: Any) -> Any:
        """A goal of ``count`` waypoints (and ``fields``): its handle once answered."""
        feedback_topic = "/follow_waypoints/_action/feedback"
        wait_until(lambda: self.follower.count_subscribers(feedback_topic), 10, "the feedback subscription",
                   node=self.node)
        goal = FollowWaypoints.Goal(poses=waypoints(count), **fields)
        return send_goal(self.client, goal, self.node,
                         feedback_callback=lambda msg: self.feedback.append(msg.feedback.current_waypoint))

    def result(self, handle: Any, tick: Callable[[], None] = lambda: None, timeout_s: float = 30.0) -> Any:
        """The goal's end (status and result), calling ``tick`` between looks."""
        future = handle.get_result_async()

        def done() -> Any:
            tick()
            return future.result() if future.done() else None
        return wait_until(done, timeout_s, "the follow_waypoints result", node=self.node)


@pytest.fixture
def stack(ros_node: Any, spin_in_background: Callable[..., Any]) -> Iterator[Callable[..., Stack]]:
    """``stack(ends, **parameters)``: a follower (unconfigured) with the parameters, and its navigator."""
    def start(ends: dict[int, GoalEnd | None] | None = None, **parameters: Any) -> Stack:
        follower = WaypointFollower(parameter_overrides=[Parameter(k, value=v) for k, v in parameters.items()])
        navigator = FakeNavigator(ends or {})
        spin_in_background(follower, navigator)
        return Stack(ros_node, follower, navigator)
    yield start


def test_goals_are_rejected_until_active_then_every_waypoint_is_visited_with_feedback(stack):
    s = stack(**NO_PAUSE)
    assert not s.send().accepted  # unconfigured
    assert s.change(Transition.TRANSITION_CONFIGURE)
    assert not s.send().accepted  # inactive
    assert s.change(Transition.TRANSITION_ACTIVATE)
    handle = s.send()
    assert handle.accepted
    end = s.result(handle)
    assert end.status == GoalStatus.STATUS_SUCCEEDED
    assert end.result.error_code == Result.NONE and list(end.result.missed_waypoints) == []
    assert s.navigator.indices() == [0, 1, 2]
    assert sorted(set(s.feedback)) == [0, 1, 2] and s.feedback == sorted(s.feedback)


def test_a_missed_waypoint_aborts_the_goal_with_stop_on_failure(stack):
    s = stack({1: GoalEnd.ABORTED}, **NO_PAUSE)
    s.activate()
    end = s.result(s.send())
    assert end.status == GoalStatus.STATUS_ABORTED
    # Nav2's STOP_ON_MISSED_WAYPOINT where the message has it; Jazzy's has not: UNKNOWN, said in the message
    assert end.result.error_code == getattr(Result, "STOP_ON_MISSED_WAYPOINT", Result.UNKNOWN)
    assert "waypoint 1 was missed" in end.result.error_msg
    assert [(m.index, m.error_code, m.goal.pose.position.x) for m in end.result.missed_waypoints] == \
        [(1, ABORT_CODE, 1.0)]
    assert s.navigator.indices() == [0, 1]  # waypoint 2 never sent


def test_without_stop_on_failure_a_missed_waypoint_is_listed_and_the_rest_visited(stack):
    s = stack({1: GoalEnd.ABORTED}, stop_on_failure=False, **NO_PAUSE)
    s.activate()
    end = s.result(s.send(number_of_loops=1))
    assert end.status == GoalStatus.STATUS_SUCCEEDED
    assert [(m.index, m.error_code) for m in end.result.missed_waypoints] == [(1, ABORT_CODE), (1, ABORT_CODE)]
    assert s.navigator.indices() == [0, 1, 2, 0, 1, 2]


def test_goal_index_starts_part_way_and_one_out_of_range_is_refused(stack):
    s = stack(**NO_PAUSE)
    s.activate()
    assert s.result(s.send(goal_index=1)).status == GoalStatus.STATUS_SUCCEEDED
    assert s.navigator.indices() == [1, 2]
    end = s.result(s.send(goal_index=3))
    assert end.status == GoalStatus.STATUS_ABORTED
    assert end.result.error_code == getattr(Result, "NO_VALID_WAYPOINTS", Result.UNKNOWN)
    assert "goal_index 3 is out of range" in end.result.error_msg
    assert s.navigator.indices() == [1, 2]


def test_cancel_cancels_the_running_navigation_and_ends_canceled(stack):
    s = stack({1: None}, **NO_PAUSE)
    s.activate()
    handle = s.send()
    wait_until(lambda: s.navigator.indices() == [0, 1], 30, "navigation to waypoint 1", node=s.node)
    handle.cancel_goal_async()
    end = s.result(handle)
    assert end.status == GoalStatus.STATUS_CANCELED
    wait_until(lambda: s.navigator.canceled == [1], 10, "the navigation canceled", node=s.node)
    assert s.navigator.indices() == [0, 1]


def test_a_new_goal_preempts_the_running_one(stack):
    s = stack({1: None}, **NO_PAUSE)
    s.activate()
    first = s.send()
    wait_until(lambda: s.navigator.indices() == [0, 1], 30, "navigation to waypoint 1", node=s.node)
    second = s.send(count=1)
    assert s.result(first).status == GoalStatus.STATUS_ABORTED
    assert s.result(second).status == GoalStatus.STATUS_SUCCEEDED
    assert s.navigator.indices() == [0, 1, 0]


def sim_clock(s: Stack, start_s: float) -> Any:
    """A /clock publisher, the follower on it at ``start_s``."""
    clock = s.node.create_publisher(Clock, "/clock", 10)
    wait_until(clock.get_subscription_count, 10, "the follower's /clock subscription", node=s.node)

    def at(t_s: float) -> None:
        clock.publish(Clock(clock=Time(sec=int(t_s), nanosec=int(round((t_s % 1) * 1e9)))))
    at(start_s)
    wait_until(lambda: s.follower.get_clock().now().nanoseconds >= int(start_s * 1e9), 10, "sim time", node=s.node)
    return at


def test_wait_at_waypoint_pauses_on_the_nodes_clock(stack):
    s = stack(use_sim_time=True, **{"wait_at_waypoint.waypoint_pause_duration": 2000})
    at = sim_clock(s, 100.0)
    s.activate()
    handle = s.send(count=2)
    now = [100.0]

    def advance() -> None:  # sim time moves only once the first waypoint is reached
        if len(s.navigator.goals) >= 1 and not s.navigator.pending:
            now[0] += 0.25
            at(now[0])
    assert s.result(handle, advance).status == GoalStatus.STATUS_SUCCEEDED
    (_, first), (_, second) = s.navigator.goals
    assert first == 100.0
    assert second - first >= 2.0  # the pause, in sim time


def test_with_the_wait_disabled_the_waypoints_follow_on_a_stopped_clock(stack):
    s = stack(use_sim_time=True, **{"wait_at_waypoint.enabled": False})
    sim_clock(s, 100.0)
    s.activate()
    end = s.result(s.send(count=3))
    assert end.status == GoalStatus.STATUS_SUCCEEDED
    assert [stamp for _, stamp in s.navigator.goals] == [100.0, 100.0, 100.0]


def test_bad_parameters_and_plugins_are_refused_naming_them(stack):
    with pytest.raises(ParameterError, match="loop_rate"):
        WaypointFollower(parameter_overrides=[Parameter("loop_rate", value=0)])
    with pytest.raises(ParameterError, match="waypoint_task_executor_plugin"):
        WaypointFollower(parameter_overrides=[Parameter("waypoint_task_executor_plugin", value="photo_at_waypoint")])
    s = stack(**{"wait_at_waypoint.plugin": "nav2_waypoint_follower::PhotoAtWaypoint"})
    assert not s.change(Transition.TRANSITION_CONFIGURE)
    assert "'nav2_waypoint_follower::PhotoAtWaypoint'" in s.follower.configure_failure
    assert "'nav2_waypoint_follower::WaitAtWaypoint'" in s.follower.configure_failure
