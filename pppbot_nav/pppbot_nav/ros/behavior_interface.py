"""What a behaviour plugin is: the Protocols the behavior_server asks of an entry point in the
``pppbot_nav.behaviors`` group (:mod:`pppbot_nav.plugins`), Nav2's ``nav2_core::Behavior`` (as
its ``nav2_behaviors::TimedBehavior``: one action, stepped at the server's cycle).

An entry point names a **parameters class** (:class:`BehaviorPlugin`): a frozen dataclass whose
fields are the plugin's parameters (declared under ``<name>.`` with their defaults; most have
none), whose ``validate()`` raises :class:`pppbot_common.params.ParameterError` on a bad value,
whose ``ACTION`` is the action type it serves (as an action named as the behaviour) and whose
``make(context)`` returns the :class:`Behavior`, once, at the server's start (where it may
subscribe to what it reads, as assisted teleop does its teleop commands). Nav2's behaviour server
has no dynamic parameters: a plugin's are read once.

For each goal the server asks ``behavior.begin(request, time_allowance_s)`` for a
:class:`BehaviorRun` (:class:`InvalidInput`: the goal fails with the action's INVALID_INPUT,
UNKNOWN where it has none, and the message). Then, each cycle, with the robot's pose in the
server's ``local_frame`` ((x m, y m, yaw rad)) and the time (s, the node's clock):

1. ``run.start(pose, now_s)``, at the first cycle with a pose;
2. ``run.step(pose, now_s)``: the command (v m/s, ω rad/s), or :class:`~pppbot_nav.behaviors.Outcome`
   ``DONE`` (the goal succeeds) or ``TIMEOUT`` (it fails with TIMEOUT), as the cores of
   :mod:`pppbot_nav.behaviors` step;
3. ``run.collision_ahead(costmap, pose, command)``: why the command must not be sent (the goal
   fails with COLLISION_AHEAD), or None; a behaviour that does not check collisions always
   says None;
4. the command goes out on ``cmd_vel`` and ``run.feedback(msg, elapsed_s)`` fills the action's
   feedback message.

The rest is the server's, alike for every behaviour: one goal at a time (a new one preempts),
cancels, TF_ERROR when no pose comes within ``transform_tolerance``, and stopping the robot when
a goal ends.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol

from pppbot_common.errors import PppbotError
from pppbot_common.maps import OccupancyGrid
from pppbot_lockstep.ros.node import StepNode
from pppbot_nav.behaviors import Outcome, Pose, Velocity


class InvalidInput(PppbotError, ValueError):
    """A goal the behaviour cannot carry out as given (Nav2's INVALID_INPUT); the message says why."""


@dataclass(frozen=True)
class BehaviorSettings:
    """The server's parameters every behaviour may read (Nav2's node-level ones)."""

    cycle_frequency_hz: float  # steps per second
    simulate_ahead_time_s: float  # how far ahead a command is checked for collisions
    max_rotational_vel: float  # rad/s, spin's top speed
    min_rotational_vel: float  # rad/s, spin's lowest speed
    rotational_acc_lim: float  # rad/s², spin's deceleration towards its target


@dataclass(frozen=True)
class BehaviorContext:
    """What the server gives a behaviour at its start."""

    node: StepNode  # the server: a behaviour's own subscriptions go on it
    name: str  # the behaviour's name: its action's name and its parameters' prefix
    settings: BehaviorSettings
    costmap: Callable[[], OccupancyGrid | None]  # the latest local costmap (in local_frame); None before one


class BehaviorRun(Protocol):
    """One goal of a behaviour, stepped by the server (see the module's docstring)."""

    def start(self, pose: Pose, now_s: float) -> None: ...

    def step(self, pose: Pose, now_s: float) -> Velocity | Outcome: ...

    def collision_ahead(self, costmap: OccupancyGrid | None, pose: Pose, command: Velocity) -> str | None:
        """Why ``command`` at ``pose`` would collide (the costmap in local_frame, None: none yet), or None."""
        ...

    def feedback(self, feedback: Any, elapsed_s: float) -> None:
        """Fill ``feedback`` (the action's Feedback message); ``elapsed_s`` since the goal came."""
        ...


class Behavior(Protocol):
    """A behaviour served under its name: a run per goal."""

    def begin(self, request: Any, time_allowance_s: float) -> BehaviorRun:
        """The run of ``request`` (the action's Goal); ``time_allowance_s`` is its ``time_allowance``
        (inf for an action without one).

        Raises:
            InvalidInput: a goal the behaviour refuses, with the reason.
        """
        ...


class BehaviorPlugin(Protocol):
    """An entry point of ``pppbot_nav.behaviors``: the plugin's parameters, validated, its action
    type and its behaviour."""

    ACTION: ClassVar[Any]

    def validate(self) -> None: ...

    def make(self, context: BehaviorContext) -> Behavior: ...
