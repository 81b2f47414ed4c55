"""``launch_sim``'s arguments and node plan: ppp_bot's ``launch_sim.launch.py`` as data.

The ROS side (readiness probes, running the plan) is ``pppbot_bringup.ros.launch_sim``.

Start order, each step waiting for real readiness (a first message, not a sleep):
simulator (first /clock; the robot's controllers run in its process, as gz_ros2_control
runs them in Gazebo) → robot_state_publisher (/robot_description) → twist_mux → mapping or
localization (map_server and amcl; one process) → navigation (planner, controller,
navigator; one process) → RViz (when on PATH) → keyboard teleop. The processes of several
nodes are Nav2's composition (``use_composition:=false``: a process per node). With
``lockstep:=true`` the nodes on the data path are lockstep participants: each is ready once
it has joined (time starts when all have).
"""
from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from pppbot_bringup.paths import config_directory, maps_directory
from pppbot_bringup.supervisor import NodeSpec, ReadyCheck
from pppbot_common.launch_args import Argument, ArgumentError

LOG_LEVELS = ("debug", "info", "warn", "error", "fatal")

ARGUMENTS = [
    Argument("world", "cones", "world name (worlds/<name>.sdf) or path to an SDF or MJCF file"),
    Argument("localization", False, "localize on a saved map (map_server + AMCL) instead of mapping (SLAM)"),
    Argument("map", "", "map YAML for localization; default maps/<world>.yaml"),
    Argument("use_slam", True, "with localization:=false, map with the SLAM node (false: drive on odometry only)"),
    Argument("navigation", "auto", "planner_server, controller_server and navigator (auto: with localization:=true)",
             choices=("auto", "true", "false")),
    Argument("use_composition", True, "map_server and amcl in one process (localization), the navigation nodes "
                                      "in another (navigation), as Nav2's bringup composes its servers "
                                      "(false: a process each)"),
    Argument("slam_params_file", "", "the slam node's parameters; default config/mapper_params_online_async.yaml"),
    Argument("use_teleop", True, "keyboard teleop in this terminal (other nodes' output goes to log files)"),
    Argument("use_rviz", True, "start rviz2 with config/ppp_bot.rviz when rviz2 is on PATH"),
    Argument("headless", True, "no MuJoCo viewer window (false opens one; needs a display)"),
    Argument("real_time_factor", 1.0, "simulated seconds per wall second; 0 = as fast as possible"),
    Argument("lockstep", False, "time advances only when the nodes on the data path have done their work "
                                "(the same run on any machine; with real_time_factor:=0 as fast as they allow)"),
    Argument("x", 0.0, "spawn x (m)"),
    Argument("y", 0.0, "spawn y (m)"),
    Argument("z", 0.05, "spawn z of base_link (m); ppp_bot rests at 0.05"),
    Argument("yaw", 0.0, "spawn yaw (rad)"),
    Argument("seed", 0, "seed of the simulator's sensor noise and wheel slip"),
    Argument("wheel_slip", 0.0, "wheel slip as the encoders see it (0.02 = 2 %): odometry drifts like a real robot's"),
    Argument("log_level", "info", "log level of every node", choices=LOG_LEVELS),
    Argument("record", False, "record every topic (pppbot bag record -a, sim time) while the launch runs"),
    Argument("bag_path", "", "the bag directory for record:=true; default rosbag2_YYYY_MM_DD-HH_MM_SS here"),
    Argument("sigterm_timeout", 5.0, "on shutdown, seconds from SIGINT to SIGTERM for a node still running "
                                     "(ros2 launch's sigterm_timeout)"),
    Argument("sigkill_timeout", 5.0, "seconds from SIGTERM to SIGKILL (ros2 launch's sigkill_timeout)"),
]


def stop_timeouts(values: dict[str, Any]) -> tuple[float, float]:
    """(seconds after SIGINT, seconds after SIGTERM) before the launch escalates.

    Raises:
        ArgumentError: a timeout that is not a positive finite number.
    """
    timeouts = []
    for name in ("sigterm_timeout", "sigkill_timeout"):
        value = float(values[name])
        if not 0.0 < value < float("inf"):
            raise ArgumentError(f"{name}:={value:g}: must be a positive number of seconds")
        timeouts.append(value)
    return timeouts[0], timeouts[1]

Resolver = Callable[[str, str], str]


class Probes(Protocol):
    """Readiness from the ROS graph (:class:`pppbot_bringup.ros.graph_probe.GraphProbe`)."""

    def first_message(self, topic: str, type_name: str, latched: bool) -> Callable[[], bool]:
        """True once a message came on ``topic``."""

    def joined(self, participant: str) -> Callable[[], bool]:
        """True once the simulator lists ``participant`` on /lockstep/status."""


@dataclass(frozen=True)
class Plan:
    nodes: list[NodeSpec]
    notes: list[str]


