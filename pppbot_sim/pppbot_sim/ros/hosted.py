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
any other type is named in a warning and left out.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import yaml
from rclpy.clock import ClockType, ROSClock
from rclpy.node import Node
from rclpy.time import Time

from pppbot_description.urdf_model import RobotModel
from pppbot_sim.errors import SpawnError
from pppbot_sim.runner import PhysicsRunner

#: Plugin files of gz_ros2_control (Fortress's ign_ and Harmonic's gz_ names) and of Gazebo Classic's.
ROS2_CONTROL_PLUGINS = ("gz_ros2_control-system", "ign_ros2_control-system", "gazebo_ros2_control")
DIFF_DRIVE = "diff_drive_controller/DiffDriveController"
JOINT_STATE_BROADCASTER = "joint_state_broadcaster/JointStateBroadcaster"


@dataclass(frozen=True)
class ControllerPlan:
    """What the parameter file asks for: the update rate and the controllers by type."""

    parameters_file: Path
    update_rate_hz: float
    diff_drives: tuple[str, ...]
    unsupported: tuple[tuple[str, str], ...]  # (name, type)


def controllers_file(robot: RobotModel) -> Path | None:
    """The ``<parameters>`` file of the robot's gz_ros2_control plugin (None: no such plugin).

    Raises:
        SpawnError: the plugin names no parameters file, or the file does not exist.
    """
    for plugin in robot.plugins:
        if any(name in plugin.filename for name in ROS2_CONTROL_PLUGINS):
            text = plugin.settings.get("parameters", "")
            if not text:
                raise SpawnError(f"robot '{robot.name}': the {plugin.filename} plugin has no <parameters> file")
            path = Path(text).expanduser()
            if not path.is_file():
                raise SpawnError(f"robot '{robot.name}': the {plugin.filename} plugin's <parameters> file {path} "
                                 "does not exist")
            return path
    return None


def read_plan(path: Path) -> ControllerPlan:
    """The controllers ``path`` declares under ``controller_manager``.

    Raises:
        SpawnError: the file is not valid YAML or its controller_manager section is malformed.
    """
    try:
        document = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise SpawnError(f"{path}: cannot read the controllers file: {exc}") from exc
    section = (document or {}).get("controller_manager", {}) if isinstance(document, dict) else None
    params = section.get("ros__parameters", {}) if isinstance(section, dict) else None
    if not isinstance(params, dict):
        raise SpawnError(f"{path}: controller_manager.ros__parameters must be a mapping")
    rate = params.get("update_rate", 100)
    if not isinstance(rate, (int, float)) or isinstance(rate, bool) or not 0 < rate <= 10000:
        raise SpawnError(f"{path}: controller_manager update_rate = {rate!r}: must be a number in (0, 10000] Hz")
    diff_drives, unsupported = [], []
    for name, value in params.items():
        if not isinstance(value, dict) or "type" not in value:
            continue
        kind = str(value["type"])
        if kind == DIFF_DRIVE:
            diff_drives.append(name)
        elif kind != JOINT_STATE_BROADCASTER:
            unsupported.append((name, kind))
    return ControllerPlan(path, float(rate), tuple(diff_drives), tuple(unsupported))


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


def controller_arguments(plan: ControllerPlan) -> list[str]:
    """The node arguments a hosted controller starts with: its parameters from the file, and
    no /clock subscription (its clock is set by the simulator)."""
    return ["--ros-args", "--params-file", str(plan.parameters_file), "-p", "use_sim_time:=false"]
