"""Nav2's action and service nodes: a goal to a server, its result on the blackboard (Nav2
Jazzy's ``BtActionNode`` and ``BtServiceNode`` and the nodes built on them).

An action node sends its goal on its first tick and answers RUNNING until the goal ends:
SUCCESS when it succeeded, FAILURE when it was aborted, SUCCESS when it was canceled (Nav2's
default). A goal the server neither accepts nor refuses within ``server_timeout`` ms of the
tree's clock, or refuses, is a FAILURE. Halted while its goal runs, it cancels the goal.
``error_code_id`` and ``error_msg`` carry the result's error code and message (``NONE`` and ""
when it succeeded). The servers are reached through the tree's
:class:`~pppbot_nav.bt.ports.RobotPorts`.
"""
from __future__ import annotations

import math
from typing import Any, ClassVar

from builtin_interfaces.msg import Duration as DurationMsg
from nav2_msgs import action as nav2_action
from nav2_msgs import srv as nav2_srv
from nav_msgs.msg import Path
from std_srvs.srv import Empty

from pppbot_nav.bt.ports import PORTS_KEY, ActionPort, GoalCall, GoalStatus, Outcome, RobotPorts, ServiceCall
from pppbot_nav.bt.tree import NodeConfig, Port, Status, TreeNode, as_bool, input_port, output_port
from pppbot_nav.errors import BehaviorTreeError

#: the blackboard entries Nav2's navigators set for every tree (ms), with Nav2 Jazzy's defaults
SERVER_TIMEOUT_KEY = "server_timeout"
DEFAULT_SERVER_TIMEOUT_MS = 20.0
#: the blackboard entry counting the recoveries (behaviours run with ``is_recovery``)
RECOVERIES_KEY = "number_recoveries"


