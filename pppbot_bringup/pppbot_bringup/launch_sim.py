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

import enum
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import yaml
from pppbot_viz.viewer import ViewerKind

from pppbot_bringup.filter_masks import with_filters
from pppbot_bringup.node_specs import (
    NAVIGATION_ENDPOINTS,
    Beside,
    Probes,
    Resolver,
    VizPlan,
    joystick_nodes,
    ros_args,
    simulator_spec,
    twist_mux_inputs,
    viz_nodes,
)
from pppbot_bringup.parameter_files import (
    NOT_IN_PPP_BOTS_BRINGUP,
    PARAMETER_FILES,
    check_slam_localization,
    map_free_navigation_problem,
    missing_sections_note,
    parameter_file,
    sections_missing,
)
from pppbot_bringup.paths import config_directory, maps_directory
from pppbot_bringup.robot import PPP_BOT, RobotFacts, adapt_parameters
from pppbot_bringup.supervisor import NodeSpec, ReadyCheck
from pppbot_common.errors import MapFileError
from pppbot_common.launch_args import Argument, ArgumentError, parse_assignments
from pppbot_common.maps import check_map_file
from pppbot_nav.lifecycle import LOCALIZATION_NODES, NAVIGATION_NODES, command_remaps, navigation_nodes

LOG_LEVELS = ("debug", "info", "warn", "error", "fatal")
#: the simulator's largest ``wheel_slip`` (pppbot_sim.wheel_slip.MAX_SLIP_STDDEV)
MAX_WHEEL_SLIP = 0.2
#: With ``respawn:=true``, how often the recorder is started again (other nodes: without limit).
RECORDER_RESPAWNS = 3
#: ``pppbot bag record``'s node name (rosbag2's).
RECORDER_NODE = "rosbag2_recorder"
#: With ``respawn:=true``, sim seconds between the slam node's autosaves of its pose graph.
AUTOSAVE_PERIOD_S = 5.0


class NavigationMode(enum.Enum):
    """``navigation:=``: whether the navigation nodes start."""

    AUTO = "auto"  # with localization:=true
    TRUE = "true"
    FALSE = "false"

    def enabled(self, localization: bool) -> bool:
        return self is NavigationMode.TRUE or (self is NavigationMode.AUTO and localization)


def _arg(default: Any, description: str, choices: tuple[str, ...] = ()) -> Any:
    """A launch argument: its default, ``--show-args`` text and allowed values."""
    return field(default=default, metadata={"description": description, "choices": choices})


