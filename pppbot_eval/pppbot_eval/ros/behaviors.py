"""What the evaluation's node does on each of its ticks (every :data:`TICK_S` of sim time).

A scenario is a chain of behaviours: put AMCL off (localization), drive a route on ground
truth, send navigation goals one after another. Each acts only on ticks, so in lockstep
everything the evaluation does happens at fixed sim times: the same run on any machine.
A behaviour reads what the node has recorded and acts through it (:class:`EvalActions`);
it has no clock and no ROS of its own.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from action_msgs.msg import GoalStatus

from pppbot_common.maps import OccupancyGrid
from pppbot_common.se2 import se2_compose, se2_inverse
from pppbot_eval.driver import RouteDriver
from pppbot_eval.scenarios import GoalAnswer, GoalRecord, Recording, shortest_path_m
from pppbot_lockstep.ros.goals import Arrival, hold_until
from pppbot_lockstep.ros.port import StepPort

#: The evaluation ticks at 20 Hz of sim time, a teleop's or a controller's rate.
TICK_S = 0.05

ANSWERS = {GoalStatus.STATUS_SUCCEEDED: GoalAnswer.SUCCEEDED, GoalStatus.STATUS_ABORTED: GoalAnswer.ABORTED,
           GoalStatus.STATUS_CANCELED: GoalAnswer.CANCELED}


class EvalActions(Protocol):
    """What a behaviour may read and do (the evaluation's node)."""

    recording: Recording
    sim_now_s: float | None
    truth_pose: tuple[float, float, float] | None
    amcl_poses: int
    localizes: bool
    driving: bool

    @property
    def port(self) -> StepPort:
        """The node's step port (the run's lockstep participant, or the free-running one)."""
        ...

    def command(self, linear_mps: float, angular_radps: float) -> None: ...
    def send_initial_pose(self, x: float, y: float, yaw: float, covariance: list[float]) -> None: ...
    def request_global_localization(self) -> Any: ...
    def send_goal(self, x: float, y: float, yaw: float) -> Any: ...
    def recoveries(self) -> int: ...


class Behavior(Protocol):
    #: None while running; "" when it ended well, else why it failed.
    outcome: str | None

    def tick(self, node: EvalActions) -> None: ...
    def progress(self) -> tuple[float, str]: ...


class Chain:
    """Behaviours one after another; ends at the first failure."""

    def __init__(self, behaviors: Sequence[Behavior]) -> None:
        self.behaviors = list(behaviors)
        self.index = 0
        self.outcome: str | None = None

    def tick(self, node: EvalActions) -> None:
        while self.outcome is None:
            current = self.behaviors[self.index]
            current.tick(node)
            if current.outcome is None:
                return
            if current.outcome:
                self.outcome = current.outcome
            elif self.index + 1 == len(self.behaviors):
                self.outcome = ""
            else:
                self.index += 1  # the next one starts on this tick

    def progress(self) -> tuple[float, str]:
        return self.behaviors[min(self.index, len(self.behaviors) - 1)].progress()


class DriveRoute:
    """Follow the route on ground truth, one command a tick, until the driver is done."""

    def __init__(self, driver: RouteDriver, limit_s: float) -> None:
        self.driver = driver
        self.limit_s = limit_s
        self.outcome: str | None = None
        self._start_s: float | None = None

    def tick(self, node: EvalActions) -> None:
        if node.truth_pose is None or node.sim_now_s is None:
            return
        if self._start_s is None:
            self._start_s = node.sim_now_s
            node.recording.start_sim_s = node.recording.end_sim_s = node.sim_now_s
            node.driving = True
        node.recording.end_sim_s = node.sim_now_s
        x, y, yaw = node.truth_pose
        linear, angular = self.driver.command(x, y, yaw)
        node.command(linear, angular)
        node.recording.route_progress = self.driver.progress
        node.recording.route_finished = self.driver.finished
        if self.driver.finished:
            self.outcome = ""
        elif node.sim_now_s - self._start_s > self.limit_s:
            node.command(0.0, 0.0)
            self.outcome = f"route not finished within {self.limit_s:.0f} sim seconds"

    def progress(self) -> tuple[float, str]:
        return self.driver.progress, f"{self.driver.travelled_m:5.1f}/{self.driver.length_m:.1f} m"


class StartLocalization:
    """AMCL's first estimate at the spawn pose (the launch's initial pose); then the initial pose
    moved by ``offset`` (sent as RViz sends it), or global localization; done at AMCL's first
    estimate after that."""

    def __init__(self, start: tuple[float, float, float], offset: tuple[float, float, float] | None,
                 covariance: list[float]) -> None:
        self.start = start
        self.offset = offset  # None: global localization
        self.covariance = covariance
        self.outcome: str | None = None
        self._asked_at: int | None = None  # AMCL's pose count when the request went out
        self._service: Any = None

    def tick(self, node: EvalActions) -> None:
        if self._asked_at is None:
            if node.amcl_poses == 0:
                return  # its first estimate: after it a standing robot gets none until ours
            self._asked_at = node.amcl_poses
            if self.offset is None:
                self._service = node.request_global_localization()
            else:
                x, y, yaw = self.start
                dx, dy, dyaw = self.offset
                node.send_initial_pose(x + dx, y + dy, yaw + dyaw, self.covariance)
            return
        if node.amcl_poses > self._asked_at:
            self.outcome = ""

    def progress(self) -> tuple[float, str]:
        return 0.0, "localizing"


@dataclass(frozen=True)
class GoalLimits:
    """How long a goal may take (sim s): ``base_s`` plus ``per_shortest`` times the shortest path's time."""

    base_s: float = 60.0
    per_shortest: float = 4.0


class NavigateGoals:
    """Goals (world frame) to ``navigate_to_pose`` one after another, each sent in the node's goal
    frame (``map``, or ``odom`` without a map; at ``map_to_world`` in the world), judged later on
    ground truth. A goal past its time limit
    is canceled and recorded as ``timeout``; one the server never answers is recorded as
    ``unanswered`` once past its limit (a lost request must not hang the run)."""

    def __init__(self, goals: Sequence[tuple[float, float, float]], truth_map: OccupancyGrid,
                 map_to_world: tuple[float, float, float], max_speed_mps: float,
                 limits: GoalLimits = GoalLimits()) -> None:
        self.goals = list(goals)
        self.truth_map = truth_map
        self.world_to_map = se2_inverse(map_to_world)
        self.max_speed_mps = max_speed_mps
        self.limits = limits
        self.outcome: str | None = None
        self.index = 0
        self._sent: Any = None  # the goal's send future
        self._result: Any = None
        self._handle: Any = None
        self._start_s = 0.0
        self._limit_s = 0.0
        self._shortest: float | None = None
        self._canceled = False
        self._recording: Recording | None = None

    def tick(self, node: EvalActions) -> None:
        if node.sim_now_s is None:
            return
        rec = self._recording = node.recording
        if not node.driving:
            node.driving = True
            rec.start_sim_s = rec.end_sim_s = node.sim_now_s
        rec.end_sim_s = node.sim_now_s
        if self._sent is None:
            if self.index == len(self.goals):
                self.outcome = ""
                return
            if self.index == 0 and node.localizes and node.amcl_poses == 0:
                # As BasicNavigator's waitUntilNav2Active: the localizer's first pose (and with it
                # map -> odom) before the first goal, which the navigator would abort without it.
                return
            self._send(node, self.goals[self.index])
            return
        elapsed = node.sim_now_s - self._start_s
        if self._handle is None:
            if not self._sent.done():
                if elapsed > self._limit_s:  # the request or its answer is lost: say so, go on
                    self._record(node, GoalAnswer.UNANSWERED, error_msg="navigate_to_pose did not answer the goal "
                                                                        f"within {self._limit_s:.0f} sim seconds")
                return
            self._handle = self._sent.result()
            if self._handle is None or not self._handle.accepted:
                self._record(node, GoalAnswer.REJECTED)
                return
            self._result = Arrival(self._handle.get_result_async(), lambda: node.sim_now_s, node.port)
        if self._result.done():
            response = self._result.result()
            answer = ANSWERS.get(response.status, GoalAnswer.UNKNOWN)
            if self._canceled:
                self._record(node, GoalAnswer.TIMEOUT, error_msg=f"no result within {self._limit_s:.0f} sim seconds")
            else:
                message = str(response.result.error_msg)
                if answer is GoalAnswer.UNKNOWN:
                    message = f"action status {response.status}" + (f": {message}" if message else "")
                self._record(node, answer, int(response.result.error_code), message)
        elif not self._canceled and elapsed > self._limit_s:
            self._canceled = True
            hold_until(node.port, self._handle.cancel_goal_async())
        elif self._canceled and elapsed > self._limit_s + self.limits.base_s:
            self._record(node, GoalAnswer.TIMEOUT, error_msg=f"no result within {self._limit_s:.0f} sim seconds, "
                                                    f"nor {self.limits.base_s:.0f} s after the cancel")

    def _send(self, node: EvalActions, goal: tuple[float, float, float]) -> None:
        truth = node.truth_pose
        self._shortest = shortest_path_m(self.truth_map, truth[:2], goal[:2]) if truth is not None else None
        self._limit_s = self.limits.base_s + self.limits.per_shortest * (self._shortest or 0.0) / self.max_speed_mps
        x, y, yaw = (float(v) for v in se2_compose(self.world_to_map, goal))
        self._start_s = node.sim_now_s or 0.0
        self._canceled = False
        self._sent = Arrival(hold_until(node.port, node.send_goal(x, y, yaw)), lambda: node.sim_now_s,
                             node.port)

    def _record(self, node: EvalActions, status: GoalAnswer, error_code: int = 0, error_msg: str = "") -> None:
        node.recording.goals.append(GoalRecord(
            goal=self.goals[self.index], start_s=self._start_s, end_s=node.sim_now_s or self._start_s, status=status,
            error_code=error_code, error_msg=error_msg, recoveries=node.recoveries(), shortest_path_m=self._shortest,
            limit_s=self._limit_s))
        self.index += 1
        self._sent = self._handle = self._result = None

    def cancel(self) -> None:
        """Cancel the goal under way (the run is being stopped)."""
        if self._handle is not None and self._result is not None and not self._result.done():
            self._handle.cancel_goal_async()

    def progress(self) -> tuple[float, str]:
        rec = self._recording
        reached = sum(1 for r in rec.goals if r.status is GoalAnswer.SUCCEEDED) if rec is not None else 0
        count = len(self.goals)
        return self.index / max(count, 1), f"goal {min(self.index + 1, count)}/{count}, {reached} succeeded"
