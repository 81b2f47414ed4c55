"""The robot the bringup starts: its description (``description:=``, ``xacro_args:=``) and what the
rest of the stack takes from it.

A description is ppp_bot's xacro (the default), or a user's ``.urdf``/``.xacro`` file by path or
``package://pkg/path`` (through the ament index); ``$(find pkg)`` inside a xacro resolves the same
way. What it declares decides:

- **what drives the wheels**: gz_ros2_control's plugin naming a controllers file with a
  ``diff_drive_controller/DiffDriveController`` (the simulator runs it; twist_mux feeds its
  ``~/cmd_vel_unstamped``), or a Gazebo DiffDrive plugin (the simulator runs it; twist_mux feeds
  its topic, or, when that topic is one of twist_mux's inputs, twist_mux keeps its own output
  ``cmd_vel_out`` and the plugin is remapped there, as a bridge remapping would do);
- **frames and topics** SLAM, AMCL and the costmaps use: the odometry frame and topic of the
  drive, ``base_footprint`` (else the root link) for SLAM and AMCL, ``base_link`` (else the root
  link) for the costmaps and the navigator, the first lidar's topic for the scans.
"""
from __future__ import annotations

import enum
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from pppbot_common.launch_args import ArgumentError
from pppbot_description.urdf_model import RobotModel, parse_urdf
from pppbot_description.xacro_model import declared_arguments, default_xacro_path, process_xacro
from pppbot_sim.controllers import controller_parameters, controllers_file, read_plan
from pppbot_sim.gz_plugins import robot_plugins
from pppbot_sim.uris import resolve_uri

#: twist_mux's own name for its output, used when the drive's topic is one of its inputs.
MUX_OWN_OUTPUT = "/cmd_vel_out"
LIDAR_TYPES = ("gpu_lidar", "lidar", "gpu_ray", "ray")


class Drive(enum.Enum):
    """What moves the robot's wheels."""

    ROS2_CONTROL = "ros2_control"  # gz_ros2_control's controllers, a diff_drive_controller among them
    GAZEBO_PLUGIN = "gazebo_plugin"  # a Gazebo DiffDrive plugin
    NONE = "none"


@dataclass(frozen=True)
class RobotFacts:
    """What the bringup takes from the description."""

    name: str
    drive: Drive
    command_topic: str  # where twist_mux's output goes
    simulator_cmd_vel_topic: str  # the robot's DiffDrive plugin listens here instead of its own topic ("": its own)
    odom_topic: str
    odom_frame: str
    localization_base_frame: str  # SLAM's base_frame, AMCL's base_frame_id
    navigation_base_frame: str  # the costmaps' and the navigator's robot_base_frame
    scan_topic: str | None
    notes: tuple[str, ...] = ()  # what the user should act on
    info: tuple[str, ...] = ()  # what the bringup does about the description


def parse_xacro_args(text: str) -> dict[str, str]:
    """``name:=value name:=value`` (what ``xacro_args:=`` holds) as a mapping.

    Raises:
        ArgumentError: an item that is not ``name:=value``.
    """
    mappings = {}
    for item in text.split():
        name, sep, value = item.partition(":=")
        if not sep or not name:
            raise ArgumentError(f"xacro_args: '{item}' is not of the form name:=value")
        mappings[name] = value
    return mappings


def description_path(description: str) -> Path:
    """The file ``description:=`` names: a path, ``file://``, or ``package://pkg/path``; ppp_bot's
    xacro when empty.

    Raises:
        ArgumentError: no such file (the message says where it looked).
    """
    if not description:
        return default_xacro_path()
    try:
        path, _ = resolve_uri(description, Path.cwd(), [])
    except ValueError as exc:
        raise ArgumentError(f"description:={description}: {exc}") from exc
    path = path.expanduser()
    if not path.is_file():
        raise ArgumentError(f"description:={description}: no such file ({path})")
    if path.suffix not in (".urdf", ".xacro", ".xml"):
        raise ArgumentError(f"description:={description}: expected a .urdf or .xacro file, not '{path.suffix}'")
    return path


def load_description(description: str, xacro_args: str, controllers: Path) -> tuple[str, str]:
    """(URDF XML, its source for messages). A xacro declaring ``controllers_file`` (ppp_bot's) gets
    ``controllers`` unless ``xacro_args`` sets it.

    Raises:
        ArgumentError: a bad ``description:=`` or ``xacro_args:=``.
        DescriptionError: a xacro error or an unreadable file, with file and line.
    """
    path = description_path(description)
    mappings = parse_xacro_args(xacro_args)
    if path.suffix != ".xacro":
        if mappings:
            raise ArgumentError(f"xacro_args:={xacro_args}: {path} is not a xacro file")
        return path.read_text(), str(path)
    if "controllers_file" in declared_arguments([path]) and "controllers_file" not in mappings:
        mappings["controllers_file"] = str(controllers)
    return process_xacro(path, mappings), str(path)


def _absolute(topic: str) -> str:
    return "/" + topic.strip().strip("/")


