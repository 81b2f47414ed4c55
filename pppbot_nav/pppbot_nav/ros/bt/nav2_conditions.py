"""Nav2's condition nodes, with Nav2 Jazzy's ports and defaults: SUCCESS or FAILURE on each tick
(``IsPathValid`` alone answers RUNNING while its service has not answered: pppbot's ticks never
block, where Nav2's condition waits within the tick).

Where Nav2's nodes read the navigator's parameters (``global_frame``, ``robot_base_frame``,
``goal_reached_tol``, ``odom_topic``), these read the blackboard entries the navigator sets
(:data:`~pppbot_nav.bt.ports.NAVIGATOR_DEFAULTS`).
"""
from __future__ import annotations

import math
from typing import Any, ClassVar

from nav2_msgs import action as nav2_action
from nav2_msgs import srv as nav2_srv
from nav_msgs.msg import Odometry
from sensor_msgs.msg import BatteryState

from pppbot_nav.bt.ports import ServiceCall, setting
from pppbot_nav.bt.tree import NodeConfig, Port, Status, TreeNode, as_bool, input_port
from pppbot_nav.errors import BehaviorTreeError
from pppbot_nav.ros.bt.nav2_actions import ports_of, server_timeout_s

#: a deceleration beyond this (m/s², forward speed) means the robot hit something (Nav2's IsStuck)
STUCK_DECELERATION = 10.0


def _answer(condition: bool) -> Status:
    return Status.SUCCESS if condition else Status.FAILURE


def _goal_and_goals(node: TreeNode) -> tuple[Any, Any]:
    """The ``goal`` and ``goals`` ports, else the blackboard's entries of those names."""
    board = node.config.blackboard
    goal = node.get_input("goal")
    goals = node.get_input("goals")
    return (board.get("goal") if goal is None else goal), (board.get("goals") if goals is None else goals)


def _same(a: Any, b: Any) -> bool:
    return a is b or a == b


class GoalUpdated(TreeNode):
    """SUCCESS when ``goal`` or ``goals`` changed since the last tick; FAILURE on the first tick."""

    PORTS = (input_port("goal", None, None), input_port("goals", None, None))

    def __init__(self, name: str, config: NodeConfig | None = None) -> None:
        super().__init__(name, config)
        self.seen: tuple[Any, Any] = (None, None)

    def tick(self) -> Status:
        current = _goal_and_goals(self)
        if self.status in (Status.IDLE, Status.SKIPPED):
            self.seen = current
            return Status.FAILURE
        if _same(current[0], self.seen[0]) and _same(current[1], self.seen[1]):
            return Status.FAILURE
        self.seen = current
        return Status.SUCCESS


class GlobalUpdatedGoal(GoalUpdated):
    """As GoalUpdated, but what it saw lasts through resets, and its very first tick is a SUCCESS."""

    def __init__(self, name: str, config: NodeConfig | None = None) -> None:
        super().__init__(name, config)
        self.first = True

    def tick(self) -> Status:
        current = _goal_and_goals(self)
        if self.first:
            self.first = False
            self.seen = current
            return Status.SUCCESS
        if _same(current[0], self.seen[0]) and _same(current[1], self.seen[1]):
            return Status.FAILURE
        self.seen = current
        return Status.SUCCESS


def robot_pose_in(node: TreeNode, frame: str) -> tuple[float, float, float] | None:
    """The robot's (x, y, yaw) in ``frame`` (its base frame: the ``robot_base_frame`` port, else the navigator's)."""
    base = node.get_input("robot_base_frame") if "robot_base_frame" in node._ports else None
    return ports_of(node).transform(frame, base or setting(node.config.blackboard, "robot_base_frame"))


class GoalReached(TreeNode):
    """SUCCESS once the robot is within the navigator's ``goal_reached_tol`` (m) of ``goal``."""

    PORTS = (input_port("goal", None), input_port("robot_base_frame", str, None))

    def tick(self) -> Status:
        goal = self.get_input("goal")
        frame = goal.header.frame_id or setting(self.config.blackboard, "global_frame")
        robot = robot_pose_in(self, frame)
        if robot is None:
            return Status.FAILURE
        tolerance = float(setting(self.config.blackboard, "goal_reached_tol"))
        return _answer(math.hypot(goal.pose.position.x - robot[0], goal.pose.position.y - robot[1]) <= tolerance)


