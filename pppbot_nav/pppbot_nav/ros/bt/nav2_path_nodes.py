"""Nav2's nodes that work on paths, goals and the navigator's choices, and its decorators that
tick their child on distance, speed, a new goal or a longer path (Nav2 Jazzy's ports, defaults
and answers): ``TruncatePath``, ``TruncatePathLocal``, ``RemovePassedGoals``, ``GetPoseFromPath``,
the five selectors, ``GoalUpdater``, ``DistanceController``, ``SpeedController``,
``GoalUpdatedController`` and ``PathLongerOnApproach``."""
from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry
from nav_msgs.msg import Path as PathMsg
from std_msgs.msg import String

from pppbot_common.se2 import quaternion_from_yaw, wrap_angles, yaw_from_quaternion
from pppbot_nav.bt.builtin import Decorator
from pppbot_nav.bt.ports import setting
from pppbot_nav.bt.tree import NodeConfig, Status, TreeNode, input_port, output_port
from pppbot_nav.errors import BehaviorTreeError
from pppbot_nav.ros.bt.nav2_actions import ports_of
from pppbot_nav.ros.bt.nav2_conditions import _goal_and_goals, _same, robot_pose_in


def path_xy(path: Any) -> np.ndarray:
    """A nav_msgs/Path's positions (K, 2)."""
    return np.array([[p.pose.position.x, p.pose.position.y] for p in path.poses], dtype=float).reshape(-1, 2)


def path_length(path: Any) -> float:
    xy = path_xy(path)
    return float(np.hypot(*np.diff(xy, axis=0).T).sum()) if len(xy) > 1 else 0.0


def _with_poses(path: Any, poses: list[Any]) -> PathMsg:
    out = PathMsg()
    out.header = path.header
    out.poses = poses
    return out


class TruncatePath(TreeNode):
    """``input_path`` without its last poses closer than ``distance`` m (straight line) to its end,
    keeping at least two; the new last pose faces the old end."""

    PORTS = (input_port("input_path", None), input_port("distance", float, 1.0), output_port("output_path"))

    def tick(self) -> Status:
        path = self.get_input("input_path")
        if not path.poses:
            self.set_output("output_path", path)
            return Status.SUCCESS
        end = path.poses[-1].pose.position
        distance = self.get_input("distance")
        keep = len(path.poses)
        while keep > 2 and math.hypot(end.x - path.poses[keep - 1].pose.position.x,
                                      end.y - path.poses[keep - 1].pose.position.y) < distance:
            keep -= 1
        poses = list(path.poses[:keep])
        last = poses[-1].pose.position
        heading = math.atan2(end.y - last.y, end.x - last.x)
        turned = PoseStamped(header=poses[-1].header)
        turned.pose.position = last
        o = turned.pose.orientation
        o.x, o.y, o.z, o.w = quaternion_from_yaw(heading if math.isfinite(heading) else 0.0)
        poses[-1] = turned
        self.set_output("output_path", _with_poses(path, poses))
        return Status.SUCCESS


