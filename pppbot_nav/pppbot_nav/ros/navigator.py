"""``bt_navigator``: goals to the robot's arrival, in Nav2's ``bt_navigator`` place, by running a
behaviour tree.

Accepts goals as the ``navigate_to_pose`` action (nav2_msgs/action/NavigateToPose), on
``goal_pose`` (geometry_msgs/PoseStamped, RViz's "2D Goal Pose") and as the
``navigate_through_poses`` action (nav2_msgs/action/NavigateThroughPoses). Each goal runs a tree
(BehaviorTree.CPP 4 XML, :mod:`pppbot_nav.bt`): the goal's ``behavior_tree`` file, else
``default_nav_to_pose_bt_xml`` / ``default_nav_through_poses_bt_xml``, else pppbot's own default
trees (:mod:`pppbot_nav.ros.bt.nav2`: replanning at ``replanning_frequency`` while following, a
costmap cleared and one retry, then ``number_of_retries`` recoveries in a round robin). The tree
is ticked every ``bt_loop_duration`` ms of sim time, and at once when a server's prompt answer
(a goal accepted, a plan, a cleared costmap) came. A tree that cannot be loaded is refused
with the file and line: the default ones at configure, a goal's own by aborting the goal (as
Nav2 Jazzy's takes it and ends it).

A new goal for the tree that runs takes the place of the running one (which aborts) and the tree
ticks on with it, as Nav2's; a goal for another tree, or for the other navigator, is refused
while one runs (Nav2's onPreempt: cancel the running goal first).
Cancel halts the tree, which cancels what its nodes started.

Before the first tick the navigator waits (up to ``server_timeout`` s) for the clock, the planner
and controller servers and the robot's pose in ``global_frame``. Feedback: the robot's pose, the
navigation time, the distance left along the tree's path (``path_blackboard_id``), an estimated
time remaining, the recoveries so far (``number_recoveries``) and, through poses, the poses
remaining (``goals_blackboard_id``). A failed goal carries the smallest non-zero error code of
``error_code_names`` (Nav2's rule) and that node's message. The navigator commands no velocity
itself: the controller and the behaviours do.
"""
from __future__ import annotations

import importlib
import math
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from nav2_msgs.action import (
    ComputePathThroughPoses,
    ComputePathToPose,
    FollowPath,
    NavigateThroughPoses,
    NavigateToPose,
)
from rclpy.action.server import ServerGoalHandle
from rclpy.duration import Duration

from pppbot_common.params import check_finite_range, param
from pppbot_common.ros.params import declare_parameters, fixed_parameters
from pppbot_common.se2 import quaternion_from_yaw
from pppbot_common.transforms import TransformError
from pppbot_common.upright import UPRIGHT_STATUS
from pppbot_lockstep.ros.action_client import ActionClient
from pppbot_lockstep.ros.goals import Cancels, GoalEnd, GoalServer, send_feedback
from pppbot_lockstep.ros.lifecycle import ManagedNode
from pppbot_lockstep.ros.runner import Warnings, guarded, run_nodes
from pppbot_lockstep.ros.tf_listener import TfListener
from pppbot_nav.bt.tree import Status, Tree, TreeNode
from pppbot_nav.errors import BehaviorTreeError
from pppbot_nav.plugins import PluginError, plugins
from pppbot_nav.ros.bt.nav2_actions import RECOVERIES_KEY, ActionNode, ServiceNode
from pppbot_nav.ros.bt.navigation import NavigatorTrees, TreeSettings, error_of
from pppbot_nav.ros.bt_ports import RosPorts