def duration_msg(seconds: float) -> DurationMsg:
    """``builtin_interfaces/Duration`` of ``seconds`` (≥ 0)."""
    nanoseconds = round(max(0.0, seconds) * 1e9)
    return DurationMsg(sec=nanoseconds // 1_000_000_000, nanosec=nanoseconds % 1_000_000_000)


def duration_s(msg: DurationMsg) -> float:
    return msg.sec + msg.nanosec * 1e-9


def ports_of(node: TreeNode) -> RobotPorts:
    """The tree's ports (the blackboard entry :data:`~pppbot_nav.bt.ports.PORTS_KEY`).

    Raises:
        BehaviorTreeError: the tree was given none.
    """
    ports = node.config.blackboard.get(PORTS_KEY)
    if ports is None:
        raise BehaviorTreeError(f"{node._where()}'{node.name}' needs the navigator's ports (blackboard entry "
                                f"'{PORTS_KEY}'): this tree was loaded without them")
    return ports


def server_timeout_s(node: TreeNode) -> float:
    """How long (s) ``node`` waits for its server: its ``server_timeout`` port (ms), else the
    navigator's (the blackboard's ``server_timeout``, bt_navigator's default_server_timeout)."""
    ms = node.get_input("server_timeout")
    if ms is None:
        ms = node.config.blackboard.get(SERVER_TIMEOUT_KEY, DEFAULT_SERVER_TIMEOUT_MS)
    return float(ms) / 1000.0


def server_ports(default_name: str, *own: Port, errors: bool = True) -> tuple[Port, ...]:
    """A server node's ports: ``server_name``, ``server_timeout``, ``own``, and with ``errors`` the
    outputs ``error_code_id`` and ``error_msg``."""
    common = (input_port("server_name", str, default_name, "the server's name"),
              input_port("server_timeout", float, None, "ms to wait for the server to answer (the navigator's "
                                                        "default_server_timeout without it)"))
    error_ports = (output_port("error_code_id", "the result's error code"),
                   output_port("error_msg", "the result's error message")) if errors else ()
    return (*common, *own, *error_ports)


class ActionNode(TreeNode):
    """Nav2's ``BtActionNode``: subclasses name ``ACTION`` and their ports (:func:`server_ports`), fill the goal in
    :meth:`on_tick`; :meth:`on_wait_for_result` may set ``goal_updated`` to send the goal anew
    (a new path to follow); :meth:`on_success`, :meth:`on_aborted` and :meth:`on_cancelled`
    write the outputs and give the answer."""

    ACTION: ClassVar[Any]

    def __init__(self, name: str, config: NodeConfig | None = None) -> None:
        super().__init__(name, config)
        self.goal: Any = None
        self.call: GoalCall | None = None
        self.acknowledged = False
        self.sent_s = 0.0
        self.should_send_goal = True
        self.goal_updated = False
        self.feedback: Any = None

    # -- what subclasses fill ---------------------------------------------------------------
    def on_tick(self) -> None:
        """Fill ``self.goal`` from the inputs (clear ``should_send_goal`` to fail instead)."""

    def on_wait_for_result(self, feedback: Any) -> None:
        """Each tick while the goal runs, with the newest feedback (None when none came)."""

    def on_success(self, result: Any) -> Status:
        self.write_error(result)
        return Status.SUCCESS

    def on_aborted(self, result: Any) -> Status:
        self.write_error(result)
        self.why = (f"aborted with error code {getattr(result, 'error_code', 0)}"
                    + (f": {result.error_msg}" if getattr(result, "error_msg", "") else ""))
        return Status.FAILURE

    def on_cancelled(self, result: Any) -> Status:
        self.set_output("error_code_id", 0)
        self.set_output("error_msg", "")
        return Status.SUCCESS

    def write_error(self, result: Any) -> None:
        self.set_output("error_code_id", int(getattr(result, "error_code", 0)))
        self.set_output("error_msg", str(getattr(result, "error_msg", "")))

    # -- the lifecycle ---------------------------------------------------------------------
    def server(self) -> ActionPort:
        return ports_of(self).action(self.get_input("server_name"), self.ACTION)

    def timeout_s(self) -> float:
        return server_timeout_s(self)

    def send_new_goal(self) -> None:
        self.call = self.server().send(self.goal, self._on_feedback)
        self.acknowledged = False
        self.sent_s = self.now()

    def _on_feedback(self, feedback: Any) -> None:
        self.feedback = feedback

    def tick(self) -> Status:
        if self.status.completed:  # ticked again once it ended (a pipeline does): its end, until reset
            return self.status
        if self.status in (Status.IDLE, Status.SKIPPED):
            self.goal = self.ACTION.Goal()
            self.should_send_goal = True
            self.goal_updated = False
            self.feedback = None
            self.on_tick()
            if not self.should_send_goal:
                return Status.FAILURE
            self.send_new_goal()
        answer = self._acknowledgement()
        if answer is not None:
            return answer
        assert self.call is not None
        outcome = self.call.outcome()
        if outcome is None:
            feedback, self.feedback = self.feedback, None
            self.on_wait_for_result(feedback)
            if self.goal_updated:
                self.goal_updated = False
                self.send_new_goal()
                answer = self._acknowledgement()
                if answer is not None:
                    return answer
            return Status.RUNNING
        self.call = None
        return self._ended(outcome)

    def _acknowledgement(self) -> Status | None:
        """RUNNING while the server has not answered the goal (within the timeout), FAILURE when it
        refused it or timed out; None once it took it."""
        assert self.call is not None
        if self.acknowledged:
            return None
        accepted = self.call.accepted()
        if accepted is None:
            if self.now() - self.sent_s < self.timeout_s():
                return Status.RUNNING
            self.call.cancel()  # should the server take it late, it does not run on unwatched
            self.call = None
            self.why = f"the server did not take the goal within {self.timeout_s():g} s"
            return Status.FAILURE  # timed out waiting for the server to acknowledge the goal
        if not accepted:
            self.call = None
            self.why = "the server refused the goal (or is not there)"
            return Status.FAILURE  # refused: the node fails, not the tree
        self.acknowledged = True
        return None

    def _ended(self, outcome: Outcome) -> Status:
        if outcome.status is GoalStatus.SUCCEEDED:
            return self.on_success(outcome.result)
        if outcome.status is GoalStatus.ABORTED:
            return self.on_aborted(outcome.result)
        return self.on_cancelled(outcome.result)

    def halt(self) -> None:
        if self.status is Status.RUNNING and self.call is not None and self.call.outcome() is None:
            self.call.cancel()
        self.call = None


# -- planning, smoothing and following -----------------------------------------------------------


class ComputePathToPoseNode(ActionNode):
    """A path to ``goal`` (from ``start`` when given, else from the robot) written to ``path``;
    halted or failed, ``path`` is empty."""

    ACTION = nav2_action.ComputePathToPose
    PORTS = server_ports("compute_path_to_pose", input_port("goal", None, description="where to"),
                         input_port("start", None, None, "where from (the robot without it)"),
                         input_port("planner_id", str, ""), output_port("path"))

    def on_tick(self) -> None:
        self.goal.goal = self.get_input("goal")
        self.goal.planner_id = self.get_input("planner_id")
        start = self.get_input("start")
        if start is not None:
            self.goal.start = start
            self.goal.use_start = True

    def on_success(self, result: Any) -> Status:
        self.set_output("path", result.path)
        return super().on_success(result)

    def on_aborted(self, result: Any) -> Status:
        self.set_output("path", Path())
        return super().on_aborted(result)

    def on_cancelled(self, result: Any) -> Status:
        self.set_output("path", Path())
        return super().on_cancelled(result)

    def halt(self) -> None:
        self.set_output("path", Path())
        super().halt()


class ComputePathThroughPosesNode(ComputePathToPoseNode):
    """A path through ``goals`` in turn, written to ``path``."""

    ACTION = nav2_action.ComputePathThroughPoses
    PORTS = server_ports("compute_path_through_poses", input_port("goals", None, description="the poses in turn"),
                         input_port("start", None, None, "where from (the robot without it)"),
                         input_port("planner_id", str, ""), output_port("path"))

    def on_tick(self) -> None:
        self.goal.goals = list(self.get_input("goals"))
        self.goal.planner_id = self.get_input("planner_id")
        start = self.get_input("start")
        if start is not None:
            self.goal.start = start
            self.goal.use_start = True


class SmoothPathNode(ActionNode):
    ACTION = nav2_action.SmoothPath
    PORTS = server_ports("smooth_path", input_port("unsmoothed_path", None), input_port("smoother_id", str, ""),
                         input_port("max_smoothing_duration", float, 3.0, "s"),
                         input_port("check_for_collisions", as_bool, False),
                         output_port("smoothed_path"), output_port("smoothing_duration"),
                         output_port("was_completed"))

    def on_tick(self) -> None:
        self.goal.path = self.get_input("unsmoothed_path")
        self.goal.smoother_id = self.get_input("smoother_id")
        self.goal.max_smoothing_duration = duration_msg(self.get_input("max_smoothing_duration"))
        self.goal.check_for_collisions = self.get_input("check_for_collisions")

    def on_success(self, result: Any) -> Status:
        self.set_output("smoothed_path", result.path)
        self.set_output("smoothing_duration", duration_s(result.smoothing_duration))
        self.set_output("was_completed", bool(result.was_completed))
        return super().on_success(result)


class FollowPathNode(ActionNode):
    """Follows ``path``; a new path on the blackboard (or controller) while it runs is sent as a new
    goal, which the controller takes as an update of the one it follows."""

    ACTION = nav2_action.FollowPath
    PORTS = server_ports("follow_path", input_port("path", None), input_port("controller_id", str, ""),
                         input_port("goal_checker_id", str, ""), input_port("progress_checker_id", str, ""))

    def on_tick(self) -> None:
        self.goal.path = self.get_input("path")
        self.goal.controller_id = self.get_input("controller_id")
        self.goal.goal_checker_id = self.get_input("goal_checker_id")
        self.goal.progress_checker_id = self.get_input("progress_checker_id")

    def on_wait_for_result(self, feedback: Any) -> None:
        fields = {"path": self.get_input("path")}
        if not fields["path"].poses:  # an empty path is no update (Nav2's)
            fields["path"] = self.goal.path
        for field in ("controller_id", "goal_checker_id", "progress_checker_id"):
            fields[field] = self.get_input(field)
        if any(value is not getattr(self.goal, field) and value != getattr(self.goal, field)
               for field, value in fields.items()):
            self.goal = self.ACTION.Goal(**fields)  # a new goal: the one sent stays as it was
            self.goal_updated = True


# -- behaviours ---------------------------------------------------------------------------------


class _Behavior(ActionNode):
    """A behavior_server action; with ``is_recovery`` it counts in the blackboard's
    ``number_recoveries`` (the navigator's feedback)."""

    def on_tick(self) -> None:
        if self.get_input("is_recovery"):
            board = self.config.blackboard
            board.set(RECOVERIES_KEY, int(board.get(RECOVERIES_KEY, 0)) + 1)
        self.fill()

    def fill(self) -> None:
        raise NotImplementedError


def _recovery_port(default: bool) -> Port:
    return input_port("is_recovery", as_bool, default, "count it in number_recoveries")


class SpinNode(_Behavior):
    ACTION = nav2_action.Spin
    PORTS = server_ports("spin", input_port("spin_dist", float, 1.57, "rad"),
                         input_port("time_allowance", float, 10.0, "s"), _recovery_port(True))

    def fill(self) -> None:
        self.goal.target_yaw = self.get_input("spin_dist")
        self.goal.time_allowance = duration_msg(self.get_input("time_allowance"))


class BackUpNode(_Behavior):
    ACTION = nav2_action.BackUp
    PORTS = server_ports("backup", input_port("backup_dist", float, 0.15, "m"),
                         input_port("backup_speed", float, 0.025, "m/s"),
                         input_port("time_allowance", float, 10.0, "s"), _recovery_port(True))

    def fill(self) -> None:
        self.goal.target.x = self.get_input("backup_dist")
        self.goal.speed = self.get_input("backup_speed")
        self.goal.time_allowance = duration_msg(self.get_input("time_allowance"))


class DriveOnHeadingNode(_Behavior):
    ACTION = nav2_action.DriveOnHeading
    PORTS = server_ports("drive_on_heading", input_port("dist_to_travel", float, 0.15, "m"),
                         input_port("speed", float, 0.025, "m/s"),
                         input_port("time_allowance", float, 10.0, "s"), _recovery_port(False))

    def fill(self) -> None:
        self.goal.target.x = self.get_input("dist_to_travel")
        self.goal.speed = self.get_input("speed")
        self.goal.time_allowance = duration_msg(self.get_input("time_allowance"))


class WaitNode(_Behavior):
    ACTION = nav2_action.Wait
    """Waits ``wait_duration`` s (a negative one as its opposite, as Nav2's)."""

    PORTS = server_ports("wait", input_port("wait_duration", float, 1.0, "s"), _recovery_port(True))

    def fill(self) -> None:
        seconds = self.get_input("wait_duration")
        if not math.isfinite(seconds):
            raise BehaviorTreeError(f"{self._where()}Wait '{self.name}': wait_duration = {seconds}: a finite "
                                    "number of seconds")
        self.goal.time = duration_msg(abs(seconds))


class AssistedTeleopNode(_Behavior):
    ACTION = nav2_action.AssistedTeleop
    PORTS = server_ports("assisted_teleop", input_port("time_allowance", float, 10.0, "s"), _recovery_port(False))

    def fill(self) -> None:
        self.goal.time_allowance = duration_msg(self.get_input("time_allowance"))


# -- navigating (a tree that sends goals to a navigator) --------------------------------------------


class NavigateToPoseNode(ActionNode):
    ACTION = nav2_action.NavigateToPose
    PORTS = server_ports("navigate_to_pose", input_port("goal", None), input_port("behavior_tree", str, ""))

    def on_tick(self) -> None:
        self.goal.pose = self.get_input("goal")
        self.goal.behavior_tree = self.get_input("behavior_tree")


class NavigateThroughPosesNode(ActionNode):
    ACTION = nav2_action.NavigateThroughPoses
    PORTS = server_ports("navigate_through_poses", input_port("goals", None), input_port("behavior_tree", str, ""))

    def on_tick(self) -> None:
        self.goal.poses = list(self.get_input("goals"))
        self.goal.behavior_tree = self.get_input("behavior_tree")


# -- services -------------------------------------------------------------------------------------


class ServiceNode(TreeNode):
    """Nav2's ``BtServiceNode``: the request on the first tick, RUNNING until the response, then
    :meth:`on_completion` (SUCCESS by default); no response within ``server_timeout`` ms of the
    tree's clock is a FAILURE."""

    SERVICE: ClassVar[Any]

    def __init__(self, name: str, config: NodeConfig | None = None) -> None:
        super().__init__(name, config)
        self.request: Any = None
        self.call: ServiceCall | None = None
        self.sent_s = 0.0

    def on_tick(self) -> None:
        """Fill ``self.request`` from the inputs."""

    def on_completion(self, response: Any) -> Status:
        return Status.SUCCESS

    def tick(self) -> Status:
        if self.status.completed:  # ticked again once it ended: its end, until reset
            return self.status
        if self.status in (Status.IDLE, Status.SKIPPED):
            self.request = self.SERVICE.Request()
            self.on_tick()
            self.call = ports_of(self).service(self.get_input("service_name"), self.SERVICE).call(self.request)
            self.sent_s = self.now()
        assert self.call is not None
        if self.call.refused():  # no such service
            self.call = None
            return Status.FAILURE
        response = self.call.response()
        if response is None:
            if self.now() - self.sent_s < server_timeout_s(self):
                return Status.RUNNING
            self.call = None
            return Status.FAILURE
        self.call = None
        return self.on_completion(response)

    def halt(self) -> None:
        self.call = None


def service_ports(default_name: str | None, *own: Port) -> tuple[Port, ...]:
    """A service node's ports: ``service_name`` (required without ``default_name``), ``server_timeout``, ``own``."""
    name = input_port("service_name", str, description="the service's name") if default_name is None \
        else input_port("service_name", str, default_name, "the service's name")
    return (name,
            input_port("server_timeout", float, None, "ms to wait for the response (the navigator's "
                                                      "default_server_timeout without it)"), *own)


class ClearEntireCostmapNode(ServiceNode):
    """Clears a costmap (``service_name``: its node's ``clear_entirely_<name>``); counts in
    ``number_recoveries``, as Nav2's."""

    SERVICE = nav2_srv.ClearEntireCostmap
    PORTS = service_ports(None)

    def on_tick(self) -> None:
        board = self.config.blackboard
        board.set(RECOVERIES_KEY, int(board.get(RECOVERIES_KEY, 0)) + 1)


class ClearCostmapAroundRobotNode(ClearEntireCostmapNode):
    SERVICE = nav2_srv.ClearCostmapAroundRobot
    PORTS = service_ports(None, input_port("reset_distance", float, 1.0, "m"))

    def on_tick(self) -> None:
        super().on_tick()
        self.request.reset_distance = self.get_input("reset_distance")


class ClearCostmapExceptRegionNode(ClearCostmapAroundRobotNode):
    SERVICE = nav2_srv.ClearCostmapExceptRegion


class ReinitializeGlobalLocalizationNode(ServiceNode):
    SERVICE = Empty
    PORTS = service_ports("reinitialize_global_localization")


# -- cancelling what another branch started -------------------------------------------------------


class _Cancel(TreeNode):
    """Cancels every goal of its server; SUCCESS."""

    ACTION: ClassVar[Any]

    def tick(self) -> Status:
        ports_of(self).action(self.get_input("server_name"), self.ACTION).cancel_all()
        return Status.SUCCESS


def _cancel(action: Any, server: str) -> type[_Cancel]:
    return type(f"Cancel{action.__name__}", (_Cancel,), {
        "ACTION": action, "PORTS": (input_port("server_name", str, server, "the server's name"),
                                    input_port("server_timeout", float, None, "ms"))})


#: Nav2's action and service nodes, by their XML names
NAV2_ACTION_NODES: dict[str, type[TreeNode]] = {
    "ComputePathToPose": ComputePathToPoseNode, "ComputePathThroughPoses": ComputePathThroughPosesNode,
    "SmoothPath": SmoothPathNode, "FollowPath": FollowPathNode,
    "Spin": SpinNode, "BackUp": BackUpNode, "DriveOnHeading": DriveOnHeadingNode, "Wait": WaitNode,
    "AssistedTeleop": AssistedTeleopNode,
    "NavigateToPose": NavigateToPoseNode, "NavigateThroughPoses": NavigateThroughPosesNode,
    "ClearEntireCostmap": ClearEntireCostmapNode, "ClearCostmapAroundRobot": ClearCostmapAroundRobotNode,
    "ClearCostmapExceptRegion": ClearCostmapExceptRegionNode,
    "ReinitializeGlobalLocalization": ReinitializeGlobalLocalizationNode,
    "CancelControl": _cancel(nav2_action.FollowPath, "follow_path"),
    "CancelSpin": _cancel(nav2_action.Spin, "spin"),
    "CancelBackUp": _cancel(nav2_action.BackUp, "backup"),
    "CancelWait": _cancel(nav2_action.Wait, "wait"),
    "CancelDriveOnHeading": _cancel(nav2_action.DriveOnHeading, "drive_on_heading"),
    "CancelAssistedTeleop": _cancel(nav2_action.AssistedTeleop, "assisted_teleop"),
}
