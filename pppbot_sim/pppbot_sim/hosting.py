"""What the simulator hosts in its process, and how a package offers it.

gz_ros2_control loads ros2_control's controllers into Gazebo's process through pluginlib; the
simulator finds its hosted controllers the Python way, through entry points, by the controller
type the robot's controllers file names (``diff_drive_controller/DiffDriveController``):

* group :data:`CONTROLLERS`: one entry per controller type, named by that type, whose object is a
  :data:`ControllerFactory` (a :class:`HostRequest` in, a :class:`HostedController` out);
* group :data:`MANAGERS`: an entry ``controller_manager`` whose object is a
  :data:`ManagerFactory`: the ROS node that lists and switches the hosted controllers;
* group :data:`NODES`: nodes the simulator's process runs beside it when asked to
  (``simulator --host robot_state_publisher``, what ``launch_sim`` does with
  ``use_composition:=true``), their topics in-process and, in lockstep, on its step port.

A package registers into them in its ``setup.py``; ``pppbot_control`` does::

    entry_points={
        "pppbot_sim.hosted_controllers": [
            "diff_drive_controller/DiffDriveController = pppbot_control.ros.hosting:diff_drive_controller"],
        "pppbot_sim.controller_managers": ["controller_manager = pppbot_control.ros.hosting:controller_manager"],
        "pppbot_sim.hosted_nodes": ["twist_mux = pppbot_control.ros.twist_mux:TwistMuxNode"],
    }

The simulator imports none of them by name: the interface is this module's Protocols. A hosted
controller is ticked by the physics loop every ``update_rate`` of sim time with the joints read
and commanded directly (:class:`JointIO`), so it never misses a period, whatever the machine does.
"""
from __future__ import annotations

import functools
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from importlib.metadata import EntryPoint, entry_points
from typing import Any, Protocol, runtime_checkable

from pppbot_sim.errors import SpawnError

#: the entry-point group of hostable controller types (name: the ros2_control type)
CONTROLLERS = "pppbot_sim.hosted_controllers"
#: the entry-point group of the controller manager (name: ``controller_manager``)
MANAGERS = "pppbot_sim.controller_managers"
MANAGER = "controller_manager"
#: the entry-point group of nodes the simulator's process can run beside it (name: the node's
#: executable, ``robot_state_publisher``; object: its node class, made with ``port=`` and rclpy's
#: Node arguments), as a component container loads components
NODES = "pppbot_sim.hosted_nodes"


class JointIO(Protocol):
    """The robot's joints as a hosted controller reads and commands them (ros2_control's hardware
    interface, in the simulator)."""

    def read(self) -> tuple[Sequence[str], Sequence[float], Sequence[float], int]:
        """(joint names, positions in rad, velocities in rad/s, sim time of the reading in ns)."""

    def write(self, velocities: Mapping[str, float]) -> None:
        """Velocity targets (rad/s) by joint name."""


@runtime_checkable
class HostedController(Protocol):
    """One controller the simulator hosts."""

    #: its name in the controllers file (its node's name)
    name: str
    #: its ros2_control type (``diff_drive_controller/DiffDriveController``)
    type: str
    #: the ``joint/interface`` names it commands (claimed while active) and reads
    command_interfaces: tuple[str, ...]
    state_interfaces: tuple[str, ...]

    @property
    def node(self) -> Any:
        """Its ROS node (an rclpy Node the simulator spins and destroys), or None."""

    def update(self, t_ns: int) -> None:
        """One control period at sim time ``t_ns``: read the joints, command them, publish."""

    def activate(self) -> None:
        """controller_manager's activate."""

    def deactivate(self) -> None:
        """controller_manager's deactivate: the joints it commands are commanded to rest."""


@dataclass(frozen=True)
class HostRequest:
    """What the simulator hands a controller factory."""

    name: str
    type: str
    joints: JointIO
    #: the node's arguments: ``--ros-args``, the controllers file as its parameters, remappings
    node_arguments: list[str]
    #: the simulator process's step port (:class:`pppbot_lockstep.ros.port.StepPort`)
    port: Any
    update_rate_hz: float


@dataclass(frozen=True)
class ManagerRequest:
    """What the simulator hands the controller manager's factory."""

    controllers: Sequence[HostedController]
    #: every controller the file declares, hosted or not: name → type
    declared: Mapping[str, str]
    #: the types this process can host (the simulator's own and :data:`CONTROLLERS`'s)
    hostable: Sequence[str]
    #: the robot's ``<ros2_control>`` interfaces, ``joint/interface``
    command_interfaces: tuple[str, ...]
    state_interfaces: tuple[str, ...]
    node_arguments: list[str]
    port: Any
    update_rate_hz: float


ControllerFactory = Callable[[HostRequest], HostedController]
ManagerFactory = Callable[[ManagerRequest], Any]


@functools.cache
def registered(group: str) -> Mapping[str, EntryPoint]:
    """The entry points of ``group`` by name (the first package's, when two register one name)."""
    found: dict[str, EntryPoint] = {}
    for point in entry_points(group=group):
        found.setdefault(point.name, point)
    return found


def load(point: EntryPoint) -> Callable[..., Any]:
    """The object ``point`` names.

    Raises:
        SpawnError: it does not import, or is not callable.
    """
    try:
        factory = point.load()
    except Exception as exc:  # an ImportError, or whatever the module raises while importing
        raise SpawnError(f"entry point '{point.name} = {point.value}' (group {point.group}) does not load: "
                         f"{type(exc).__name__}: {exc}") from exc
    if not callable(factory):
        raise SpawnError(f"entry point '{point.name} = {point.value}' (group {point.group}) names "
                         f"{type(factory).__name__}, not a factory")
    return factory


def controller_factory(kind: str) -> ControllerFactory | None:
    """The factory of controller type ``kind`` (None: no package offers it).

    Raises:
        SpawnError: the registered entry point does not load.
    """
    point = registered(CONTROLLERS).get(kind)
    return None if point is None else load(point)


def manager_factory() -> ManagerFactory | None:
    """The controller manager's factory (None: no package offers one).

    Raises:
        SpawnError: the registered entry point does not load.
    """
    point = registered(MANAGERS).get(MANAGER)
    return None if point is None else load(point)


def node_factories(names: Sequence[str]) -> list[Callable[..., Any]]:
    """The node classes of the :data:`NODES` entries ``names``, in order.

    Raises:
        SpawnError: a name no installed package registers, or an entry that does not load.
    """
    found = registered(NODES)
    unknown = [name for name in names if name not in found]
    if unknown:
        raise SpawnError(f"no installed package offers node(s) {', '.join(unknown)} to the simulator's process "
                         f"(entry point group {NODES}: {', '.join(sorted(found)) or 'none'})")
    return [load(found[name]) for name in names]