@dataclass(frozen=True)
class NavigatorParameters:
    global_frame: str = param("map", "frame of goals and feedback")
    robot_base_frame: str = param("base_link", "the robot's frame")
    transform_tolerance: float = param(0.1, "s; given to the tree's nodes")
    default_nav_to_pose_bt_xml: str = param("", "tree file of navigate_to_pose goals (empty: pppbot's default)")
    default_nav_through_poses_bt_xml: str = param("", "tree file of navigate_through_poses goals (empty: "
                                                      "pppbot's default)")
    always_reload_bt_xml: bool = param(False, "load a goal's tree file again for each goal")
    plugin_lib_names: list = param([], "BT node libraries the trees may use: entry points of pppbot_nav.bt_plugins "
                                       "or Python modules with BT_NODES (XML name → class); "
                                       "Nav2's own library names are known already")
    error_code_names: list = param(["follow_path_error_code", "compute_path_error_code"],
                                   "blackboard entries whose smallest non-zero value is a failed goal's code")
    goal_blackboard_id: str = param("goal", "blackboard entry of a navigate_to_pose goal")
    goals_blackboard_id: str = param("goals", "blackboard entry of a navigate_through_poses goal's poses")
    path_blackboard_id: str = param("path", "blackboard entry of the path (the feedback's distance remaining)")
    bt_loop_duration: int = param(50, "ms of sim time between ticks (Nav2's default is 10: pppbot also ticks "
                                      "when a prompt answer comes, and in lockstep each tick is a round)")
    default_server_timeout: int = param(1000, "ms a tree's node waits for a server to take its goal or answer "
                                              "(Nav2's default is 20)")
    goal_reached_tol: float = param(0.25, "m; GoalReached's tolerance")
    odom_topic: str = param("odom", "odometry for the tree's nodes that read it")
    goal_updater_topic: str = param("goal_update", "GoalUpdater's topic of newer goals")
    replanning_frequency: float = param(1.0, "pppbot's default trees: plans per second while following (Hz)")
    number_of_retries: int = param(6, "pppbot's default trees: recoveries per goal before it fails")
    server_timeout: float = param(10.0, "s to wait before the first tick for the servers and the robot's pose")

    def validate(self) -> None:
        check_finite_range("replanning_frequency", self.replanning_frequency, 0.0, 100.0, low_open=True)
        check_finite_range("server_timeout", self.server_timeout, 0.0, 3600.0, low_open=True)
        check_finite_range("number_of_retries", self.number_of_retries, 0, 1000)
        check_finite_range("bt_loop_duration", self.bt_loop_duration, 1, 10_000)
        check_finite_range("default_server_timeout", self.default_server_timeout, 1, 3_600_000)
        check_finite_range("transform_tolerance", self.transform_tolerance, 0.0, 60.0)
        check_finite_range("goal_reached_tol", self.goal_reached_tol, 0.0, 100.0)

    def tree_settings(self) -> TreeSettings:
        return TreeSettings(
            default_nav_to_pose_bt_xml=self.default_nav_to_pose_bt_xml,
            default_nav_through_poses_bt_xml=self.default_nav_through_poses_bt_xml,
            always_reload_bt_xml=self.always_reload_bt_xml, server_timeout_ms=float(self.default_server_timeout),
            error_code_names=tuple(str(name) for name in self.error_code_names),
            goal_blackboard_id=self.goal_blackboard_id, goals_blackboard_id=self.goals_blackboard_id,
            path_blackboard_id=self.path_blackboard_id,
            entries={"global_frame": self.global_frame, "robot_base_frame": self.robot_base_frame,
                     "transform_tolerance": self.transform_tolerance, "goal_reached_tol": self.goal_reached_tol,
                     "odom_topic": self.odom_topic, "goal_updater_topic": self.goal_updater_topic,
                     "replanning_frequency": self.replanning_frequency,
                     "number_of_retries": self.number_of_retries, "initial_pose_received": False})