@dataclass(frozen=True)
class LaunchArgs:
    """``launch_sim``'s arguments (``name:=value``), typed; :data:`ARGUMENTS` is made from them."""

    world: str = _arg("cones", "world name (worlds/<name>.sdf) or path to an SDF or MJCF file (ppp_bot's name "
                               "for it, world_name:=, works too)")
    localization: bool = _arg(False, "localize on a saved map (map_server + AMCL) instead of mapping (SLAM)")
    map: str = _arg("", "map YAML for localization; default maps/<world>.yaml")
    use_slam: bool = _arg(True, "with localization:=false, map with the SLAM node (false: drive on odometry only)")
    navigation: NavigationMode = _arg(NavigationMode.AUTO, "Nav2's navigation servers: planner, controller, "
                                                           "behaviours, bt_navigator, waypoints (auto: with "
                                                           "localization:=true; with neither localization nor "
                                                           "SLAM, in odom if params_file says so)",
                                      tuple(m.value for m in NavigationMode))
    use_velocity_smoother: bool = _arg(True, "the velocity_smoother between the controller and twist_mux, as in "
                                             "Nav2's bringup (false: leave it out)")
    use_collision_monitor: bool = _arg(True, "the collision_monitor between the velocity_smoother and twist_mux: "
                                             "stops the robot short of what the lidar sees in its way (false: "
                                             "leave it out)")
    use_composition: bool = _arg(True, "robot_state_publisher and twist_mux in the simulator's process, map_server "
                                       "and amcl in one (localization), the navigation nodes in another "
                                       "(navigation), as Nav2's bringup composes its servers (false: a process "
                                       "each)")
    slam_params_file: str = _arg("", "the slam node's parameters; default config/mapper_params_online_async.yaml")
    params_file: str = _arg("", "Nav2's parameters for localization and navigation (Nav2's bringup argument); "
                                "default config/nav2_params.yaml")
    keepout_mask: str = _arg("", "a keepout zones mask (a Nav2 map YAML): served with its filter info, and the "
                                 "costmaps' KeepoutFilter keeps the robot out (Nav2's use_keepout_zones)")
    speed_mask: str = _arg("", "a speed zones mask (a Nav2 map YAML; limit = 100 - value %): served with its "
                               "filter info, and the global costmap's SpeedFilter limits the controller "
                               "(Nav2's use_speed_zones)")
    twist_mux_params: str = _arg("", "twist_mux's parameters; default config/twist_mux.yaml")
    controllers_file: str = _arg("", "the ros2_control controllers the robot's gz_ros2_control plugin loads (its "
                                     "xacro's controllers_file argument); default config/my_controllers.yaml")
    description: str = _arg("", "the robot: a .urdf or .xacro file, by path or package://pkg/path (default: "
                                "ppp_bot's robot.urdf.xacro)")
    xacro_args: str = _arg("", "the description's xacro arguments, 'name:=value name:=value' (e.g. "
                               "'use_ros2_control:=false' drives ppp_bot with Gazebo's DiffDrive plugin)")
    use_teleop: bool = _arg(True, "keyboard teleop in this terminal (other nodes' output goes to log files)")
    use_joystick: bool = _arg(False, "joystick teleop: joy_node + teleop_twist_joy into twist_mux's teleop input "
                                     "(cmd_vel_teleop), as ppp_bot's")
    joy_params: str = _arg("", "joy_node's and teleop_node's parameters; default config/joystick.yaml")
    use_rviz: bool = _arg(True, "start rviz2 with config/ppp_bot.rviz when rviz2 is on PATH")
    use_viz: bool = _arg(True, "the live view (rerun): map, costmaps, scan, robot, plans, particles; "
                               "its web page sets goals and initial poses")
    viz_viewer: ViewerKind = _arg(ViewerKind.AUTO, "the live view's viewer: native (a window), web (a page on "
                                                   "127.0.0.1:viz_port), auto (native with a display, else web); "
                                                   "the page is served in every case",
                                  tuple(k.value for k in ViewerKind))
    viz_port: int = _arg(9090, "the live view's web page on 127.0.0.1 (0: a free port)")
    headless: bool = _arg(True, "no MuJoCo viewer window (false opens one; needs a display)")
    real_time_factor: float = _arg(1.0, "simulated seconds per wall second; 0 = as fast as possible")
    lockstep: bool = _arg(False, "time advances only when the nodes on the data path have done their work "
                                 "(the same run on any machine; with real_time_factor:=0 as fast as they allow)")
    x: float = _arg(0.0, "spawn x (m)")
    y: float = _arg(0.0, "spawn y (m)")
    z: float = _arg(math.nan, "spawn z of the robot's root link (m); default (nan): resting on whatever lies "
                              "beneath x, y (ppp_bot on the ground: 0.05)")
    yaw: float = _arg(0.0, "spawn yaw (rad)")
    seed: int = _arg(0, "seed of the simulator's sensor noise and wheel slip")
    cameras: bool = _arg(True, "render the robot's camera tags while someone subscribes (false: no camera topics)")
    wheel_slip: float = _arg(0.0, "wheel slip as the encoders see it (0.02 = 2 %): odometry drifts like a "
                                  "real robot's")
    log_level: str = _arg("info", "log level of every node", LOG_LEVELS)
    record: bool = _arg(False, "record every topic (pppbot bag record -a, sim time) while the launch runs")
    bag_path: str = _arg("", "the bag directory for record:=true; default rosbag2_YYYY_MM_DD-HH_MM_SS here")
    sigterm_timeout: float = _arg(5.0, "on shutdown, seconds from SIGINT to SIGTERM for a node still running "
                                       "(ros2 launch's sigterm_timeout)")
    sigkill_timeout: float = _arg(5.0, "seconds from SIGTERM to SIGKILL (ros2 launch's sigkill_timeout)")
    respawn: bool = _arg(False, "start a node process that dies again, after respawn_delay (ros2 launch's "
                                "respawn); the simulator's death still ends the launch; needs lockstep:=false")
    respawn_delay: float = _arg(1.0, "seconds before a dead node is started again (respawn:=true)")

    @classmethod
    def parse(cls, argv: Sequence[str]) -> LaunchArgs:
        """The arguments of ``name:=value`` items (defaults for the rest).

        Raises:
            ArgumentError: a malformed item, an unknown or repeated name, or a bad value.
        """
        return cls.from_values(parse_assignments(with_aliases(argv), ARGUMENTS))

    @classmethod
    def from_values(cls, values: Mapping[str, Any]) -> LaunchArgs:
        """From plain values (strings for the enums), as :func:`parse_assignments` gives them."""
        typed = dict(values)
        if isinstance(typed.get("navigation"), str):
            typed["navigation"] = NavigationMode(typed["navigation"])
        if isinstance(typed.get("viz_viewer"), str):
            typed["viz_viewer"] = ViewerKind(typed["viz_viewer"])
        return cls(**typed)

    def validate(self, environ: Mapping[str, str]) -> None:
        """Check every value before anything starts (files and the world are checked where they are
        read); ``environ``: for a display with ``headless:=false`` or ``viz_viewer:=native``.

        Raises:
            ArgumentError: the first bad value, named with what is allowed.
        """
        from pppbot_viz.viewer import has_display
        ranges = {"real_time_factor": (0.0, 1000.0), "x": (-1e6, 1e6), "y": (-1e6, 1e6), "yaw": (-1e3, 1e3),
                  "wheel_slip": (0.0, MAX_WHEEL_SLIP)}
        for name, (low, high) in ranges.items():
            value = float(getattr(self, name))
            if not low <= value <= high:
                raise ArgumentError(f"{name}:={value:g}: must be a number from {low:g} to {high:g}")
        if not (math.isnan(self.z) or -1e6 <= self.z <= 1e6):
            raise ArgumentError(f"z:={self.z:g}: must be a number (or nan: resting on the ground)")
        if not 0 <= self.seed < 2**63:
            raise ArgumentError(f"seed:={self.seed}: must be a whole number from 0")
        if not 0 <= self.viz_port <= 65535:
            raise ArgumentError(f"viz_port:={self.viz_port}: must be a port number from 0 (a free one) to 65535")
        self.stop_timeouts()
        wants_window = not self.headless, self.use_viz and self.viz_viewer is ViewerKind.NATIVE
        for name, wants in zip(("headless:=false", "viz_viewer:=native"), wants_window, strict=True):
            if wants and not has_display(environ):
                raise ArgumentError(f"{name} opens a window, and there is no display here (DISPLAY and WAYLAND_DISPLAY "
                                    "are not set): leave it out, or run where a desktop is")
        if self.respawn and self.lockstep:
            raise ArgumentError("respawn:=true needs lockstep:=false: a node started again cannot rejoin the "
                                "lockstep it left (time would wait for it forever)")
        if self.respawn and not self.use_composition:
            raise ArgumentError("respawn:=true needs use_composition:=true: a lifecycle node started again on its "
                                "own would wait for its manager to configure it (the composed processes bring "
                                "their manager with them)")
        if not 0.0 <= self.respawn_delay <= 3600.0:
            raise ArgumentError(f"respawn_delay:={self.respawn_delay:g}: must be a number of seconds from 0 to 3600")
        if self.record and self.bag_path and Path(self.bag_path).exists():
            raise ArgumentError(f"bag_path:={self.bag_path}: exists already; a bag is never overwritten")
        for name in PARAMETER_FILES:  # every file given, whether this launch reads it or not
            if getattr(self, name):
                parameter_file(getattr(self, name), Path(), name)

    def stop_timeouts(self) -> tuple[float, float]:
        """(seconds after SIGINT, seconds after SIGTERM) before the launch escalates.

        Raises:
            ArgumentError: a timeout that is not a positive finite number.
        """
        timeouts = (float(self.sigterm_timeout), float(self.sigkill_timeout))
        for name, value in zip(("sigterm_timeout", "sigkill_timeout"), timeouts, strict=True):
            if not 0.0 < value < float("inf"):
                raise ArgumentError(f"{name}:={value:g}: must be a positive number of seconds")
        return timeouts


