"""What Nav2's lifecycle manager does on each command: which transitions, on which nodes, in
which order, and what the managed nodes are in afterwards. No ROS here
(:mod:`pppbot_nav.ros.lifecycle_manager` runs it).

The commands are ``nav2_msgs/srv/ManageLifecycleNodes``'s. Configure and activate go through
``node_names`` in order, everything else in reverse (a server is stopped before what it
needs). STARTUP is configure-all then activate-all; RESET deactivates then cleans up;
SHUTDOWN deactivates, cleans up and shuts down, going on past failures. Any other command
stops at the first node that fails.
"""
from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass
from enum import IntEnum

from pppbot_nav.errors import LifecycleError

#: The lifecycle nodes of Nav2's bringup, in start order: lifecycle_manager_localization's
#: and lifecycle_manager_navigation's ``node_names`` (Jazzy's, without docking_server).
LOCALIZATION_NODES = ("map_server", "amcl")
NAVIGATION_NODES = ("controller_server", "smoother_server", "planner_server", "behavior_server", "velocity_smoother",
                    "collision_monitor", "bt_navigator", "waypoint_follower")
#: The nodes between the controller and twist_mux, which a bringup may leave out.
VELOCITY_CHAIN = ("velocity_smoother", "collision_monitor")


def navigation_nodes(without: Collection[str] = ()) -> tuple[str, ...]:
    """:data:`NAVIGATION_NODES` but ``without`` (nodes of :data:`VELOCITY_CHAIN`).

    Raises:
        LifecycleError: a name that is not one of :data:`VELOCITY_CHAIN`.
    """
    unknown = sorted(set(without) - set(VELOCITY_CHAIN))
    if unknown:
        raise LifecycleError(f"cannot leave out {', '.join(unknown)}: only {' and '.join(VELOCITY_CHAIN)} may be")
    return tuple(name for name in NAVIGATION_NODES if name not in without)


def command_remaps(without: Collection[str] = ()) -> dict[str, str]:
    """Node-scoped remappings that chain the velocity commands as Jazzy's bringup does:
    controller_server and behavior_server → ``cmd_vel_nav`` → velocity_smoother →
    ``cmd_vel_smoothed`` → collision_monitor → ``cmd_vel`` (twist_mux's navigation input).
    A node left out is bridged: what would have gone to it goes to the next."""
    smoother, monitor = (name not in without for name in VELOCITY_CHAIN)
    after_smoother = "cmd_vel_smoothed" if monitor else "cmd_vel"
    source = "cmd_vel_nav" if smoother else after_smoother
    remaps = {}
    if source != "cmd_vel":
        remaps = {"controller_server:cmd_vel": source, "behavior_server:cmd_vel": source}
    if smoother:
        remaps["velocity_smoother:cmd_vel"] = "cmd_vel_nav"
        if not monitor:
            remaps["velocity_smoother:cmd_vel_smoothed"] = "cmd_vel"
    return remaps


class Command(IntEnum):
    STARTUP = 0
    PAUSE = 1
    RESUME = 2
    RESET = 3
    SHUTDOWN = 4
    CONFIGURE = 5
    CLEANUP = 6


class Transition(IntEnum):
    """``lifecycle_msgs/msg/Transition`` ids."""

    CONFIGURE = 1
    CLEANUP = 2
    ACTIVATE = 3
    DEACTIVATE = 4
    UNCONFIGURED_SHUTDOWN = 5


#: The primary state (``lifecycle_msgs/msg/State`` id and label) each transition ends in.
GOAL_STATE = {Transition.CONFIGURE: (2, "inactive"), Transition.CLEANUP: (1, "unconfigured"),
              Transition.ACTIVATE: (3, "active"), Transition.DEACTIVATE: (2, "inactive"),
              Transition.UNCONFIGURED_SHUTDOWN: (4, "finalized")}

#: What the managed nodes are in after each command succeeded (``~/is_active``: ACTIVE).
RESULTING_STATE = {Command.STARTUP: "active", Command.RESUME: "active", Command.PAUSE: "inactive",
                   Command.CONFIGURE: "inactive", Command.CLEANUP: "unconfigured", Command.RESET: "unconfigured",
                   Command.SHUTDOWN: "finalized"}

#: Each command's transitions, each over every node, forward for configure and activate.
_STAGES = {Command.STARTUP: (Transition.CONFIGURE, Transition.ACTIVATE),
           Command.CONFIGURE: (Transition.CONFIGURE,),
           Command.CLEANUP: (Transition.CLEANUP,),
           Command.PAUSE: (Transition.DEACTIVATE,),
           Command.RESUME: (Transition.ACTIVATE,),
           Command.RESET: (Transition.DEACTIVATE, Transition.CLEANUP),
           Command.SHUTDOWN: (Transition.DEACTIVATE, Transition.CLEANUP, Transition.UNCONFIGURED_SHUTDOWN)}

#: Nav2's log lines when a command stops at a failure.
ABORTED = {Command.STARTUP: "Failed to bring up all requested nodes. Aborting bringup.",
           Command.CONFIGURE: "Failed to configure all requested nodes. Aborting bringup.",
           Command.CLEANUP: "Failed to cleanup all requested nodes. Aborting cleanup.",
           Command.PAUSE: "Failed to pause nodes: aborting pause",
           Command.RESUME: "Failed to resume nodes: aborting resume",
           Command.RESET: "Failed to reset nodes: aborting reset"}


@dataclass(frozen=True)
class Step:
    node: str
    transition: Transition

    @property
    def goal_label(self) -> str:
        return GOAL_STATE[self.transition][1]


def command_of(value: int) -> Command:
    """The command a request carries.

    Raises:
        LifecycleError: not one of ManageLifecycleNodes's commands (naming what is allowed).
    """
    try:
        return Command(value)
    except ValueError:
        allowed = ", ".join(f"{c.name}={c.value}" for c in Command)
        raise LifecycleError(f"unknown lifecycle command {value}: one of {allowed}") from None


def plan(command: Command, node_names: list[str]) -> list[Step]:
    """The transitions of ``command`` over ``node_names``, in the order they run."""
    steps = []
    for transition in _STAGES[command]:
        forward = transition in (Transition.CONFIGURE, Transition.ACTIVATE)
        steps += [Step(name, transition) for name in (node_names if forward else node_names[::-1])]
    return steps


def goes_on_after_failure(command: Command) -> bool:
    """SHUTDOWN takes every node down whatever one of them answers (Nav2's ``hard_change``)."""
    return command == Command.SHUTDOWN


def already_there(state_label: str, step: Step) -> bool:
    """Whether a node in ``state_label`` needs no ``step``: it is in the state the step leads to
    (a node configured by hand before STARTUP is not configured again), or a shutdown finds it
    finalized already."""
    return state_label == step.goal_label


def validate_node_names(node_names: list[str]) -> list[str]:
    """``node_names`` as given, checked.

    Raises:
        LifecycleError: empty, an empty or repeated name.
    """
    if not node_names:
        raise LifecycleError("node_names is empty: name the lifecycle nodes to manage, in start order")
    for name in node_names:
        if not name or any(ch.isspace() for ch in name):
            raise LifecycleError(f"node_names has {name!r}: a node name without white space")
    repeated = sorted({n for n in node_names if node_names.count(n) > 1})
    if repeated:
        raise LifecycleError(f"node_names names {', '.join(repeated)} twice")
    return list(node_names)