class TruncatePathLocal(TreeNode):
    """The stretch of ``input_path`` from ``distance_backward`` m behind the robot's closest pose to
    ``distance_forward`` m ahead of it (the robot: ``pose``, else TF of ``robot_frame``)."""

    PORTS = (input_port("input_path", None), input_port("distance_forward", float, 8.0),
             input_port("distance_backward", float, 4.0), input_port("robot_frame", str, "base_link"),
             input_port("transform_tolerance", float, 0.2), input_port("pose", None, None),
             input_port("angular_distance_weight", float, 0.0),
             input_port("max_robot_pose_search_dist", float, math.inf), output_port("output_path"))

    def tick(self) -> Status:
        path = self.get_input("input_path")
        if not path.poses:
            self.set_output("output_path", path)
            return Status.SUCCESS
        pose = self.get_input("pose")
        if pose is not None:
            robot = (pose.pose.position.x, pose.pose.position.y, yaw_from_quaternion(
                pose.pose.orientation.x, pose.pose.orientation.y, pose.pose.orientation.z, pose.pose.orientation.w))
        else:
            found = ports_of(self).transform(path.header.frame_id, self.get_input("robot_frame"))
            if found is None:
                return Status.FAILURE
            robot = found
        xy = path_xy(path)
        yaw = np.array([yaw_from_quaternion(p.pose.orientation.x, p.pose.orientation.y, p.pose.orientation.z,
                                            p.pose.orientation.w) for p in path.poses])
        weight = self.get_input("angular_distance_weight")
        steps = np.r_[0.0, np.cumsum(np.hypot(*np.diff(xy, axis=0).T))]
        searchable = steps <= self.get_input("max_robot_pose_search_dist")
        cost = np.hypot(np.hypot(xy[:, 0] - robot[0], xy[:, 1] - robot[1]), weight * wrap_angles(yaw - robot[2]))
        closest = int(np.argmin(np.where(searchable, cost, np.inf)))
        along = steps - steps[closest]
        inside = (along >= -self.get_input("distance_backward")) & (along <= self.get_input("distance_forward"))
        kept = [p for p, keep in zip(path.poses, inside, strict=True) if keep]
        self.set_output("output_path", _with_poses(path, kept))
        return Status.SUCCESS


class RemovePassedGoals(TreeNode):
    """``input_goals`` without those at its front the robot came within ``radius`` m of (the last
    goal is never removed)."""

    PORTS = (input_port("input_goals", None), output_port("output_goals"), input_port("radius", float, 0.5),
             input_port("robot_base_frame", str, None))

    def tick(self) -> Status:
        goals = list(self.get_input("input_goals"))
        if not goals:
            self.set_output("output_goals", goals)
            return Status.SUCCESS
        robot = robot_pose_in(self, goals[0].header.frame_id or setting(self.config.blackboard, "global_frame"))
        if robot is None:
            return Status.FAILURE
        radius = self.get_input("radius")
        while len(goals) > 1 and math.hypot(goals[0].pose.position.x - robot[0],
                                            goals[0].pose.position.y - robot[1]) <= radius:
            goals.pop(0)
        self.set_output("output_goals", goals)
        return Status.SUCCESS


class GetPoseFromPath(TreeNode):
    """The pose at ``index`` of ``path`` (negative: from its end); FAILURE when there is none."""

    PORTS = (input_port("path", None), input_port("index", int, 0), output_port("pose"))

    def tick(self) -> Status:
        path = self.get_input("path")
        index = self.get_input("index")
        if not -len(path.poses) <= index < len(path.poses):
            return Status.FAILURE
        pose = path.poses[index]
        if not pose.header.frame_id:
            pose = PoseStamped(header=path.header, pose=pose.pose)
        self.set_output("pose", pose)
        return Status.SUCCESS


class _Selector(TreeNode):
    """The newest name heard on ``topic_name`` (latched), else ``default_<kind>``, written to
    ``selected_<kind>``; FAILURE when neither is there."""

    KIND: ClassVar[str]

    def tick(self) -> Status:
        heard = ports_of(self).latest(self.get_input("topic_name"), String, latched=True)
        selected = heard.data if heard is not None else self.get_input(f"default_{self.KIND}")
        if not selected:
            return Status.FAILURE
        self.set_output(f"selected_{self.KIND}", selected)
        return Status.SUCCESS


def _selector(kind: str) -> type[_Selector]:
    name = "".join(part.title() for part in kind.split("_")) + "Selector"
    return type(name, (_Selector,), {"KIND": kind, "PORTS": (
        input_port("topic_name", str, f"{kind}_selector"), input_port(f"default_{kind}", str, ""),
        output_port(f"selected_{kind}"))})


# -- decorators ---------------------------------------------------------------------------------------