ARGUMENTS = [Argument(f.name, f.default.value if isinstance(f.default, enum.Enum) else f.default,
                      f.metadata["description"], f.metadata["choices"]) for f in fields(LaunchArgs)]

@dataclass(frozen=True)
class Plan:
    nodes: list[NodeSpec]
    #: what the user should act on (printed as warnings before the start)
    notes: list[str]
    #: what the user should know once it is up (the live view's address)
    info: list[str] = field(default_factory=list)
    #: files to write before starting (parameter files adapted to the robot), path → text
    files: dict[Path, str] = field(default_factory=dict)
    #: what the launch does, for the user's information (printed before the start)
    start_info: list[str] = field(default_factory=list)
    #: information worth reading once, not at every start (an optional tool that is absent), key → text
    once: dict[str, str] = field(default_factory=dict)


def controllers_file(given: str = "") -> Path:
    """The controller parameters the robot's gz_ros2_control plugin points at (the simulator runs
    those controllers in its process): ``given`` (``controllers_file:=``), else ppp_bot's.

    Raises:
        ArgumentError: a given file that is missing or not a ROS 2 parameter file.
    """
    return parameter_file(given, config_directory() / "my_controllers.yaml", "controllers_file")


#: ppp_bot's launch argument names that name one of launch_sim's (its launch_sim.launch.py's).
ALIASES = {"world_name": "world"}


