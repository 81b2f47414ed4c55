"""The navigation scenario's goal loop: send each goal to ``navigate_to_pose``, wait for its result.

Goals are in the world frame (the ground truth's); they are sent in ``map``, which is
``map_to_world`` in the world. A goal that takes longer than its time limit (sim time:
:attr:`GoalLimits.base_s` plus :attr:`GoalLimits.per_shortest` times the shortest path's
time at full speed) is canceled and recorded as ``timeout``. Each goal becomes a
:class:`~pppbot_bringup.eval.scenarios.GoalRecord` in the recording.
"""
from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from action_msgs.msg import GoalStatus
from rclpy.task import Future

from pppbot_bringup.eval.progress import Progress
from pppbot_bringup.eval.scenarios import GoalRecord, Recording, shortest_path_m
from pppbot_bringup.ros.eval_node import EvalNode
from pppbot_common.maps import OccupancyGrid
from pppbot_common.se2 import se2_compose, se2_inverse

STATUS_NAMES = {GoalStatus.STATUS_SUCCEEDED: "succeeded", GoalStatus.STATUS_ABORTED: "aborted",
                GoalStatus.STATUS_CANCELED: "canceled"}


@dataclass(frozen=True)
class GoalLimits:
    """How long the loop waits: sim seconds for a goal, wall seconds for the navigator's answers."""

    base_s: float = 60.0
    per_shortest: float = 4.0
    server_wall_s: float = 60.0
    answer_wall_s: float = 30.0


class GoalLoop:
    """Sends goals one after another and records what became of each.

    ``problem`` is asked between spins; when it returns a reason (interrupted, the stack
    stopped, ...), the current goal is canceled and the loop ends with that as the
    recording's failure.
    """

    def __init__(self, node: EvalNode, recording: Recording, truth_map: OccupancyGrid,
                 map_to_world: tuple[float, float, float], max_speed_mps: float, progress: Progress,
                 problem: Callable[[], str | None], limits: GoalLimits = GoalLimits()) -> None:
        self.node = node
        self.recording = recording
        self.truth_map = truth_map
        self.world_to_map = se2_inverse(map_to_world)
        self.max_speed_mps = max_speed_mps
        self.progress = progress
        self.problem = problem
        self.limits = limits

    def run(self, goals: Sequence[tuple[float, float, float]]) -> None:
        if not self.node.navigator.wait_for_server(timeout_sec=self.limits.server_wall_s):
            self.recording.failure = f"no navigate_to_pose server after {self.limits.server_wall_s:.0f} s"
            return
        self.recording.start_sim_s = self.recording.end_sim_s = self.node.sim_now_s or 0.0
        self.node.driving = True
        for index, goal in enumerate(goals):
            self._show(index, len(goals))
            failure = self._one(goal)
            if failure is not None:
                self.recording.failure = failure
                return
        self._show(len(goals), len(goals))

    def _show(self, index: int, count: int) -> None:
        reached = sum(1 for r in self.recording.goals if r.status == "succeeded")
        self.progress.update(index / max(count, 1), lambda: f"goal {min(index + 1, count)}/{count}, "
                             f"{reached} succeeded, sim {self.recording.sim_seconds:6.1f} s")

    def _spin(self) -> str | None:
        self.node.spin_pending(0.05)
        if self.node.sim_now_s is not None:
            self.recording.end_sim_s = self.node.sim_now_s
        return self.problem()

    def _wait(self, future: Future, wall_s: float) -> str | None:
        """Spin until ``future`` is done; a problem, or None (done, or not within ``wall_s``)."""
        deadline = time.monotonic() + wall_s
        while not future.done() and time.monotonic() < deadline:
            problem = self._spin()
            if problem is not None:
                return problem
        return None

    def _one(self, goal: tuple[float, float, float]) -> str | None:
        truth = self.node.truth_pose
        shortest = shortest_path_m(self.truth_map, truth[:2], goal[:2]) if truth is not None else None
        limit_s = self.limits.base_s + self.limits.per_shortest * (shortest or 0.0) / self.max_speed_mps
        x, y, yaw = (float(v) for v in se2_compose(self.world_to_map, goal))
        start_s = self.node.sim_now_s or 0.0
        sent = self.node.send_goal(x, y, yaw)
        problem = self._wait(sent, self.limits.answer_wall_s)
        handle = sent.result() if sent.done() else None
        if problem is not None or handle is None or not handle.accepted:
            self._record(goal, start_s, "rejected", shortest)
            return problem or ("the navigator did not answer a goal" if handle is None else None)
        result_future = handle.get_result_async()
        while not result_future.done():
            problem = self._spin()
            timed_out = (self.node.sim_now_s or 0.0) - start_s > limit_s
            if problem is not None or timed_out:
                self._wait(handle.cancel_goal_async(), self.limits.answer_wall_s)
                self._wait(result_future, self.limits.answer_wall_s)
                self._record(goal, start_s, "timeout" if problem is None else "canceled", shortest,
                             error_msg=f"no result within {limit_s:.0f} sim seconds" if problem is None else problem)
                return problem
        response = result_future.result()
        self._record(goal, start_s, STATUS_NAMES.get(response.status, f"status {response.status}"), shortest,
                     int(response.result.error_code), str(response.result.error_msg))
        return None

    def _record(self, goal: tuple[float, float, float], start_s: float, status: str, shortest: float | None,
                error_code: int = 0, error_msg: str = "") -> None:
        self.recording.goals.append(GoalRecord(
            goal=goal, start_s=start_s, end_s=self.node.sim_now_s or start_s, status=status, error_code=error_code,
            error_msg=error_msg, recoveries=self.node.recoveries, shortest_path_m=shortest))
