"""Controllers in the simulator's process, as gz_ros2_control runs ros2_control inside Gazebo.

A robot whose URDF carries gz_ros2_control's system plugin::

    <gazebo>
      <plugin filename="libgz_ros2_control-system.so" name="gz_ros2_control::GazeboSimROS2ControlPlugin">
        <parameters>/path/to/my_controllers.yaml</parameters>
      </plugin>
    </gazebo>

gets the controllers that file lists under ``controller_manager: ros__parameters:`` loaded
into the simulator's process: each a ROS node of its own (its name, its parameters from
the same file, its topics), ticked by the physics loop every ``update_rate`` of sim time,
reading and commanding the joints directly. A controller in the simulator's process never
misses a period, whatever the machine is doing; that is what ppp_bot's controllers get in
Gazebo. Controller types come from the packages that register them
(:mod:`pppbot_sim.hosting`: ``pppbot_control`` offers ``diff_drive_controller/DiffDriveController``
and the ``controller_manager`` node that lists and switches them);
``joint_state_broadcaster/JointStateBroadcaster`` is the simulator's own ``/joint_states``;
any other type is named in a warning and left out.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from pppbot_description.urdf_model import RobotModel
from pppbot_lockstep.ros.port import StepPort
from pppbot_sim.controllers import JOINT_STATE_BROADCASTER, ControllerPlan
from pppbot_sim.errors import SpawnError
from pppbot_sim.hosting import (
    CONTROLLERS,
    ControllerFactory,
    HostedController,
    HostRequest,
    JointIO,
    ManagerFactory,
    ManagerRequest,
    controller_factory,
    manager_factory,
    registered,
)
from pppbot_sim.runner import PhysicsRunner


class SimWheels:
    """The joints of the simulated robot as a hosted controller reads and commands them."""

    def __init__(self, runner: PhysicsRunner) -> None:
        self.runner = runner

    def read(self) -> tuple[Sequence[str], Sequence[float], Sequence[float], int]:
        state = self.runner.sim.wheel_state()
        return state.names, state.positions.tolist(), state.velocities.tolist(), self.runner.sim.time_ns

    def write(self, velocities: Mapping[str, float]) -> None:
        self.runner.command(velocities)


def controller_arguments(plan: ControllerPlan, remappings: Sequence[str] = ()) -> list[str]:
    """The node arguments a hosted controller (and the controller manager) starts with: its
    parameters from the file, no /clock subscription (its clock is set by the simulator), and
    ``remappings`` (``from:=to``, as gz_ros2_control's ``<ros><remapping>`` elements give them).

    Raises:
        SpawnError: a remapping without ``:=``.
    """
    args = ["--ros-args", "--params-file", str(plan.parameters_file), "-p", "use_sim_time:=false"]
    for rule in remappings:
        source, sep, target = rule.partition(":=")
        if not (source and sep and target):
            raise SpawnError(f"controller remapping '{rule}': must read from:=to")
        args += ["-r", rule]
    return args


class HostedBroadcaster:
    """joint_state_broadcaster in the simulator: the simulator's own /joint_states, published
    while it is active (controller_manager switches it)."""

    type = JOINT_STATE_BROADCASTER
    command_interfaces: tuple[str, ...] = ()
    node = None

    def __init__(self, name: str, state_interfaces: tuple[str, ...]) -> None:
        self.name = name
        self.state_interfaces = state_interfaces
        self.active = True

    def update(self, t_ns: int) -> None:
        pass  # the simulator publishes /joint_states at its own rate

    def activate(self) -> None:
        self.active = True

    def deactivate(self) -> None:
        self.active = False


@dataclass
class Hosted:
    """What the simulator hosts for a robot: controllers ticked by the physics loop, its joint state
    broadcasters, the controller manager node (None: no package offers one)."""

    controllers: list[HostedController] = field(default_factory=list)
    broadcasters: list[HostedBroadcaster] = field(default_factory=list)
    manager: Any = None
    #: (name, type) of each controller left out: no package hosts its type
    left_out: list[tuple[str, str]] = field(default_factory=list)

    @property
    def nodes(self) -> list[Any]:
        """The ROS nodes of what is hosted (the simulator spins and destroys them)."""
        return [c.node for c in self.controllers if c.node is not None] + ([self.manager] if self.manager else [])


def host(plan: ControllerPlan, robot: RobotModel, joints: JointIO, arguments: list[str], port: StepPort,
         *, factory: Callable[[str], ControllerFactory | None] = controller_factory,
         manager: Callable[[], ManagerFactory | None] = manager_factory) -> Hosted:
    """The controllers ``plan`` declares, made by the packages that register their types, and the
    controller manager over them with the robot's ``<ros2_control>`` interfaces. ``factory`` finds a
    type's factory, ``manager`` the manager's (default: the registered ones).

    Raises:
        SpawnError: a registered factory does not load, or its controller is not one
            (:class:`~pppbot_sim.hosting.HostedController`).
    """
    joints_ = robot.control_joints.values()
    command = tuple(f"{j.name}/{i}" for j in joints_ for i in j.command_interfaces)
    state = tuple(f"{j.name}/{i}" for j in joints_ for i in j.state_interfaces)
    hosted = Hosted()
    for name, kind in plan.controllers:
        if kind == JOINT_STATE_BROADCASTER:
            hosted.broadcasters.append(HostedBroadcaster(name, state))
            continue
        make = factory(kind)
        if make is None:
            hosted.left_out.append((name, kind))
            continue
        controller = make(HostRequest(name, kind, joints, list(arguments), port, plan.update_rate_hz))
        if not isinstance(controller, HostedController):
            raise SpawnError(f"controller '{name}' of type {kind}: its factory made a {type(controller).__name__}, "
                             "which lacks what pppbot_sim.hosting.HostedController has")
        hosted.controllers.append(controller)
    make_manager = manager()
    if make_manager is not None:
        hostable = sorted({JOINT_STATE_BROADCASTER, *registered(CONTROLLERS)})
        hosted.manager = make_manager(ManagerRequest(
            [*hosted.controllers, *hosted.broadcasters], dict(plan.controllers), hostable, command, state,
            list(arguments), port, plan.update_rate_hz))
    return hosted