def plugin_nodes(libraries: list[str]) -> dict[str, type[TreeNode]]:
    """The BT nodes of ``plugin_lib_names``. Each name is a library of the ``pppbot_nav.bt_plugins``
    entry-point group (its value a mapping of XML names to node classes, as a package exports its
    nodes: :mod:`pppbot_nav.plugins`), or else a Python module with ``BT_NODES``, that mapping.
    Nav2's own library names (``nav2_*``) are skipped, their nodes being built in.

    Raises:
        BehaviorTreeError: a name that is neither, or a library that does not load.
    """
    group = plugins("behavior tree node library")
    found: dict[str, type[TreeNode]] = {}
    for name in map(str, libraries):
        if name.startswith("nav2_"):
            continue
        if name in group:
            try:
                nodes = group[name]
            except PluginError as exc:
                raise BehaviorTreeError(f"plugin_lib_names: {exc}") from exc
        else:
            try:
                module = importlib.import_module(name)
            except ImportError as exc:
                raise BehaviorTreeError(f"plugin_lib_names: '{name}' is neither an installed library ("
                                        f"{group.unknown(name)}) nor an importable Python module ({exc})") from exc
            nodes = getattr(module, "BT_NODES", None)
        if not isinstance(nodes, Mapping):
            raise BehaviorTreeError(f"plugin_lib_names: '{name}' gives no mapping of XML names to "
                                    "pppbot_nav.bt.tree.TreeNode classes (a module's BT_NODES)")
        found.update(nodes)
    return found


#: a planned path ending further than this from the goal means the planner moved the goal (m)
GOAL_MOVED_M = 0.05


def path_length_from(path: np.ndarray, xy: tuple[float, float]) -> float:
    """Length (m) along ``path`` (K, 2) from its point closest to ``xy`` to its end."""
    if len(path) == 0:
        return 0.0
    i = int(np.argmin(np.hypot(path[:, 0] - xy[0], path[:, 1] - xy[1])))
    rest = path[i:]
    return float(math.hypot(rest[0, 0] - xy[0], rest[0, 1] - xy[1]) + np.hypot(*np.diff(rest, axis=0).T).sum())


#: bt_navigator keys that mean nothing here, with the reason (named in the start-up warning when given).
NO_EFFECT = {
    "default_bt_xml_filename": "Humble's name: default_nav_to_pose_bt_xml",
    "navigators": "pppbot's bt_navigator runs navigate_to_pose and navigate_through_poses, fixed",
    "navigate_to_pose.*": "pppbot's navigators are fixed", "navigate_through_poses.*": "pppbot's navigators are fixed",
    "error_code_name_prefixes": "Kilted's; pppbot reads Jazzy's error_code_names",
    "wait_for_service_timeout": "the navigator waits for its servers up to server_timeout before the first tick",
    "enable_groot_monitoring": "no Groot", "groot_*": "no Groot",
    "filter_duration": "the feedback's speed comes from the robot's pose over the last ticks",
    "use_sim_time": "",
}
#: the robot's speed for the feedback's time estimate is its pose's change over this long (sim s)
SPEED_WINDOW_S = 0.3


class NotUpright(Exception):  # noqa: N818 (a signal of the navigator's own, not an error record)
    """The robot's base reports it is not upright: the goal ends at once, with no recovery."""


class _Run:
    """One goal's run of a tree."""

    def __init__(self, handle: ServerGoalHandle, tree: Tree | None, through: bool, start_s: float,
                 deadline_s: float, goal: PoseStamped) -> None:
        self.handle = handle
        self.tree = tree
        self.through = through
        self.action: Any = NavigateThroughPoses if through else NavigateToPose
        self.start_s = start_s
        self.deadline_s = deadline_s  # for the servers and the robot's pose, before the first tick
        self.goal = goal  # the last pose asked for
        self.ticking = False  # past the wait for servers and pose
        self.moved_note: str | None = None
        self.seen_path: Any = None
        self.poses: list[tuple[float, float, float]] = []  # (t, x, y) for the speed
        self.path_msg: Any = None  # the path the feedback measures along, and its points (K, 2)
        self.path_xy = np.zeros((0, 2))
        self.requested = ""  # the goal's behavior_tree field