class GoalUpdater(Decorator):
    """``output_goal`` = the newest goal heard on the navigator's ``goal_updater_topic`` when it is
    newer than ``input_goal``, else ``input_goal``; then the child's answer."""

    PORTS = (input_port("input_goal", None), output_port("output_goal"))

    def tick(self) -> Status:
        goal = self.get_input("input_goal")
        heard = ports_of(self).latest(setting(self.config.blackboard, "goal_updater_topic"), PoseStamped)
        if heard is not None and _stamp_s(heard) > _stamp_s(goal):
            goal = heard
        self.set_output("output_goal", goal)
        return self.child.execute_tick()


def _stamp_s(msg: Any) -> float:
    return float(msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9)


class _Throttle(Decorator):
    """A decorator that ticks its child on its first tick, while the child runs, and when
    :meth:`due` says; between, RUNNING (as Nav2's RateController)."""

    def __init__(self, name: str, config: NodeConfig | None = None) -> None:
        super().__init__(name, config)
        self.first = True

    def start(self) -> bool:
        """A new run begins (False: it cannot, FAILURE)."""
        return True

    def due(self) -> bool:
        raise NotImplementedError

    def on_child_success(self) -> None:
        pass

    def tick(self) -> Status:
        if self.status in (Status.IDLE, Status.SKIPPED):
            self.first = True
            if not self.start():
                return Status.FAILURE
        if self.first or self.child.status is Status.RUNNING or self.due():
            self.first = False
            status = self.child.execute_tick()
            if status in (Status.RUNNING, Status.SKIPPED):
                return status
            if status is Status.SUCCESS:
                self.on_child_success()
            self.child.reset()
            return status
        return Status.RUNNING


class DistanceController(_Throttle):
    """Ticks its child each ``distance`` m the robot travels (straight line, in ``global_frame``)."""

    PORTS = (input_port("distance", float, 1.0), input_port("global_frame", str, None),
             input_port("robot_base_frame", str, None))
    since: tuple[float, float, float] | None = None

    def _pose(self) -> tuple[float, float, float] | None:
        return robot_pose_in(self, self.get_input("global_frame") or setting(self.config.blackboard, "global_frame"))

    def start(self) -> bool:
        self.since = self._pose()
        return self.since is not None

    def due(self) -> bool:
        pose = self._pose()
        return pose is not None and self.since is not None and \
            math.hypot(pose[0] - self.since[0], pose[1] - self.since[1]) >= self.get_input("distance")

    def on_child_success(self) -> None:
        self.since = self._pose() or self.since


class SpeedController(_Throttle):
    """Ticks its child at a rate between ``min_rate`` and ``max_rate`` (Hz) growing with the robot's
    speed between ``min_speed`` and ``max_speed`` (m/s, from odometry); a new goal starts it anew."""

    PORTS = (input_port("min_rate", float, 0.1), input_port("max_rate", float, 1.0),
             input_port("min_speed", float, 0.0), input_port("max_speed", float, 0.5),
             input_port("goal", None, None), input_port("goals", None, None))

    def __init__(self, name: str, config: NodeConfig | None = None) -> None:
        super().__init__(name, config)
        self.since = 0.0
        self.period = 1.0
        self.goals: tuple[Any, Any] = (None, None)

    def _check(self) -> tuple[float, float, float, float]:
        rates = (self.get_input("min_rate"), self.get_input("max_rate"))
        speeds = (self.get_input("min_speed"), self.get_input("max_speed"))
        if not (rates[0] > 0 and rates[1] > 0):
            raise BehaviorTreeError(f"{self._where()}SpeedController '{self.name}': min_rate = {rates[0]} and "
                                    f"max_rate = {rates[1]} must be above 0")
        if not speeds[1] > speeds[0]:
            raise BehaviorTreeError(f"{self._where()}SpeedController '{self.name}': max_speed = {speeds[1]} must "
                                    f"be above min_speed = {speeds[0]}")
        return (*rates, *speeds)

    def start(self) -> bool:
        self.period = 1.0 / self._check()[1]
        self.since = self.now()
        self.goals = _goal_and_goals(self)
        return True

    def tick(self) -> Status:
        current = _goal_and_goals(self)
        if self.status not in (Status.IDLE, Status.SKIPPED) and not (
                _same(current[0], self.goals[0]) and _same(current[1], self.goals[1])):
            self.start()
            self.first = True
        return super().tick()

    def due(self) -> bool:
        if self.now() - self.since < self.period:
            return False
        min_rate, max_rate, min_speed, max_speed = self._check()
        odom = ports_of(self).latest(setting(self.config.blackboard, "odom_topic"), Odometry)
        speed = 0.0 if odom is None else math.hypot(odom.twist.twist.linear.x, odom.twist.twist.linear.y)
        share = min(1.0, max(0.0, (speed - min_speed) / (max_speed - min_speed)))
        self.period = 1.0 / (min_rate + share * (max_rate - min_rate))
        self.since = self.now()
        return True