def with_aliases(argv: Sequence[str]) -> list[str]:
    """``argv`` with ppp_bot's argument names (:data:`ALIASES`) as launch_sim's.

    Raises:
        ArgumentError: an alias given together with the argument it names.
    """
    names = [item.partition(":=")[0] for item in argv]
    out = []
    for item, name in zip(argv, names, strict=True):
        target = ALIASES.get(name)
        if target is not None and target in names:
            raise ArgumentError(f"{name}:= and {target}:= are the same argument (ppp_bot's name and "
                                f"launch_sim's): give one")
        out.append(item if target is None else f"{target}{item[len(name):]}")
    return out


def adapted_file(path: Path, robot: RobotFacts, directory: Path, files: dict[Path, str], info: list[str]) -> Path:
    """``path``, or a copy in ``directory`` (added to ``files``) with its frames and topics pointed
    at ``robot``'s (:func:`pppbot_bringup.robot.adapt_parameters`); ``info`` says so.

    Raises:
        ArgumentError: the file is not YAML.
    """
    target = directory / path.name
    if target in files:
        return target
    try:
        document = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise ArgumentError(f"{path}: cannot read the parameter file: {exc}") from exc
    changes = adapt_parameters(document, robot)
    if not changes:
        return path
    files[target] = yaml.safe_dump(document, sort_keys=False)
    info.append(f"{path.name} follows robot '{robot.name}': {'; '.join(changes)} (in {target})")
    return target


def costmap_filters(masks: dict[str, str], params: Path, directory: Path, files: dict[Path, str], level: str,
                    resolve: Resolver, info: list[str]) -> tuple[Path, NodeSpec]:
    """The navigation parameters with the masks' filters (:mod:`pppbot_bringup.filter_masks`, a copy in
    ``directory`` added to ``files``) and the ``costmap_filters`` process serving the masks.

    Raises:
        ArgumentError: a mask that is not a readable map YAML, or costmaps reading two info topics.
    """
    for kind, mask in masks.items():
        try:
            check_map_file(Path(mask))
        except MapFileError as exc:
            raise ArgumentError(f"{kind}_mask:={exc}") from exc
    text = files.get(params) or params.read_text()
    try:
        setup = with_filters(yaml.safe_load(text) or {}, list(masks))
    except ValueError as exc:
        raise ArgumentError(f"params_file:={params}: {exc}") from exc
    target = directory / f"{params.stem}_filters.yaml"
    files[target] = yaml.safe_dump(setup.document, sort_keys=False)
    scoped: dict[str, Any] = {}
    for kind, mask in masks.items():
        scoped[f"{kind}_filter_mask_server:yaml_filename"] = Path(mask).resolve()
        scoped[f"{kind}_costmap_filter_info_server:filter_info_topic"] = setup.info_topics[kind]
    info.append("costmap filters: " + ", ".join(f"{kind} zones from {mask}" for kind, mask in masks.items())
                + (f" ({'; '.join(setup.changes)})" if setup.changes else ""))
    flags = [f"--{kind}" for kind in masks]
    return target, NodeSpec("costmap_filters", [resolve("pppbot_nav", "costmap_filters"), *flags,
                                                *ros_args(level, scoped, params_file=target)],
                            required=True, pppbot_node=True)