class IsPathValid(TreeNode):
    """Asks the planner server's ``is_path_valid`` about ``path``: SUCCESS when valid; FAILURE when
    not or no answer within ``server_timeout`` ms; RUNNING while waiting."""

    PORTS = (input_port("path", None), input_port("server_timeout", float, None))

    def __init__(self, name: str, config: NodeConfig | None = None) -> None:
        super().__init__(name, config)
        self.call: ServiceCall | None = None
        self.sent_s = 0.0

    def tick(self) -> Status:
        if self.call is None:
            request = nav2_srv.IsPathValid.Request(path=self.get_input("path"))
            self.call = ports_of(self).service("is_path_valid", nav2_srv.IsPathValid).call(request)
            self.sent_s = self.now()
        if self.call.refused():  # no planner serving it
            self.call = None
            return Status.FAILURE
        response = self.call.response()
        if response is None:
            if self.now() - self.sent_s < server_timeout_s(self):
                return Status.RUNNING
            self.call = None
            return Status.FAILURE
        self.call = None
        return _answer(bool(response.is_valid))

    def halt(self) -> None:
        self.call = None


class IsStuck(TreeNode):
    """SUCCESS when odometry's forward speed fell faster than :data:`STUCK_DECELERATION` between its
    last two messages (a collision's stop, as Nav2's)."""

    def __init__(self, name: str, config: NodeConfig | None = None) -> None:
        super().__init__(name, config)
        self.previous: tuple[float, float] | None = None  # (stamp s, forward speed) of the message before
        self.newest: tuple[float, float] | None = None

    def tick(self) -> Status:
        msg = ports_of(self).latest(setting(self.config.blackboard, "odom_topic"), Odometry)
        if msg is not None:
            sample = (msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9, float(msg.twist.twist.linear.x))
            if self.newest is None or sample[0] > self.newest[0]:
                self.previous, self.newest = self.newest, sample
        if self.previous is None or self.newest is None:
            return Status.FAILURE
        dt = self.newest[0] - self.previous[0]
        return _answer(dt > 0 and (self.newest[1] - self.previous[1]) / dt < -STUCK_DECELERATION)


class TimeExpired(TreeNode):
    """FAILURE until ``seconds`` of the tree's clock passed since its first tick (or its last
    SUCCESS), then SUCCESS once and it counts again."""

    PORTS = (input_port("seconds", float, 1.0),)
    start = 0.0

    def tick(self) -> Status:
        if self.status in (Status.IDLE, Status.SKIPPED):
            self.start = self.now()
            return Status.FAILURE
        if self.now() - self.start < self.get_input("seconds"):
            return Status.FAILURE
        self.start = self.now()
        return Status.SUCCESS


class DistanceTraveled(TreeNode):
    """FAILURE until the robot moved ``distance`` m (straight line, in ``global_frame``) since its
    first tick or last SUCCESS."""

    PORTS = (input_port("distance", float, 1.0), input_port("global_frame", str, None),
             input_port("robot_base_frame", str, None))
    start: tuple[float, float, float] | None = None

    def tick(self) -> Status:
        frame = self.get_input("global_frame") or setting(self.config.blackboard, "global_frame")
        pose = robot_pose_in(self, frame)
        if self.status in (Status.IDLE, Status.SKIPPED) or self.start is None:
            self.start = pose
            return Status.FAILURE
        if pose is None or math.hypot(pose[0] - self.start[0], pose[1] - self.start[1]) < self.get_input("distance"):
            return Status.FAILURE
        self.start = pose
        return Status.SUCCESS


class TransformAvailable(TreeNode):
    """SUCCESS once TF has given ``parent`` → ``child`` (and from then on)."""

    PORTS = (input_port("child", str, ""), input_port("parent", str, ""))
    found = False

    def tick(self) -> Status:
        if self.found:
            return Status.SUCCESS
        child, parent = self.get_input("child"), self.get_input("parent")
        if not child or not parent:
            raise BehaviorTreeError(f"{self._where()}TransformAvailable '{self.name}': child and parent frames "
                                    f"must both be named (child = '{child}', parent = '{parent}')")
        self.found = ports_of(self).transform(parent, child) is not None
        return _answer(self.found)


class InitialPoseReceived(TreeNode):
    """SUCCESS when ``initial_pose_received`` (its port, else the blackboard's entry) is true."""

    PORTS = (input_port("initial_pose_received", as_bool, None),)

    def tick(self) -> Status:
        value = self.get_input("initial_pose_received")
        return _answer(bool(self.config.blackboard.get("initial_pose_received", False) if value is None else value))


class IsBatteryLow(TreeNode):
    """SUCCESS when the newest ``battery_topic`` message's percentage (or voltage, with ``is_voltage``)
    is at most ``min_battery``; FAILURE before one came."""

    PORTS = (input_port("min_battery", float), input_port("battery_topic", str, "/battery_status"),
             input_port("is_voltage", as_bool, False))

    def tick(self) -> Status:
        msg = ports_of(self).latest(self.get_input("battery_topic"), BatteryState)
        if msg is None:
            return Status.FAILURE
        level = msg.voltage if self.get_input("is_voltage") else msg.percentage
        return _answer(level <= self.get_input("min_battery"))


