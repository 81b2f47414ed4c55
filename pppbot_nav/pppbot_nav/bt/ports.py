"""What Nav2's tree nodes reach outside the tree, as Protocols: action servers, services, the
robot's pose, and the newest message of a topic.

Nav2's nodes take the ROS node from the blackboard and make their own clients; pppbot's take a
:class:`RobotPorts` from the blackboard entry :data:`PORTS_KEY`. The navigator gives one made
of rclpy clients and TF (:mod:`pppbot_nav.ros.bt_ports`); a test gives fakes, so every node's
logic runs without ROS. Messages are ROS's own types (nav2_msgs goals and results,
geometry_msgs poses), as they are on Nav2's blackboards.
"""
from __future__ import annotations

import enum
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

#: the blackboard entry holding the tree's :class:`RobotPorts`
PORTS_KEY = "ports"


class GoalStatus(enum.IntEnum):
    """How an action goal ended (action_msgs/GoalStatus's values)."""

    SUCCEEDED = 4
    CANCELED = 5
    ABORTED = 6


@dataclass(frozen=True)
class Outcome:
    """An ended goal: how it ended and the action's result message."""

    status: GoalStatus
    result: Any


class GoalCall(Protocol):
    """A goal sent to an action server."""

    def accepted(self) -> bool | None:
        """True once the server took it, False if it refused it, None before it answered."""

    def outcome(self) -> Outcome | None:
        """How the goal ended; None while it runs."""

    def cancel(self) -> None:
        """Ask the server to cancel the goal (it answers with a CANCELED outcome)."""


class ActionPort(Protocol):
    def ready(self) -> bool:
        """Whether the action server is there."""

    def send(self, goal: Any, on_feedback: Callable[[Any], None] | None = None) -> GoalCall:
        """Send ``goal``; ``on_feedback`` gets each feedback message."""

    def cancel_all(self) -> None:
        """Cancel every goal of the server (Nav2's cancel nodes)."""


class ServiceCall(Protocol):
    def response(self) -> Any | None:
        """The response; None until it came."""

    def refused(self) -> bool:
        """True when the request was not sent (no such service): no response will come."""


class ServicePort(Protocol):
    def ready(self) -> bool:
        """Whether the service is there."""

    def call(self, request: Any) -> ServiceCall:
        """Send ``request``."""


class RobotPorts(Protocol):
    """What a tree's nodes use beyond the tree."""

    def action(self, name: str, action_type: Any) -> ActionPort:
        """The client of the action server ``name`` (made once, kept)."""

    def service(self, name: str, service_type: Any) -> ServicePort:
        """The client of the service ``name`` (made once, kept)."""

    def transform(self, target_frame: str, source_frame: str) -> tuple[float, float, float] | None:
        """The newest planar pose (x, y, yaw) of ``source_frame`` in ``target_frame``; None when TF
        cannot tell."""

    def latest(self, topic: str, message_type: Any, *, latched: bool = False) -> Any | None:
        """The newest message heard on ``topic`` (subscribed at the first call, ``latched``: transient
        local, as Nav2's selectors); None before one."""


#: The navigator's settings its tree's nodes read where Nav2's read the navigator node's
#: parameters: blackboard entry → Nav2's default.
NAVIGATOR_DEFAULTS: dict[str, Any] = {
    "global_frame": "map", "robot_base_frame": "base_link", "transform_tolerance": 0.1,
    "goal_reached_tol": 0.25, "odom_topic": "odom", "goal_updater_topic": "goal_update",
}


def setting(blackboard: Any, key: str) -> Any:
    """The navigator's setting ``key`` from the blackboard, else Nav2's default."""
    value = blackboard.get(key)
    return NAVIGATOR_DEFAULTS[key] if value is None else value