def robot_facts(urdf: str, source: str, mux_inputs: Sequence[str]) -> RobotFacts:
    """What the description at ``source`` declares, for a bringup whose twist_mux listens on
    ``mux_inputs``.

    Raises:
        DescriptionError: the URDF is malformed.
        SpawnError, PluginError: its controllers file or DiffDrive plugin cannot work.
    """
    robot = parse_urdf(urdf, source)
    notes: list[str] = []
    info: list[str] = []
    lidars = [s for s in robot.sensors if s.type in LIDAR_TYPES]
    scan_topic = _absolute(lidars[0].topic) if lidars else None
    if not lidars:
        notes.append(f"robot '{robot.name}' has no lidar (<gazebo reference><sensor type='gpu_lidar'>): SLAM, "
                     "AMCL and the costmaps get no scans")
    base = "base_footprint" if "base_footprint" in robot.links else robot.root
    nav_base = "base_link" if "base_link" in robot.links else robot.root
    drive, command, remap, odom_topic, odom_frame = _drive(robot, mux_inputs, notes, info)
    return RobotFacts(robot.name, drive, command, remap, odom_topic, odom_frame, base, nav_base, scan_topic,
                      tuple(notes), tuple(info))


def _drive(robot: RobotModel, mux_inputs: Sequence[str], notes: list[str],
           info: list[str]) -> tuple[Drive, str, str, str, str]:
    """(drive, twist_mux's output, the plugin's remap, odometry topic, odometry frame)."""
    path = controllers_file(robot)
    if path is not None:
        plan = read_plan(path)
        if plan.diff_drives:
            name = plan.diff_drives[0]
            params = controller_parameters(path, name)
            return (Drive.ROS2_CONTROL, f"/{name}/cmd_vel_unstamped", "", "/odom",
                    str(params.get("odom_frame_id", "odom")))
        notes.append(f"{path} runs no diff_drive_controller/DiffDriveController: nothing drives the wheels")
    plugins = robot_plugins(robot.plugins, robot.name, robot.root).diff_drives
    if plugins:
        spec = plugins[0]
        if spec.tf_topic != "/tf":
            notes.append(f"{spec.where}: the DiffDrive plugin publishes {spec.frame_id} → {spec.child_frame_id} "
                         f"on {spec.tf_topic or 'no topic'}, not /tf: SLAM and AMCL see no odometry frame "
                         "(set <tf_topic>/tf</tf_topic>, or <publish_odom_tf>true in Gazebo classic)")
        if spec.topic in {_absolute(t) for t in mux_inputs}:
            info.append(f"the DiffDrive plugin's topic {spec.topic} is one of twist_mux's inputs: twist_mux "
                         f"publishes on {MUX_OWN_OUTPUT} and the plugin listens there")
            return Drive.GAZEBO_PLUGIN, MUX_OWN_OUTPUT, MUX_OWN_OUTPUT, spec.odom_topic, spec.frame_id
        return Drive.GAZEBO_PLUGIN, spec.topic, "", spec.odom_topic, spec.frame_id
    if path is None:
        notes.append(f"robot '{robot.name}' has no gz_ros2_control plugin with a diff_drive_controller and no "
                     "Gazebo DiffDrive plugin: nothing drives its wheels")
    return Drive.NONE, MUX_OWN_OUTPUT, "", "/odom", "odom"


#: ppp_bot's robot, as the shipped parameter files expect it.
PPP_BOT = RobotFacts("ppp_bot", Drive.ROS2_CONTROL, "/diff_drive_base_controller/cmd_vel_unstamped", "", "/odom",
                     "odom", "base_footprint", "base_link", "/scan")


def adapt_parameters(document: object, robot: RobotFacts) -> list[str]:
    """Point a parameter file's frames and topics at ``robot``'s where the file has ppp_bot's
    (``base_footprint``, ``base_link``, ``odom``, ``scan``); the document is changed in place.
    Returns what changed (``key: old → new``), empty when nothing did."""
    follow: dict[str, tuple[tuple[str, ...], str | None]] = {
        "base_frame": (("base_footprint",), robot.localization_base_frame),
        "base_frame_id": (("base_footprint",), robot.localization_base_frame),
        "robot_base_frame": (("base_link",), robot.navigation_base_frame),
        "odom_frame": (("odom",), robot.odom_frame),
        "odom_frame_id": (("odom",), robot.odom_frame),
        "global_frame": (("odom",), robot.odom_frame),
        "odom_topic": (("odom", "/odom"), robot.odom_topic),
        "scan_topic": (("scan", "/scan"), robot.scan_topic),
        "topic": (("scan", "/scan"), robot.scan_topic),
    }
    changes: list[str] = []

    def walk(node: object) -> None:
        if isinstance(node, dict):
            for key, value in node.items():
                rule = follow.get(key)
                if rule is not None and isinstance(value, str) and value in rule[0] and rule[1] is not None \
                        and _absolute(value) != _absolute(rule[1]) and value != rule[1]:
                    node[key] = rule[1]
                    changes.append(f"{key}: {value} → {rule[1]}")
                else:
                    walk(value)
        elif isinstance(node, list):
            for item in node:
                walk(item)

    walk(document)
    if robot.navigation_base_frame != "base_link" and isinstance(document, dict) and "planner_server" in document:
        document.setdefault("bt_navigator", {}).setdefault("ros__parameters", {})["robot_base_frame"] = \
            robot.navigation_base_frame
        changes.append(f"navigator robot_base_frame → {robot.navigation_base_frame}")
    monitor = document.get("collision_monitor") if isinstance(document, dict) else None
    monitored = monitor.get("ros__parameters") if isinstance(monitor, dict) else None
    if isinstance(monitored, dict) and monitored.get("base_frame_id") == "base_link" \
            and robot.navigation_base_frame != "base_link":
        monitored["base_frame_id"] = robot.navigation_base_frame  # its zones are around the navigation base
        changes.append(f"collision_monitor base_frame_id: base_link → {robot.navigation_base_frame}")
    return sorted(set(changes))