def ros_args(log_level: str, params: dict[str, Any] | None = None, params_file: Path | None = None,
             remaps: dict[str, str] | None = None, sim_time: bool = True) -> list[str]:
    args = ["--ros-args", "--log-level", log_level]
    if params_file is not None:
        args += ["--params-file", str(params_file)]
    all_params = {"use_sim_time": True} if sim_time else {}
    all_params.update(params or {})
    for name, value in all_params.items():
        text = str(value).lower() if isinstance(value, bool) else str(value)
        args += ["-p", f"{name}:={text}"]
    for old, new in (remaps or {}).items():
        args += ["-r", f"{old}:={new}"]
    return args


def controllers_file() -> Path:
    """ppp_bot's controller parameters: the robot's gz_ros2_control plugin points at them, and the
    simulator runs those controllers in its process."""
    return config_directory() / "my_controllers.yaml"


def plan(values: dict[str, Any], world_file: Path, urdf_file: Path, resolve: Resolver, probes: Probes,  # noqa: C901
         terminal: bool, rviz: str | None, extra_participants: Sequence[str] = ()) -> Plan:
    """The nodes to start, in ppp_bot's order, and notes for the user. ``extra_participants``:
    lockstep participants outside the launch that time must wait for from its start (the
    evaluation's own node).

    Raises:
        ArgumentError: ``localization:=true`` without a map file, or a bag path that exists.
    """
    level = values["log_level"]
    lockstep = bool(values["lockstep"])
    config = config_directory()
    notes: list[str] = []
    participants: list[str] = []

    def participant(name: str, description: str, check: ReadyCheck) -> tuple[dict[str, Any], ReadyCheck]:
        """A lockstep participant's parameters and readiness: joined, in lockstep; else ``check``."""
        if not lockstep:
            return {}, check
        participants.append(name)
        return ({"lockstep": True, "lockstep_name": name},
                ReadyCheck(f"{description} (joined lockstep)", probes.joined(name), timeout_s=check.timeout_s))

    mux_params, mux_ready = participant("twist_mux", "its inputs", ReadyCheck("its inputs", output_pattern=r"inputs: "))
    # A participant too: its wheel transforms are on /tf, which the data path counts.
    rsp_params, rsp_ready = participant("robot_state_publisher", "/robot_description", ReadyCheck(
        "/robot_description", probes.first_message("/robot_description", "std_msgs/msg/String", True)))
    nodes = [
        NodeSpec("robot_state_publisher", [resolve("pppbot_description", "robot_state_publisher"),
                                           *ros_args(level, {"robot_description": urdf_file, **rsp_params})],
                 after=("simulator",), required=True, pppbot_node=True, ready=rsp_ready),
        NodeSpec("twist_mux", [resolve("pppbot_control", "twist_mux"), *ros_args(
            level, mux_params, params_file=config / "twist_mux.yaml",
            remaps={"cmd_vel_out": "/diff_drive_base_controller/cmd_vel_unstamped"})],
            after=("simulator",), required=True, pppbot_node=True, ready=mux_ready),
    ]
    if values["record"]:
        bag = Path(values["bag_path"] or time.strftime("rosbag2_%Y_%m_%d-%H_%M_%S"))
        if bag.exists():
            raise ArgumentError(f"bag_path: '{bag}' exists already; a bag is never overwritten")
        # Right after the simulator, so the rest of the bringup (latched /robot_description,
        # /tf_static) is in the bag; stopping the launch finishes the bag.
        nodes.insert(0, NodeSpec("bag_record", [resolve("pppbot_bringup", "pppbot"), "bag", "record", "-a",
                                                "--use-sim-time", "-o", str(bag)],
                                 after=("simulator",), ready=ReadyCheck("recording", output_pattern=r"recording to ")))
        notes.append(f"recording every topic to {bag} (ends when the launch ends)")
    if values["localization"]:
        map_file = Path(values["map"]) if values["map"] else maps_directory() / f"{world_file.stem}.yaml"
        if not map_file.is_file():
            raise ArgumentError(f"localization:=true needs a map; {map_file} does not exist "
                                f"(save one while mapping, or give map:=path/to/map.yaml)")
        nav2_params = config / "nav2_params.yaml"
        # AMCL starts where the robot was spawned (the shipped maps' frame is the world's, the
        # spawn pose of a map made with the default spawn); RViz's 2D Pose Estimate moves it.
        # The launch's seed seeds AMCL's particles too: one seed makes the whole run repeatable.
        server_params = {"yaml_filename": map_file.resolve()}
        amcl_params = {"set_initial_pose": True, "initial_pose.x": values["x"], "initial_pose.y": values["y"],
                       "initial_pose.yaw": values["yaw"], "seed": values["seed"]}
        amcl_ready = ReadyCheck("an initial pose", output_pattern=r"initial pose \(")
        if values["use_composition"]:
            # One process, as Nav2 composes its servers; each parameter goes to its own node.
            extra, localized = participant("localization", "an initial pose", amcl_ready)
            scoped = {**{f"map_server:{k}": v for k, v in server_params.items()},
                      **{f"amcl:{k}": v for k, v in amcl_params.items()}, **extra}
            nodes.append(NodeSpec("localization", [resolve("pppbot_nav", "localization"), *ros_args(
                level, scoped, params_file=nav2_params)],
                after=("robot_state_publisher",), required=True, pppbot_node=True, ready=localized))
        else:
            nodes.append(NodeSpec("map_server", [resolve("pppbot_nav", "map_server"), *ros_args(
                level, server_params, params_file=nav2_params)],
                after=("simulator",), required=True, pppbot_node=True,
                ready=ReadyCheck("/map", probes.first_message("/map", "nav_msgs/msg/OccupancyGrid", True))))
            extra, localized = participant("amcl", "an initial pose", amcl_ready)
            nodes.append(NodeSpec("amcl", [resolve("pppbot_nav", "amcl"), *ros_args(
                level, {**amcl_params, **extra}, params_file=nav2_params)],
                after=("map_server", "robot_state_publisher"), required=True, pppbot_node=True, ready=localized))
        notes.append(f"localizing on {map_file}")
    elif values["use_slam"]:
        slam_params = Path(values["slam_params_file"] or config / "mapper_params_online_async.yaml")
        if not slam_params.is_file():
            raise ArgumentError(f"slam_params_file: {slam_params} does not exist")
        # Ready once it has mapped its first scan: the map frame is where the robot was then, so
        # nothing should drive it before (eval relies on map = spawn pose). In lockstep the first
        # scan is mapped before time moves past it.
        slam_params_lockstep, slam_ready = participant(
            "slam_toolbox", "a first /map",
            ReadyCheck("a first /map", probes.first_message("/map", "nav_msgs/msg/OccupancyGrid", True)))
        nodes.append(NodeSpec("slam_toolbox", [resolve("pppbot_slam", "slam"), *ros_args(
            level, slam_params_lockstep, params_file=slam_params)],
            after=("robot_state_publisher",), required=True, pppbot_node=True, ready=slam_ready))
    localizer = (("localization" if values["use_composition"] else "amcl") if values["localization"]
                 else "slam_toolbox" if values["use_slam"] else None)
    if values["navigation"] == "true" or (values["navigation"] == "auto" and values["localization"]):
        if localizer is None:
            raise ArgumentError("navigation:=true needs a map frame: localization:=true or use_slam:=true")
        nav2_params = config / "nav2_params.yaml"
        servers: tuple[tuple[str, str], ...] = (("planner_server", r"planner 'GridBased' ready"),
                                                ("controller_server", r"controller 'FollowPath'"),
                                                ("navigator", r"navigator ready"))
        if values["use_composition"]:
            # The navigator is made last: its line means all three are.
            servers = (("navigation", r"navigator ready"),)
        for name, ready in servers:
            extra, check = participant(name, name, ReadyCheck(name, output_pattern=ready))
            nodes.append(NodeSpec(name, [resolve("pppbot_nav", name), *ros_args(level, extra, params_file=nav2_params)],
                                  after=(localizer,), required=True, pppbot_node=True, ready=check))
        notes.append("navigating: send goals with RViz's 2D Goal Pose, ./pppbot nav goto X Y YAW, "
                     "or the navigate_to_pose action")
    simulator_params: dict[str, Any] = {
        "world": world_file, "robot_description": urdf_file, "real_time_factor": values["real_time_factor"],
        "x": values["x"], "y": values["y"], "z": values["z"], "yaw": values["yaw"],
        "seed": values["seed"], "wheel_slip": values["wheel_slip"], "viewer": not values["headless"]}
    if lockstep:
        simulator_params.update(lockstep=True, lockstep_participants=[*participants, *extra_participants])
    nodes.insert(0, NodeSpec("simulator", [resolve("pppbot_sim", "simulator"),
                                           *ros_args(level, simulator_params, sim_time=False)],
                             ready=ReadyCheck("a first /clock",
                                              probes.first_message("/clock", "rosgraph_msgs/msg/Clock", False)),
                             required=True, pppbot_node=True))
    if values["use_rviz"]:
        if rviz is None:
            notes.append("rviz2 is not on PATH: no RViz (use_rviz:=false silences this); "
                         "with ROS 2 Jazzy installed, run rviz2 -d config/ppp_bot.rviz on the same ROS_DOMAIN_ID")
        else:
            nodes.append(NodeSpec("rviz2", [rviz, "-d", str(config / "ppp_bot.rviz"), *ros_args(level)],
                                  after=("robot_state_publisher",)))
    if values["use_teleop"]:
        if terminal:
            # Last, once the robot is up, so that its key help is what the terminal shows.
            nodes.append(NodeSpec("teleop_keyboard", [resolve("pppbot_control", "teleop_keyboard"),
                                                      *ros_args(level, sim_time=False)],
                                  after=tuple(n.name for n in nodes if n.required), terminal=True))
        else:
            notes.append("no terminal here for the keyboard teleop: run ./pppbot teleop in another terminal")
    return Plan(nodes, notes)