class GoalUpdatedController(Decorator):
    """Ticks its child when ``goal`` or ``goals`` changed since it last did (and on its first tick,
    and while the child runs); between, RUNNING."""

    PORTS = (input_port("goal", None, None), input_port("goals", None, None))

    def __init__(self, name: str, config: NodeConfig | None = None) -> None:
        super().__init__(name, config)
        self.seen: tuple[Any, Any] = (None, None)
        self.updated = True

    def tick(self) -> Status:
        current = _goal_and_goals(self)
        changed = not (_same(current[0], self.seen[0]) and _same(current[1], self.seen[1]))
        if self.status in (Status.IDLE, Status.SKIPPED) or changed:
            self.seen, self.updated = current, True
        if self.child.status is Status.RUNNING or self.updated:
            self.updated = False
            status = self.child.execute_tick()
            if status.completed:
                self.child.reset()
            return status
        return Status.RUNNING


class PathLongerOnApproach(Decorator):
    """Ticks its child (a wait, say) when, within ``prox_len`` m of the goal, a new path to the same
    goal is more than ``length_factor`` times the old one; otherwise SUCCESS."""

    PORTS = (input_port("path", None), input_port("prox_len", float, 3.0), input_port("length_factor", float, 2.0))

    def __init__(self, name: str, config: NodeConfig | None = None) -> None:
        super().__init__(name, config)
        self.old: Any = None

    def tick(self) -> Status:
        new = self.get_input("path")
        old = self.old
        if self.child.status is Status.RUNNING or (old is not None and self._longer_on_approach(old, new)):
            status = self.child.execute_tick()
            if status in (Status.RUNNING, Status.SKIPPED):
                return status
            self.old = new
            self.child.reset()
            return status
        self.old = new
        return Status.SUCCESS

    def _longer_on_approach(self, old: Any, new: Any) -> bool:
        if not old.poses or not new.poses or len(old.poses) == len(new.poses):
            return False
        a, b = old.poses[-1].pose.position, new.poses[-1].pose.position
        if (a.x, a.y) != (b.x, b.y):  # another goal: a new approach
            return False
        old_length = path_length(old)
        longer = path_length(new) > self.get_input("length_factor") * old_length
        return old_length < self.get_input("prox_len") and longer


#: these nodes, by their XML names
NAV2_PATH_NODES: dict[str, type[TreeNode]] = {
    "TruncatePath": TruncatePath, "TruncatePathLocal": TruncatePathLocal, "RemovePassedGoals": RemovePassedGoals,
    "GetPoseFromPath": GetPoseFromPath,
    "PlannerSelector": _selector("planner"), "ControllerSelector": _selector("controller"),
    "GoalCheckerSelector": _selector("goal_checker"), "ProgressCheckerSelector": _selector("progress_checker"),
    "SmootherSelector": _selector("smoother"),
    "GoalUpdater": GoalUpdater, "DistanceController": DistanceController, "SpeedController": SpeedController,
    "GoalUpdatedController": GoalUpdatedController, "PathLongerOnApproach": PathLongerOnApproach,
}
