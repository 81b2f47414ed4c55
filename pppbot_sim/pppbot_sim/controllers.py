"""The controllers a robot's gz_ros2_control plugin names, read from its parameters file.

A robot whose URDF carries gz_ros2_control's system plugin::

    <gazebo>
      <plugin filename="libgz_ros2_control-system.so" name="gz_ros2_control::GazeboSimROS2ControlPlugin">
        <parameters>/path/to/my_controllers.yaml</parameters>
      </plugin>
    </gazebo>

has the controllers that file lists under ``controller_manager: ros__parameters:``; the
simulator runs them in its process (:mod:`pppbot_sim.ros.hosted`), and the bringup reads their
settings (topics, frames) from the same file.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from pppbot_description.urdf_model import RobotModel
from pppbot_sim.errors import SpawnError

#: Plugin files of gz_ros2_control (Fortress's ign_ and Harmonic's gz_ names) and of Gazebo Classic's.
ROS2_CONTROL_PLUGINS = ("gz_ros2_control-system", "ign_ros2_control-system", "gazebo_ros2_control")
DIFF_DRIVE = "diff_drive_controller/DiffDriveController"
JOINT_STATE_BROADCASTER = "joint_state_broadcaster/JointStateBroadcaster"


@dataclass(frozen=True)
class ControllerPlan:
    """What the parameter file asks for: the update rate and the controllers, (name, type) in the
    file's order."""

    parameters_file: Path
    update_rate_hz: float
    controllers: tuple[tuple[str, str], ...]

    @property
    def diff_drives(self) -> tuple[str, ...]:
        """The names of the diff_drive_controllers."""
        return tuple(name for name, kind in self.controllers if kind == DIFF_DRIVE)


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
    controllers = tuple((str(name), str(value["type"])) for name, value in params.items()
                        if isinstance(value, dict) and "type" in value)
    return ControllerPlan(path, float(rate), controllers)


def controller_parameters(path: Path, name: str) -> dict[str, Any]:
    """The ``ros__parameters`` of controller ``name`` in ``path`` (empty when the file has none).

    Raises:
        SpawnError: the file is not valid YAML.
    """
    try:
        document = yaml.safe_load(path.read_text()) or {}
    except (OSError, yaml.YAMLError) as exc:
        raise SpawnError(f"{path}: cannot read the controllers file: {exc}") from exc
    section = document.get(name, document.get(f"/{name}", {})) if isinstance(document, dict) else {}
    params = section.get("ros__parameters", {}) if isinstance(section, dict) else {}
    return params if isinstance(params, dict) else {}