#: Nav2's answer to a goal that would preempt the running one with another tree.
OTHER_TREE = ("preemption with another behavior_tree is refused, as Nav2's: it would need the running goal "
              "canceled, not preempted; cancel it and send this goal again")


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
        self.port.require_when("the compute_path_to_pose server", self.planner.server_is_ready)
        self.port.require_when("the compute_path_through_poses server", self.planner_through.server_is_ready)
        self.port.require_when("the follow_path server", self.controller.server_is_ready)
        self._active: _Run | None = None
        self._ticking = False
        self._again = False
        self.trees: NavigatorTrees | None = None
        self._self_client = ActionClient(self, NavigateToPose, "navigate_to_pose")
        self.server = GoalServer(self, NavigateToPose, "navigate_to_pose", self._on_goal, accept=self._accept)
        self.through_server = GoalServer(self, NavigateThroughPoses, "navigate_through_poses", self._on_through_goal,
                                         accept=self._accept)
        self.create_subscription(PoseStamped, "goal_pose", guarded(self, self._on_goal_pose, "PoseStamped"), 10)
        #: why the robot is not upright, from its base's /diagnostics (the simulator's, or a driver's); None: upright
        self.not_upright: str | None = None
        on_diagnostics = guarded(self, self._on_diagnostics, "DiagnosticArray")
        self.create_subscription(DiagnosticArray, "/diagnostics", on_diagnostics, 10)
        # Ticks while a goal runs (an idle navigator makes no sync times in lockstep).
        self.timer = self.step_timer(self.params.bt_loop_duration / 1000.0, self._tick)
        self.timer.cancel()
        self._cancels = Cancels(self._now_s, self.timer)  # goals the tree canceled, asked again until they end
        self.ports = RosPorts(self, self.tf, self._cancels, self._wake, self._warn)
        self.get_logger().info("bt_navigator: navigate_to_pose and goal_pose once active")

    def configure(self) -> None:
        """Load the default trees (a tree written wrong fails the configure, naming file and line)."""
        p = self.params
        self.trees = NavigatorTrees(p.tree_settings(), self._now_s, plugin_nodes(list(p.plugin_lib_names)),
                                    warn=self.get_logger().warning)
        for through in (False, True):
            self.trees.tree("", through)

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
        if not self.active:
            return
        goal = NavigateToPose.Goal()
        goal.pose = msg
        self.get_logger().info(f"goal_pose: ({msg.pose.position.x:.2f}, {msg.pose.position.y:.2f}) "
                               f"in '{msg.header.frame_id}'")
        self._self_client.send_goal_async(goal)

    def _accept(self, request: Any) -> bool:
        """Only while active (a goal whose tree cannot be loaded is taken and aborted, as Nav2's)."""
        return self.taking_goals() and self.trees is not None

    def _on_goal(self, handle: ServerGoalHandle) -> None:
        self._start(handle, [handle.request.pose], through=False)

    def _on_through_goal(self, handle: ServerGoalHandle) -> None:
        self._start(handle, list(handle.request.poses), through=True)

    def _start(self, handle: ServerGoalHandle, goals: list[PoseStamped], through: bool) -> None:
        assert self.trees is not None
        for goal in goals:
            if not goal.header.frame_id:
                goal.header.frame_id = self.params.global_frame
        previous = self._active
        now = self._now_s()
        try:
            tree = self.trees.tree(handle.request.behavior_tree, through)
        except Exception as exc:  # noqa: BLE001 - whatever the file is, the goal ends and the node goes on
            self.get_logger().error(f"goal aborted: its behavior_tree cannot be loaded: {exc}")
            self._finish(_Run(handle, None, through, now, now, PoseStamped()), GoalEnd.ABORTED, 0,
                         f"the behavior_tree cannot be loaded: {exc}")
            return
        if not goals:
            self._finish(_Run(handle, tree, through, now, now, PoseStamped()), GoalEnd.ABORTED, 0,
                         "no poses to navigate through")
            return
        at = goals[-1].pose.position
        self.get_logger().info(f"navigating to ({at.x:.2f}, {at.y:.2f}) in '{goals[-1].header.frame_id}'"
                               + (f" through {len(goals) - 1} poses" if through else ""))
        entries: dict[str, Any] = {"goals": goals} if through else {"goal": goals[0]}
        run = _Run(handle, tree, through, now, now + self.params.server_timeout, goals[-1])
        run.requested = handle.request.behavior_tree
        if previous is not None and (previous.through != through or (
                previous.tree is not tree and previous.requested != run.requested)):
            # Nav2's onPreempt: the new goal ends, the running one goes on.
            self.get_logger().warning(f"goal refused: {OTHER_TREE}")
            self._finish(run, GoalEnd.ABORTED, 0, OTHER_TREE)
            return
        run.seen_path = tree.blackboard.get(self.params.path_blackboard_id)  # an earlier goal's: no news
        if previous is not None and previous.tree is tree and previous.ticking:
            # Nav2's preemption: the new goal takes the running tree's blackboard; the old one aborts
            self.trees.update_goal(tree, **entries)
            run.ticking = True
            self._active = run
            self._end_preempted(previous)
        else:
            if previous is not None:  # the same tree, not yet ticking: started again for the new goal
                self._halt(previous)
                self._end_preempted(previous)
            self._active = run
            tree.forget_failures()
            try:
                self.trees.start(tree, self.ports, **entries)
            except Exception as exc:  # noqa: BLE001 - a tree that cannot start ends its goal, not the node
                self._fail(run, exc)
                return
        if self.timer.is_canceled():
            self.timer.reset()
        self._tick()

    def _end_preempted(self, previous: _Run) -> None:
        """The goal a new one took the place of: aborted, or canceled if its client had asked."""
        result = previous.action.Result()
        end = GoalEnd.CANCELED if previous.handle.is_cancel_requested else GoalEnd.ABORTED
        result.error_msg = "canceled" if end is GoalEnd.CANCELED else "preempted by a new goal"
        (self.through_server if previous.through else self.server).finish(previous.handle, end, result)

    def _halt(self, run: _Run) -> None:
        """Halt the run's tree (what its nodes started is canceled); a node that fails to halt is logged."""
        if run.tree is None:
            return
        try:
            run.tree.halt()
        except Exception as exc:  # noqa: BLE001 - the goal still ends
            self.get_logger().error(f"halting the behaviour tree failed: {type(exc).__name__}: {exc}")

    def _fail(self, run: _Run, exc: BaseException) -> None:
        """A tree's node raised: the goal aborts, naming it, and the node goes on."""
        self._halt(run)
        what = str(exc) if isinstance(exc, BehaviorTreeError) else f"{type(exc).__name__}: {exc}"
        self.get_logger().error(f"the behaviour tree failed: {what}")
        self._finish(run, GoalEnd.ABORTED, 0, f"the behaviour tree failed: {what}")

    def deactivate(self) -> None:
        """As Nav2's: a goal running when the navigator is deactivated ends (its tree halted)."""
        run = self._active
        if run is not None:
            self._halt(run)
            self._finish(run, GoalEnd.ABORTED, 0, "bt_navigator deactivated")

    # ---------------------------------------------------------------- ticking
    def _now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _pose(self, frame: str) -> tuple[float, float, float]:
        return self.tf.lookup(frame, self.params.robot_base_frame)

    def _wake(self) -> None:
        """A prompt answer came: tick again now (within the same step, in lockstep), without feedback
        (that goes out on the timer's ticks, at a steady rate)."""
        if self._active is not None and self._active.ticking:
            self._tick(feedback=False)

    def _tick(self, feedback: bool = True) -> None:
        if self._ticking:  # a wake from within a tick: once more after it
            self._again = True
            return
        self._ticking = True
        try:
            for _ in range(10):  # a prompt answer at once, a bounded number of times
                self._again = False
                self._tick_once(feedback)
                if not self._again:
                    break
                feedback = False
        finally:
            self._ticking = False

    def _tick_once(self, feedback: bool = True) -> None:
        run = self._active
        if run is None:
            if not self._cancels.tick():
                self.timer.cancel()
            return
        self._cancels.tick()
        stop = self._stop(run)
        if stop is not None:
            self._halt(run)
            self._finish(run, stop[0], 0, stop[1])
            return
        if not run.ticking and not self._ready(run):
            return
        assert run.tree is not None
        try:
            status = run.tree.tick_once()
        except Exception as exc:  # noqa: BLE001 - a node's failure ends its goal, not the navigator
            self._fail(run, exc)
            return
        self._note_moved_goal(run)
        if status is Status.RUNNING:
            if feedback:
                self._feedback(run)
            return
        failed = run.tree.failures()
        self._halt(run)
        if status is Status.SUCCESS:
            self.get_logger().info(f"goal reached in {self._now_s() - run.start_s:.1f} s "
                                   f"({self._recoveries(run)} recoveries)")
            self._finish(run, GoalEnd.SUCCEEDED, 0, run.moved_note or "")
            return
        code, message = error_of(run.tree.blackboard, [str(n) for n in self.params.error_code_names])
        where = f" (its last failures: {'; '.join(failed)})" if failed else ""
        message = f"{message or 'the behaviour tree failed' + where} (after {self._recoveries(run)} recoveries)"
        self.get_logger().warning(f"navigation failed: {message}")
        self._finish(run, GoalEnd.ABORTED, code, message)

    def _stop(self, run: _Run) -> tuple[GoalEnd, str] | None:
        """Why the goal stops before its tree's next tick: canceled, or a robot not upright (no goal
        succeeds with a robot on its side)."""
        if run.handle.is_cancel_requested:
            return GoalEnd.CANCELED, "canceled"
        if self.not_upright is not None:
            return GoalEnd.ABORTED, self.not_upright
        return None

    def _ready(self, run: _Run) -> bool:
        """Before the first tick: the clock runs (on sim time, 0 until /clock is heard), the planner
        and controller servers are there, and the robot has a pose in the global frame (a stack
        just started may not have one yet). Past ``server_timeout``, the goal aborts."""
        now = self._now_s()
        if now <= 0.0:
            run.start_s = now
            run.deadline_s = math.inf
            return False
        if not math.isfinite(run.deadline_s):
            run.start_s, run.deadline_s = now, now + self.params.server_timeout
        missing = self._missing_servers(run)
        try:
            self._pose(self.params.global_frame)
            pose_error = None
        except TransformError as exc:
            pose_error = str(exc)
        if not missing and pose_error is None:
            run.ticking = True
            return True
        if now > run.deadline_s:
            if missing:
                self._finish(run, GoalEnd.ABORTED, 0, f"the {missing[0]} server is not available "
                                                      "(the behaviour tree uses it)")
            else:
                self._finish(run, GoalEnd.ABORTED, ComputePathToPose.Result.TF_ERROR,
                             f"no robot pose: {pose_error}")
        return False

    def _missing_servers(self, run: _Run) -> list[str]:
        """The action servers and services the run's tree uses that are not there yet (their clients
        made now: as Nav2's nodes wait for their servers when the tree is made)."""
        assert run.tree is not None
        missing: list[str] = []
        for node in run.tree.nodes():
            try:
                if isinstance(node, ActionNode):
                    name = node.get_input("server_name")
                    ready = self.ports.action(name, node.ACTION).ready()
                elif isinstance(node, ServiceNode):
                    name = node.get_input("service_name")
                    ready = self.ports.service(name, node.SERVICE).ready()
                else:
                    continue
            except BehaviorTreeError:
                continue  # a name from a blackboard entry not set yet: the node says so when ticked
            if not ready and name not in missing:
                missing.append(name)
        return missing

    def _finish(self, run: _Run, end: GoalEnd, code: int, message: str) -> None:
        if self._active is run:
            self._active = None
        result = run.action.Result()
        result.error_code, result.error_msg = code, message
        (self.through_server if run.through else self.server).finish(run.handle, end, result)

    def _recoveries(self, run: _Run) -> int:
        return int(run.tree.blackboard.get(RECOVERIES_KEY) or 0) if run.tree is not None else 0

    def _note_moved_goal(self, run: _Run) -> None:
        """The planner moved an unreachable goal to the nearest free pose within its tolerance: say so
        once (the log, and the result's message)."""
        assert run.tree is not None
        path = run.tree.blackboard.get(self.params.path_blackboard_id)
        if path is None or path is run.seen_path or not getattr(path, "poses", None):
            return
        run.seen_path = path
        end = path.poses[-1].pose.position
        asked = run.goal.pose.position
        moved = math.hypot(end.x - asked.x, end.y - asked.y)
        if moved > GOAL_MOVED_M and run.moved_note is None:
            run.moved_note = (f"the goal ({asked.x:.2f}, {asked.y:.2f}) is in an obstacle: navigating to the "
                              f"nearest free pose ({end.x:.2f}, {end.y:.2f}), {moved:.2f} m away "
                              "(the planner's tolerance)")
            self.get_logger().info(run.moved_note)

    def _feedback(self, run: _Run) -> None:
        try:
            x, y, yaw = self._pose(self.params.global_frame)
        except TransformError:
            return  # no pose (a stack starting): the tree's nodes say so if it lasts
        now = self._now_s()
        # the samples within the window, and the newest older one (a window longer than a tick)
        older = [sample for sample in run.poses if now - sample[0] > SPEED_WINDOW_S][-1:]
        run.poses = older + [sample for sample in run.poses if now - sample[0] <= SPEED_WINDOW_S] + [(now, x, y)]
        assert run.tree is not None
        board = run.tree.blackboard
        fb = run.action.Feedback()
        if run.through:
            fb.number_of_poses_remaining = len(board.get(self.params.goals_blackboard_id) or [])
        fb.current_pose.header.frame_id = self.params.global_frame
        fb.current_pose.header.stamp = self.get_clock().now().to_msg()
        fb.current_pose.pose.position.x, fb.current_pose.pose.position.y = x, y
        o = fb.current_pose.pose.orientation
        o.x, o.y, o.z, o.w = quaternion_from_yaw(yaw)
        fb.navigation_time = Duration(seconds=max(0.0, now - run.start_s)).to_msg()
        fb.number_of_recoveries = self._recoveries(run)
        path = board.get(self.params.path_blackboard_id)
        if path is not run.path_msg:  # a new path: its points once
            poses = getattr(path, "poses", None) or []
            run.path_msg = path
            run.path_xy = np.array([[p.pose.position.x, p.pose.position.y] for p in poses]).reshape(-1, 2)
        remaining = path_length_from(run.path_xy, (x, y))
        fb.distance_remaining = float(remaining)
        t0, x0, y0 = run.poses[0]
        speed = math.hypot(x - x0, y - y0) / (now - t0) if now > t0 else 0.0
        # Nav2's: an estimate only while moving (above 1 cm/s) and still 10 cm or more away
        eta = remaining / speed if speed > 0.01 and remaining > 0.1 else 0.0
        fb.estimated_time_remaining = Duration(seconds=eta).to_msg()
        send_feedback(self.port, run.handle, fb)


def main(args: list[str] | None = None) -> int:
    return run_nodes([Navigator], "bt_navigator", args)


if __name__ == "__main__":
    sys.exit(main())
