"""Waypoint following's decisions, as Nav2's ``waypoint_follower`` makes them (no ROS here).

A :class:`WaypointRun` walks the poses of one follow_waypoints goal: from ``goal_index`` to the
last pose, then ``number_of_loops`` more times from the first. After each pose it is told how
it went, :meth:`WaypointRun.reached` (navigation succeeded; with whether the waypoint task
succeeded) or :meth:`WaypointRun.missed` (navigation failed; with the navigator's error code),
and answers with a :class:`Decision`: navigate to the next pose, succeed, or stop. Every miss
is recorded in :attr:`WaypointRun.missed_waypoints`; with ``stop_on_failure`` the first one
ends the run, else the run goes on to the next pose (and the goal succeeds at the end, the
misses in its result), as Nav2's does.

Waypoint task executors (Nav2's ``waypoint_task_executor_plugin``) implement
:class:`TaskExecutor` and are chosen by their Nav2 plugin type from :data:`TASK_EXECUTORS`;
pppbot has ``nav2_waypoint_follower::WaitAtWaypoint`` (:class:`WaitAtWaypoint`).
"""
from __future__ import annotations

import enum
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from pppbot_nav.errors import WaypointError


class Next(enum.Enum):
    """What a run does after a pose."""

    NAVIGATE = "navigate"  # to the pose Decision.index
    SUCCEED = "succeed"  # every pose of every loop handled
    STOP_ON_MISSED_WAYPOINT = "stop on missed waypoint"  # navigation failed, stop_on_failure
    STOP_ON_TASK_FAILURE = "stop on task failure"  # the waypoint task failed, stop_on_failure


@dataclass(frozen=True)
class Decision:
    next: Next
    index: int  # NAVIGATE: the pose to go to; otherwise the pose just handled


class MissReason(enum.Enum):
    NAVIGATION = "navigation failed"
    TASK = "waypoint task failed"


@dataclass(frozen=True)
class MissedWaypoint:
    """A pose that was not handled: its index in the goal's poses, why, and the navigator's error
    code (0 for a task failure, or a navigation that ended without one: canceled, rejected)."""

    index: int
    reason: MissReason
    navigation_error_code: int = 0


class WaypointRun:
    """One goal's way through its poses (see the module's docstring).

    Raises:
        WaypointError: no poses, a ``goal_index`` out of range or a negative ``number_of_loops``.
    """

    def __init__(self, count: int, *, goal_index: int = 0, number_of_loops: int = 0,
                 stop_on_failure: bool = True) -> None:
        if count <= 0:
            raise WaypointError("no waypoints to follow: the goal has no poses")
        if not 0 <= goal_index < count:
            raise WaypointError(f"goal_index {goal_index} is out of range: the goal has {count} poses "
                                f"(0 to {count - 1})")
        if number_of_loops < 0:
            raise WaypointError(f"number_of_loops {number_of_loops} must be ≥ 0")
        self.count = count
        self.number_of_loops = number_of_loops
        self.stop_on_failure = stop_on_failure
        #: The pose being handled now.
        self.index = goal_index
        #: Loops completed so far (0 during the first pass).
        self.loop = 0
        self.missed_waypoints: list[MissedWaypoint] = []

    def reached(self, task_succeeded: bool) -> Decision:
        """The robot reached the current pose and its waypoint task ran: what next."""
        if not task_succeeded:
            self.missed_waypoints.append(MissedWaypoint(self.index, MissReason.TASK))
            if self.stop_on_failure:
                return Decision(Next.STOP_ON_TASK_FAILURE, self.index)
        return self._advance()

    def missed(self, navigation_error_code: int = 0) -> Decision:
        """Navigation to the current pose failed with ``navigation_error_code``: what next."""
        self.missed_waypoints.append(MissedWaypoint(self.index, MissReason.NAVIGATION, navigation_error_code))
        if self.stop_on_failure:
            return Decision(Next.STOP_ON_MISSED_WAYPOINT, self.index)
        return self._advance()

    def _advance(self) -> Decision:
        if self.index + 1 < self.count:
            self.index += 1
            return Decision(Next.NAVIGATE, self.index)
        if self.loop == self.number_of_loops:
            return Decision(Next.SUCCEED, self.index)
        self.loop += 1
        self.index = 0  # a new loop starts at the first pose, whatever goal_index was
        return Decision(Next.NAVIGATE, self.index)


# ------------------------------------------------------------------ task executors
class TaskStatus(enum.Enum):
    RUNNING = "running"
    SUCCEEDED = "succeeded"
    FAILED = "failed"


class TaskExecutor(Protocol):
    """What runs at each reached waypoint (Nav2's ``nav2_core::WaypointTaskExecutor``), stepped by
    the node on its clock: ``start`` once at the waypoint, then ``step`` until it is done."""

    def start(self, index: int, now_s: float) -> None:
        """The robot reached waypoint ``index`` at ``now_s`` (s, the node's clock)."""

    def step(self, now_s: float) -> TaskStatus:
        """Whether the task is done at ``now_s``, and how it went."""


class WaitAtWaypoint:
    """Nav2's ``wait_at_waypoint``: stay ``waypoint_pause_duration_ms`` at each waypoint (at once
    done when not ``enabled``); it never fails."""

    def __init__(self, *, enabled: bool = True, waypoint_pause_duration_ms: int = 200) -> None:
        if not (math.isfinite(waypoint_pause_duration_ms) and waypoint_pause_duration_ms >= 0):
            raise WaypointError(f"waypoint_pause_duration {waypoint_pause_duration_ms} ms must be ≥ 0")
        self.enabled = enabled
        self.pause_s = waypoint_pause_duration_ms / 1000.0
        self._until_s = -math.inf

    def start(self, index: int, now_s: float) -> None:
        self._until_s = now_s + self.pause_s if self.enabled else -math.inf

    def step(self, now_s: float) -> TaskStatus:
        return TaskStatus.SUCCEEDED if now_s >= self._until_s else TaskStatus.RUNNING


WAIT_AT_WAYPOINT = "nav2_waypoint_follower::WaitAtWaypoint"

#: Waypoint task executors by Nav2 plugin type; each is made from its plugin's settings.
TASK_EXECUTORS: dict[str, Callable[..., TaskExecutor]] = {
    WAIT_AT_WAYPOINT: WaitAtWaypoint,
}


def load_task_executor(plugin_type: str, **settings: Any) -> TaskExecutor:
    """The task executor of Nav2 plugin type ``plugin_type``, made from ``settings``.

    Raises:
        WaypointError: an unknown plugin type (the message lists the known ones), or settings
        the executor refuses.
    """
    factory = TASK_EXECUTORS.get(plugin_type)
    if factory is None:
        raise WaypointError(f"unknown waypoint task executor plugin '{plugin_type}': pppbot has "
                            + ", ".join(f"'{name}'" for name in TASK_EXECUTORS))
    return factory(**settings)