def plan(args: LaunchArgs, world_file: Path, urdf_file: Path, resolve: Resolver, probes: Probes,  # noqa: C901, PLR0912, PLR0915
         terminal: bool, rviz: str | None, extra_participants: Sequence[str] = (),
         viz: VizPlan | None = None, view_recording: Path | None = None, robot: RobotFacts = PPP_BOT) -> Plan:
    """The nodes to start, in ppp_bot's order, and notes for the user. ``extra_participants``:
    lockstep participants outside the launch that time must wait for from its start (the
    evaluation's own node). ``viz``: the live view's ports (with ``use_viz:=true``);
    ``view_recording``: an ``.rrd`` file the view's stream is written to (the evaluation's);
    ``robot``: what the description at ``urdf_file`` declares (:func:`pppbot_bringup.robot.robot_facts`).

    Raises:
        ArgumentError: ``localization:=true`` without a map file, or a bag path that exists.
    """
    level = args.log_level
    lockstep = args.lockstep
    config = config_directory()
    notes: list[str] = list(robot.notes)
    start_info: list[str] = list(robot.info)
    files: dict[Path, str] = {}
    participants: list[str] = []
    missing: list[str] = []  # nodes the Nav2 params file has no section for
    left_out: list[str] = []  # of those, the ones left out

    def participant(name: str, description: str, check: ReadyCheck) -> tuple[dict[str, Any], ReadyCheck]:
        """A lockstep participant's parameters and readiness: joined, in lockstep; else ``check``."""
        if not lockstep:
            return {}, check
        participants.append(name)
        return ({"lockstep": True, "lockstep_name": name},
                ReadyCheck(f"{description} (joined lockstep)", probes.joined(name), timeout_s=check.timeout_s))

    mux_config = parameter_file(args.twist_mux_params, config / "twist_mux.yaml", "twist_mux_params")
    rsp_check = ReadyCheck("/robot_description", probes.first_message("/robot_description", "std_msgs/msg/String",
                                                                      True))
    mux_check = ReadyCheck("twist_mux's inputs", probes.endpoints(
        "twist_mux", publishes=(robot.command_topic,), subscribes=twist_mux_inputs(mux_config)))
    composed = args.use_composition
    # What the rest starts after: the robot's description is up (in the simulator's process, composed).
    base = "simulator" if composed else "robot_state_publisher"
    nodes: list[NodeSpec] = []
    if not composed:
        # Participants too: twist_mux passes commands on; the wheel transforms are on /tf, which the
        # data path counts.
        mux_params, mux_ready = participant("twist_mux", "its inputs", mux_check)
        rsp_params, rsp_ready = participant("robot_state_publisher", "/robot_description", rsp_check)
        nodes += [
            NodeSpec("robot_state_publisher", [resolve("pppbot_description", "robot_state_publisher"),
                                               *ros_args(level, {"robot_description": urdf_file, **rsp_params})],
                     after=("simulator",), required=True, pppbot_node=True, ready=rsp_ready),
            NodeSpec("twist_mux", [resolve("pppbot_control", "twist_mux"), *ros_args(
                level, mux_params, params_file=mux_config, remaps={"cmd_vel_out": robot.command_topic})],
                after=("simulator",), required=True, pppbot_node=True, ready=mux_ready),
        ]
    if args.record:
        bag = Path(args.bag_path or time.strftime("rosbag2_%Y_%m_%d-%H_%M_%S"))
        if bag.exists():
            raise ArgumentError(f"bag_path: '{bag}' exists already; a bag is never overwritten")
        # Right after the simulator, so the rest of the bringup (latched /robot_description,
        # /tf_static) is in the bag; stopping the launch finishes the bag. Respawned, the
        # recorder finishes what it left and records on into the same bag.
        nodes.insert(0, NodeSpec("bag_record", [resolve("pppbot_bringup", "pppbot"), "bag", "record", "-a",
                                                "--use-sim-time", "-o", str(bag),
                                                *(["--resume"] if args.respawn else [])],
                                 after=("simulator",), ready=ReadyCheck("recording /clock", probes.endpoints(
                                     RECORDER_NODE, subscribes=("/clock",)))))
        start_info.append(f"recording every topic to {bag} (ends when the launch ends)")
    def manager_spec(name: str, managed: Sequence[str], params_file: Path, ready: ReadyCheck) -> NodeSpec:
        """A lifecycle manager's own process (``use_composition:=false``), after the nodes it manages."""
        return NodeSpec(name, [resolve("pppbot_nav", "lifecycle_manager"), *ros_args(
            level, {"node_names": list(managed), "autostart": True}, params_file=params_file,
            remaps={"__node": name})],
            after=tuple(managed), required=True, pppbot_node=True, ready=ready)

    if args.localization:
        map_file = Path(args.map) if args.map else maps_directory() / f"{world_file.stem}.yaml"
        if not map_file.is_file():
            raise ArgumentError(f"localization:=true needs a map; {map_file} does not exist "
                                f"(save one while mapping, or give map:=path/to/map.yaml)")
        try:
            check_map_file(map_file)  # before anything starts, not when map_server fails on it
        except MapFileError as exc:
            raise ArgumentError(f"map:={exc}") from exc
        given = parameter_file(args.params_file, config / "nav2_params.yaml", "params_file")
        nav2_params = adapted_file(given, robot, urdf_file.parent, files, start_info)
        missing += sections_missing(given, LOCALIZATION_NODES)
        # AMCL starts where the robot was spawned (the shipped maps' frame is the world's, the
        # spawn pose of a map made with the default spawn); RViz's 2D Pose Estimate moves it.
        # The launch's seed seeds AMCL's particles too: one seed makes the whole run repeatable.
        server_params = {"yaml_filename": map_file.resolve()}
        amcl_params = {"set_initial_pose": True, "initial_pose.x": args.x, "initial_pose.y": args.y,
                       "initial_pose.yaw": args.yaw, "seed": args.seed}
        # Localized: a first /amcl_pose (the first scan after the initial pose forces an update),
        # what nav2_simple_commander's BasicNavigator waits for too.
        amcl_ready = ReadyCheck("a first /amcl_pose", probes.first_message(
            "/amcl_pose", "geometry_msgs/msg/PoseWithCovarianceStamped", True))
        if args.use_composition:
            # One process, as Nav2 composes its servers; each parameter goes to its own node.
            extra, localized = participant("localization", "an initial pose", amcl_ready)
            scoped = {**{f"map_server:{k}": v for k, v in server_params.items()},
                      **{f"amcl:{k}": v for k, v in amcl_params.items()}, **extra}
            nodes.append(NodeSpec("localization", [resolve("pppbot_nav", "localization"), *ros_args(
                level, scoped, params_file=nav2_params)],
                after=(base,), required=True, pppbot_node=True, ready=localized))
        else:
            # Each its own process, unconfigured until lifecycle_manager_localization (its own
            # process too, as Nav2's bringup starts it) brings them up; localized is its readiness.
            nodes.append(NodeSpec("map_server", [resolve("pppbot_nav", "map_server"), *ros_args(
                level, server_params, params_file=nav2_params)],
                after=("simulator",), required=True, pppbot_node=True,
                ready=ReadyCheck("its /map publisher", probes.endpoints("map_server", publishes=("/map",)))))
            extra, localized = participant("amcl", "an initial pose", amcl_ready)
            nodes.append(NodeSpec("amcl", [resolve("pppbot_nav", "amcl"), *ros_args(
                level, {**amcl_params, **extra}, params_file=nav2_params)],
                after=(base,), required=True, pppbot_node=True,
                ready=ReadyCheck("its /amcl_pose publisher", probes.endpoints("amcl", publishes=("/amcl_pose",)))))
            nodes.append(manager_spec("lifecycle_manager_localization", LOCALIZATION_NODES, nav2_params, localized))
        start_info.append(f"localizing on {map_file}")
    elif args.use_slam:
        slam_params = parameter_file(args.slam_params_file, config / "mapper_params_online_async.yaml",
                                     "slam_params_file")
        check_slam_localization(slam_params)
        slam_params = adapted_file(slam_params, robot, urdf_file.parent, files, start_info)
        # Ready once it has mapped its first scan: the map frame is where the robot was then, so
        # nothing should drive it before (eval relies on map = spawn pose). In lockstep the first
        # scan is mapped before time moves past it.
        slam_params_lockstep, slam_ready = participant(
            "slam_toolbox", "a first /map",
            ReadyCheck("a first /map", probes.first_message("/map", "nav_msgs/msg/OccupancyGrid", True)))
        if args.respawn:  # a restarted slam maps on from its last autosave
            autosave = urdf_file.parent / "slam_autosave"  # the run's log directory: kept with its logs
            slam_params_lockstep = {**slam_params_lockstep, "autosave_name": str(autosave),
                                    "autosave_period": AUTOSAVE_PERIOD_S}
            start_info.append(f"respawn: slam saves its pose graph every {AUTOSAVE_PERIOD_S:g} s to "
                              f"{autosave}.posegraph and maps on from it when it is started again")
        nodes.append(NodeSpec("slam_toolbox", [resolve("pppbot_slam", "slam"), *ros_args(
            level, slam_params_lockstep, params_file=slam_params)],
            after=(base,), required=True, pppbot_node=True, ready=slam_ready))
    localizer = (("localization" if args.use_composition else "lifecycle_manager_localization") if args.localization
                 else "slam_toolbox" if args.use_slam else None)
    if (args.keepout_mask or args.speed_mask) and not args.navigation.enabled(args.localization):
        raise ArgumentError("keepout_mask:= and speed_mask:= filter the navigation's costmaps: they need navigation "
                            "(localization:=true, or navigation:=true)")
    if args.navigation.enabled(args.localization):
        given = parameter_file(args.params_file, config / "nav2_params.yaml", "params_file")
        if localizer is None:  # Nav2 without a map: it navigates in odom, its global costmap rolling
            problem = map_free_navigation_problem(given)
            if problem is not None:
                raise ArgumentError(f"navigation:=true without localization or SLAM navigates in odom, but "
                                    f"params_file:={given} does not: {problem}")
        nav2_params = adapted_file(given, robot, urdf_file.parent, files, start_info)
        masks = {kind: mask for kind, mask in (("keepout", args.keepout_mask), ("speed", args.speed_mask)) if mask}
        if masks:
            nav2_params, filters_spec = costmap_filters(masks, nav2_params, urdf_file.parent, files, level,
                                                          resolve, start_info)
            nodes.append(replace(filters_spec, after=(localizer or base,)))
        missing += sections_missing(given, NAVIGATION_NODES)
        left_out = [name for name in missing if name in NOT_IN_PPP_BOTS_BRINGUP]
        without = tuple(name for name, use in (("velocity_smoother", args.use_velocity_smoother),
                                               ("collision_monitor", args.use_collision_monitor))
                        if not use or name in left_out)
        managed = navigation_nodes(without)
        remaps = command_remaps(without)
        # Up once lifecycle_manager_navigation has them all active (the last one last), as
        # BasicNavigator.waitUntilNav2Active() sees bt_navigator; in lockstep, once joined as well.
        active = ReadyCheck(f"{managed[-1]} active", probes.lifecycle_active(managed[-1]))
        if args.use_composition:
            extra, check = participant("navigation", "navigation", active)
            lockstep_joined = check.probe
            check = ReadyCheck(check.description if lockstep else active.description,
                               lambda: active.probe() and lockstep_joined())
            leave_out = [arg for name in without for arg in ("--without", name)]
            nodes.append(NodeSpec("navigation", [resolve("pppbot_nav", "navigation"), *leave_out, *ros_args(
                level, extra, params_file=nav2_params, remaps=remaps)], after=(localizer or base,), required=True,
                pppbot_node=True, ready=check))
        else:
            joins = []
            for name in managed:
                endpoints = NAVIGATION_ENDPOINTS[name]
                serving = ReadyCheck(endpoints.description, probes.endpoints(
                    name, action_servers=endpoints.action_servers, subscribes=endpoints.subscribes))
                extra, joined = participant(name, name, serving)
                joins.append(joined.probe)
                own = {old: new for old, new in remaps.items() if old.startswith(f"{name}:")}
                nodes.append(NodeSpec(name, [resolve("pppbot_nav", name), *ros_args(
                    level, extra, params_file=nav2_params, remaps=own)], after=(localizer or base,), required=True,
                    pppbot_node=True, ready=serving))
            nodes.append(manager_spec("lifecycle_manager_navigation", managed, nav2_params, ReadyCheck(
                active.description + (" (joined lockstep)" if lockstep else ""),
                lambda: active.probe() and all(j() for j in joins))))
        start_info.append("navigating: send goals with RViz's 2D Goal Pose, ./pppbot nav goto X Y YAW, "
                     "or the navigate_to_pose action")
    if missing:
        start_info.append(missing_sections_note(given, missing, left_out))
    simulator_params: dict[str, Any] = {
        "world": world_file, "robot_description": urdf_file, "real_time_factor": args.real_time_factor,
        "x": args.x, "y": args.y, "z": args.z, "yaw": args.yaw,
        "seed": args.seed, "wheel_slip": args.wheel_slip, "viewer": not args.headless, "cameras": args.cameras}
    if robot.simulator_cmd_vel_topic:
        simulator_params["cmd_vel_topic"] = robot.simulator_cmd_vel_topic
    if lockstep:
        simulator_params.update(lockstep=True, lockstep_participants=[*participants, *extra_participants])
    beside = Beside(urdf_file, mux_config, robot.command_topic, rsp_check, mux_check) if composed else None
    nodes.insert(0, simulator_spec(resolve, probes, level, simulator_params, beside))
    once: dict[str, str] = {}
    if args.use_rviz:
        if rviz is None:
            once["no_rviz2"] = ("rviz2 is not on PATH, so no RViz: the live view shows the robot instead. With ROS 2 "
                                "Jazzy installed, run rviz2 -d config/ppp_bot.rviz on the same ROS_DOMAIN_ID "
                                "(said once; use_rviz:=false says it is not wanted)")
        else:
            nodes.append(NodeSpec("rviz2", [rviz, "-d", str(config / "ppp_bot.rviz"), *ros_args(level)],
                                  after=(base,)))
    info: list[str] = []
    if viz is not None or view_recording is not None:
        nodes += viz_nodes(viz, view_recording, resolve, probes, level, after=(base,))
    if viz is not None:
        viewer = "a native viewer window and " if viz.native else ""
        moved = f"; port {args.viz_port} was taken" if args.viz_port and viz.page_port != args.viz_port else ""
        info.append(f"live view: {viewer}http://127.0.0.1:{viz.page_port}/ <- open it in a browser{moved} "
                    "(2D Goal Pose / 2D Pose Estimate: a button, then two clicks on the map)")
    if args.use_joystick:
        nodes += joystick_nodes(parameter_file(args.joy_params, config / "joystick.yaml", "joy_params"), resolve,
                                level, after="simulator" if composed else "twist_mux")
        info.append("joystick: hold the enable button (6) and move the left stick; turbo: button 7")
    if args.use_teleop:
        if terminal:
            # Last, once the robot is up, so that its key help is what the terminal shows.
            nodes.append(NodeSpec("teleop_keyboard", [resolve("pppbot_control", "teleop_keyboard"),
                                                      *ros_args(level, sim_time=False)],
                                  after=tuple(n.name for n in nodes if n.required), terminal=True))
        else:
            start_info.append("no terminal here for the keyboard teleop: run ./pppbot teleop in another terminal")
    if args.respawn:  # every node but the simulator (the world: its death ends the stack) and the terminal's
        # (the recorder a few times: one that cannot record on into its bag would fail again and again)
        nodes = [replace(n, respawn=True, respawn_delay_s=args.respawn_delay,
                         max_respawns=RECORDER_RESPAWNS if n.name == "bag_record" else -1)
                 if n.name != "simulator" and not n.terminal else n for n in nodes]
    return Plan(nodes, notes, info, files, start_info, once)