class IsBatteryCharging(TreeNode):
    """SUCCESS when the newest ``battery_topic`` message says it is charging."""

    PORTS = (input_port("battery_topic", str, "/battery_status"),)

    def tick(self) -> Status:
        msg = ports_of(self).latest(self.get_input("battery_topic"), BatteryState)
        return _answer(msg is not None and msg.power_supply_status == BatteryState.POWER_SUPPLY_STATUS_CHARGING)


def error_codes(text: str) -> frozenset[int]:
    """BehaviorTree.CPP's list of integers: ``"104;105"`` (``,`` taken too)."""
    try:
        return frozenset(int(part) for part in text.replace(",", ";").split(";") if part.strip())
    except ValueError:
        raise ValueError(f"'{text}' is not a list of error codes (integers separated by ';')") from None


class AreErrorCodesPresent(TreeNode):
    """SUCCESS when ``error_code`` is one of ``error_codes_to_check``."""

    PORTS: ClassVar[tuple[Port, ...]] = (input_port("error_code", int), input_port("error_codes_to_check", error_codes))

    def codes(self) -> frozenset[int]:
        return frozenset(self.get_input("error_codes_to_check"))

    def tick(self) -> Status:
        return _answer(int(self.get_input("error_code")) in self.codes())


class _WouldRecoveryHelp(AreErrorCodesPresent):
    """SUCCESS when ``error_code`` is one a recovery may help with (Nav2's fixed lists)."""

    PORTS = (input_port("error_code", int),)
    CODES: ClassVar[frozenset[int]] = frozenset()

    def codes(self) -> frozenset[int]:
        return self.CODES


def _codes(result: Any, *names: str) -> frozenset[int]:
    return frozenset(int(getattr(result, name)) for name in names)


class WouldAPlannerRecoveryHelp(_WouldRecoveryHelp):
    CODES = _codes(nav2_action.ComputePathToPose.Result, "UNKNOWN", "NO_VALID_PATH", "TIMEOUT")


class WouldAControllerRecoveryHelp(_WouldRecoveryHelp):
    CODES = _codes(nav2_action.FollowPath.Result, "UNKNOWN", "PATIENCE_EXCEEDED", "FAILED_TO_MAKE_PROGRESS",
                   "NO_VALID_CONTROL")


class WouldASmootherRecoveryHelp(_WouldRecoveryHelp):
    CODES = _codes(nav2_action.SmoothPath.Result, "UNKNOWN", "TIMEOUT", "FAILED_TO_SMOOTH_PATH",
                   "SMOOTHED_PATH_IN_COLLISION")


class PathExpiringTimer(TreeNode):
    """FAILURE until ``seconds`` passed since ``path`` last changed (or since it last answered
    SUCCESS), then SUCCESS once."""

    PORTS = (input_port("seconds", float, 1.0), input_port("path", None))

    def __init__(self, name: str, config: NodeConfig | None = None) -> None:
        super().__init__(name, config)
        self.start: float | None = None
        self.path: Any = None

    def tick(self) -> Status:
        path = self.get_input("path")
        if self.start is None or not _same(path, self.path):
            self.start, self.path = self.now(), path
            return Status.FAILURE
        if self.now() - self.start < self.get_input("seconds"):
            return Status.FAILURE
        self.start = self.now()
        return Status.SUCCESS


#: Nav2's condition nodes, by their XML names
NAV2_CONDITION_NODES: dict[str, type[TreeNode]] = {
    "GoalUpdated": GoalUpdated, "GlobalUpdatedGoal": GlobalUpdatedGoal, "GoalReached": GoalReached,
    "IsPathValid": IsPathValid, "IsStuck": IsStuck, "TimeExpired": TimeExpired,
    "DistanceTraveled": DistanceTraveled, "TransformAvailable": TransformAvailable,
    "InitialPoseReceived": InitialPoseReceived, "IsBatteryLow": IsBatteryLow, "IsBatteryCharging": IsBatteryCharging,
    "AreErrorCodesPresent": AreErrorCodesPresent, "WouldAPlannerRecoveryHelp": WouldAPlannerRecoveryHelp,
    "WouldAControllerRecoveryHelp": WouldAControllerRecoveryHelp,
    "WouldASmootherRecoveryHelp": WouldASmootherRecoveryHelp, "PathExpiringTimer": PathExpiringTimer,
}
