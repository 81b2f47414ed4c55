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
reading and commanding the wheels directly. A controller in the simulator's process never
misses a period, whatever the machine is doing; that is what ppp_bot's controllers get in
Gazebo. ``diff_drive_controller/DiffDriveController`` is hosted;
``joint_state_broadcaster/JointStateBroadcaster`` is the simulator's own ``/joint_states``;
any other type is named in a warning and left out. A ``controller_manager`` node
(:mod:`pppbot_control.ros.controller_manager`) lists and switches them, as gz_ros2_control's
controller manager does.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence

from rclpy.clock import ClockType, ROSClock
from rclpy.node import Node
from rclpy.time import Time

from pppbot_control.ros.controller_manager import (
    DIFF_DRIVE,
    JOINT_STATE_BROADCASTER,
    ControllerManager,
    HardwareInterfaces,
    LoadedController,
)
from pppbot_control.ros.diff_drive_controller import DiffDriveController
from pppbot_description.urdf_model import RobotModel
from pppbot_sim.controllers import ControllerPlan
from pppbot_sim.errors import SpawnError
from pppbot_sim.runner import PhysicsRunner


class SimWheels:
    """The wheels of the simulated robot as a hosted controller reads and commands them."""

    def __init__(self, runner: PhysicsRunner) -> None:
        self.runner = runner

    def read(self) -> tuple[Sequence[str], Sequence[float], Sequence[float], int]:
        state = self.runner.sim.wheel_state()
        return state.names, state.positions.tolist(), state.velocities.tolist(), self.runner.sim.time_ns

    def write(self, velocities: Mapping[str, float]) -> None:
        self.runner.command(velocities)


def drive_clock(node: Node, t_ns: int) -> None:
    """Set ``node``'s clock to sim time ``t_ns`` (the simulator's in-process nodes run on the
    simulation itself, not on /clock)."""
    clock = node.get_clock()
    if isinstance(clock, ROSClock):
        if not clock.ros_time_is_active:
            clock._set_ros_time_is_active(True)
        clock.set_ros_time_override(Time(nanoseconds=t_ns, clock_type=ClockType.ROS_TIME))


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

    def __init__(self) -> None:
        self.active = True

    def activate(self) -> None:
        self.active = True

    def deactivate(self) -> None:
        self.active = False


def hosted_controller_manager(plan: ControllerPlan, robot: RobotModel, controllers: Sequence[DiffDriveController],
                              broadcasters: Sequence[HostedBroadcaster], arguments: list[str]) -> ControllerManager:
    """The controller manager over the hosted diff drives and joint_state_broadcasters, with the
    robot's ``<ros2_control>`` interfaces."""
    joints = robot.control_joints.values()
    hardware = HardwareInterfaces(command=tuple(f"{j.name}/{i}" for j in joints for i in j.command_interfaces),
                                  state=tuple(f"{j.name}/{i}" for j in joints for i in j.state_interfaces))
    loaded = []
    for controller in controllers:
        p = controller.params
        wheels = [*p.left_wheel_names, *p.right_wheel_names]
        feedback = "position" if p.position_feedback else "velocity"
        loaded.append(LoadedController(controller.get_name(), DIFF_DRIVE, controller, plan.update_rate_hz,
                                       command_interfaces=tuple(f"{w}/velocity" for w in wheels),
                                       state_interfaces=() if p.open_loop else tuple(f"{w}/{feedback}"
                                                                                     for w in wheels)))
    for name, broadcaster in zip(plan.broadcasters, broadcasters, strict=True):
        loaded.append(LoadedController(name, JOINT_STATE_BROADCASTER, broadcaster, plan.update_rate_hz,
                                       state_interfaces=hardware.state))
    declared = {**dict.fromkeys(plan.diff_drives, DIFF_DRIVE),
                **dict.fromkeys(plan.broadcasters, JOINT_STATE_BROADCASTER), **dict(plan.unsupported)}
    return ControllerManager(loaded, hardware, declared, cli_args=arguments)
