"""``launch_sim``'s arguments and node plan: ppp_bot's ``launch_sim.launch.py`` as data.

The ROS side (readiness probes, running the plan) is ``pppbot_bringup.ros.launch_sim``.

Start order, each step waiting for real readiness (a first message, not a sleep):
simulator (first /clock) → robot_state_publisher (/robot_description) and
diff_drive_base_controller (first /odom) → twist_mux → mapping or localization
→ navigation (planner, controller, navigator) → RViz (when on PATH) → keyboard teleop.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

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
    Argument("slam_params_file", "", "the slam node's parameters; default config/mapper_params_online_async.yaml"),
    Argument("use_teleop", True, "keyboard teleop in this terminal (other nodes' output goes to log files)"),
    Argument("use_rviz", True, "start rviz2 with config/ppp_bot.rviz when rviz2 is on PATH"),
    Argument("headless", True, "no MuJoCo viewer window (false opens one; needs a display)"),
    Argument("real_time_factor", 1.0, "simulated seconds per wall second; 0 = as fast as possible"),
    Argument("x", 0.0, "spawn x (m)"),
    Argument("y", 0.0, "spawn y (m)"),
    Argument("z", 0.05, "spawn z of base_link (m); ppp_bot rests at 0.05"),
    Argument("yaw", 0.0, "spawn yaw (rad)"),
    Argument("seed", 0, "seed of the simulator's sensor noise and wheel slip"),
    Argument("wheel_slip", 0.0, "wheel slip as the encoders see it (0.02 = 2 %): odometry drifts like a real robot's"),
    Argument("log_level", "info", "log level of every node", choices=LOG_LEVELS),
    Argument("record", False, "record every topic (pppbot bag record -a, sim time) while the launch runs"),
    Argument("bag_path", "", "the bag directory for record:=true; default rosbag2_YYYY_MM_DD-HH_MM_SS here"),
]

#: (topic, type, latched) → a probe that a first message came
ProbeFactory = Callable[[str, str, bool], Callable[[], bool]]
Resolver = Callable[[str, str], str]


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


def plan(values: dict[str, Any], world_file: Path, urdf_file: Path, resolve: Resolver, probe: ProbeFactory,
         terminal: bool, rviz: str | None) -> Plan:
    """The nodes to start, in ppp_bot's order, and notes for the user.

    Raises:
        ArgumentError: ``localization:=true`` without a map file, or a bag path that exists.
    """
    level = values["log_level"]
    config = config_directory()
    notes: list[str] = []
    nodes = [
        NodeSpec("simulator", [resolve("pppbot_sim", "simulator"), *ros_args(level, {
            "world": world_file, "robot_description": urdf_file, "real_time_factor": values["real_time_factor"],
            "x": values["x"], "y": values["y"], "z": values["z"], "yaw": values["yaw"],
            "seed": values["seed"], "wheel_slip": values["wheel_slip"],
            "viewer": not values["headless"]}, sim_time=False)],
            ready=ReadyCheck("a first /clock", probe("/clock", "rosgraph_msgs/msg/Clock", False)), required=True),
        NodeSpec("robot_state_publisher", [resolve("pppbot_description", "robot_state_publisher"),
                                           *ros_args(level, {"robot_description": urdf_file})],
                 after=("simulator",), required=True,
                 ready=ReadyCheck("/robot_description", probe("/robot_description", "std_msgs/msg/String", True))),
        NodeSpec("diff_drive_base_controller", [resolve("pppbot_control", "diff_drive_controller"),
                                                *ros_args(level, params_file=config / "my_controllers.yaml")],
                 after=("simulator",), required=True,
                 ready=ReadyCheck("a first /odom", probe("/odom", "nav_msgs/msg/Odometry", False))),
        NodeSpec("twist_mux", [resolve("pppbot_control", "twist_mux"), *ros_args(
            level, params_file=config / "twist_mux.yaml",
            remaps={"cmd_vel_out": "/diff_drive_base_controller/cmd_vel_unstamped"})],
            after=("diff_drive_base_controller",), required=True,
            ready=ReadyCheck("its inputs", output_pattern=r"inputs: ")),
    ]
    if values["record"]:
        bag = Path(values["bag_path"] or time.strftime("rosbag2_%Y_%m_%d-%H_%M_%S"))
        if bag.exists():
            raise ArgumentError(f"bag_path: '{bag}' exists already; a bag is never overwritten")
        # Right after the simulator, so the rest of the bringup (latched /robot_description,
        # /tf_static) is in the bag; stopping the launch finishes the bag.
        nodes.insert(1, NodeSpec("bag_record", [resolve("pppbot_bringup", "pppbot"), "bag", "record", "-a",
                                                "--use-sim-time", "-o", str(bag)],
                                 after=("simulator",), ready=ReadyCheck("recording", output_pattern=r"recording to ")))
        notes.append(f"recording every topic to {bag} (ends when the launch ends)")
    if values["localization"]:
        map_file = Path(values["map"]) if values["map"] else maps_directory() / f"{world_file.stem}.yaml"
        if not map_file.is_file():
            raise ArgumentError(f"localization:=true needs a map; {map_file} does not exist "
                                f"(save one while mapping, or give map:=path/to/map.yaml)")
        nav2_params = config / "nav2_params.yaml"
        nodes.append(NodeSpec("map_server", [resolve("pppbot_nav", "map_server"), *ros_args(
            level, {"yaml_filename": map_file.resolve()}, params_file=nav2_params)],
            after=("simulator",), required=True,
            ready=ReadyCheck("/map", probe("/map", "nav_msgs/msg/OccupancyGrid", True))))
        # AMCL starts where the robot was spawned (the shipped maps' frame is the world's, the
        # spawn pose of a map made with the default spawn); RViz's 2D Pose Estimate moves it.
        nodes.append(NodeSpec("amcl", [resolve("pppbot_nav", "amcl"), *ros_args(level, {
            "set_initial_pose": True, "initial_pose.x": values["x"], "initial_pose.y": values["y"],
            "initial_pose.yaw": values["yaw"]}, params_file=nav2_params)],
            after=("map_server", "diff_drive_base_controller"), required=True,
            ready=ReadyCheck("an initial pose", output_pattern=r"initial pose \(")))
        notes.append(f"localizing on {map_file}")
    elif values["use_slam"]:
        slam_params = Path(values["slam_params_file"] or config / "mapper_params_online_async.yaml")
        if not slam_params.is_file():
            raise ArgumentError(f"slam_params_file: {slam_params} does not exist")
        nodes.append(NodeSpec("slam_toolbox", [resolve("pppbot_slam", "slam"), *ros_args(
            level, params_file=slam_params)],
            after=("diff_drive_base_controller",), required=True,
            # Ready once it has mapped its first scan: the map frame is where the robot was
            # then, so nothing should drive it before (eval relies on map = spawn pose).
            ready=ReadyCheck("a first /map", probe("/map", "nav_msgs/msg/OccupancyGrid", True))))
    localizer = "amcl" if values["localization"] else "slam_toolbox" if values["use_slam"] else None
    if values["navigation"] == "true" or (values["navigation"] == "auto" and values["localization"]):
        if localizer is None:
            raise ArgumentError("navigation:=true needs a map frame: localization:=true or use_slam:=true")
        nav2_params = config / "nav2_params.yaml"
        for name, ready in (("planner_server", r"planner 'GridBased' ready"),
                            ("controller_server", r"controller 'FollowPath'"),
                            ("navigator", r"navigator ready")):
            nodes.append(NodeSpec(name, [resolve("pppbot_nav", name), *ros_args(level, params_file=nav2_params)],
                                  after=(localizer,), required=True, ready=ReadyCheck(name, output_pattern=ready)))
        notes.append("navigating: send goals with RViz's 2D Goal Pose, ./pppbot nav goto X Y YAW, "
                     "or the navigate_to_pose action")
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
