"""launch_sim: arguments, --show-args, the node plan, and what is refused before anything starts (running
stacks: test_launch_sim_running.py)."""
from __future__ import annotations

import dataclasses
import math
import subprocess
from pathlib import Path

import pytest
import yaml
from pppbot_viz.errors import VizError

from pppbot_bringup.launch_sim import ARGUMENTS, LaunchArgs, NavigationMode, plan
from pppbot_common.launch_args import ArgumentError, describe
from pppbot_eval.config import map_free_params
from pppbot_nav.lifecycle import NAVIGATION_NODES

ROOT = Path(__file__).resolve().parents[2]
PPPBOT = str(ROOT / "pppbot")


def values(*argv: str) -> LaunchArgs:
    return LaunchArgs.parse(list(argv))


def test_defaults_are_ppp_bots():
    v = values()
    assert (v.world, v.localization, v.use_teleop, v.use_rviz, v.headless) == ("cones", False, True, True, True)
    assert (v.real_time_factor, v.log_level, v.navigation) == (1.0, "info", NavigationMode.AUTO)
    # z:= not given: the simulator puts the robot down on what lies beneath it
    assert math.isnan(v.z) and "-p simulator:z:=nan " in " ".join(fake_plan()[0].nodes[0].cmd) + " "


def test_the_arguments_are_the_dataclass_fields_with_their_defaults():
    assert [a.name for a in ARGUMENTS] == [f.name for f in dataclasses.fields(LaunchArgs)]
    navigation = next(a for a in ARGUMENTS if a.name == "navigation")
    assert (navigation.default, navigation.choices) == ("auto", ("auto", "true", "false"))
    assert values("navigation:=false", "x:=1.5").navigation is NavigationMode.FALSE
    assert values("x:=1.5").x == 1.5
    with pytest.raises(dataclasses.FrozenInstanceError):
        values().x = 2.0  # type: ignore[misc]  # the point: it is frozen


@pytest.mark.parametrize("argv, message", [
    (["wrld:=maze"], "unknown argument 'wrld'; known: world, localization, map"),
    (["world=maze"], "'world=maze' is not of the form name:=value"),
    (["localization:=maybe"], "localization:=maybe: must be true or false"),
    (["real_time_factor:=fast"], "real_time_factor:=fast: must be a number"),
    (["log_level:=loud"], "log_level:=loud: allowed values are debug, info, warn, error, fatal"),
    (["x:=1", "x:=2"], "argument 'x' given twice"),
])
def test_bad_arguments_are_named(argv, message):
    with pytest.raises(ArgumentError) as info:
        values(*argv)
    assert message in str(info.value)


def test_show_args_lists_every_argument_with_its_default():
    result = subprocess.run([PPPBOT, "launch_sim", "--show-args"], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0
    for argument in ARGUMENTS:
        assert f"    '{argument.name}':" in result.stdout
    assert "(default: 'cones')" in result.stdout and "Choices: debug, info, warn, error, fatal" in result.stdout
    assert describe(ARGUMENTS) in result.stdout


@pytest.mark.parametrize("argv, message", [
    (["world:=mars"], "unknown world 'mars'; known worlds: cones, empty, maze, maze_boxes, office, room, room_boxes"),
    (["wrld:=maze"], "unknown argument 'wrld'"),
    (["localization:=true", "map:=/nowhere/map.yaml"],
     "localization:=true needs a map; /nowhere/map.yaml does not exist"),
    (["sigkill_timeout:=-1"], "sigkill_timeout:=-1: must be a positive number of seconds"),
    (["world_name:=maze", "world:=room"], "world_name:= and world:= are the same argument"),
    (["world_name:=mars"], "unknown world 'mars'"),
    (["controllers_file:=/nowhere/controllers.yaml"], "controllers_file:=/nowhere/controllers.yaml: no such file"),
    (["twist_mux_params:=/nowhere/twist_mux.yaml"], "twist_mux_params:=/nowhere/twist_mux.yaml: no such file"),
])
def test_launch_refuses_bad_input_before_starting_anything(argv, message):
    result = subprocess.run([PPPBOT, "launch_sim", *argv], capture_output=True, text=True, timeout=60,
                            stdin=subprocess.DEVNULL)
    assert result.returncode == 2
    assert message in result.stderr
    assert "process started" not in result.stdout


def test_a_parameter_file_that_is_not_valid_yaml_is_refused_with_its_line(tmp_path):
    broken = tmp_path / "nav2_params.yaml"
    broken.write_text("amcl:\n  ros__parameters:\n    alpha1: [0.2, 0.2\n    alpha2: 0.2\n")
    for argument in ("params_file", "slam_params_file", "twist_mux_params", "controllers_file", "joy_params"):
        result = subprocess.run([PPPBOT, "launch_sim", f"{argument}:={broken}", "localization:=true",
                                 "world:=room"], capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL)
        assert result.returncode == 2, argument
        assert f"{argument}:={broken}: line " in result.stderr, result.stderr
        assert "Traceback" not in result.stderr and "process started" not in result.stdout


def test_ppp_bots_argument_names_and_files_are_taken(tmp_path):
    assert values("world_name:=room").world == "room"
    assert values("use_rviz:=False", "localization:=True").localization is True
    nav2 = tmp_path / "my_nav2_params.yaml"
    nav2.write_text((ROOT / "config" / "nav2_params.yaml").read_text())
    mux = tmp_path / "my_twist_mux.yaml"
    mux.write_text((ROOT / "config" / "twist_mux.yaml").read_text())
    nodes = {n.name: " ".join(n.cmd) for n in fake_plan("localization:=true", f"params_file:={nav2}",
                                                         f"twist_mux_params:={mux}")[0].nodes}
    assert f"--params-file {nav2}" in nodes["localization"] and f"--params-file {nav2}" in nodes["navigation"]
    assert f"--params-file {mux}" in nodes["simulator"]  # twist_mux runs in the simulator's process


def test_use_joystick_starts_joy_and_teleop_twist_joy_into_the_teleop_input(tmp_path):
    assert "joy_node" not in {n.name for n in fake_plan()[0].nodes}  # off by default, as ppp_bot's
    by_name = {n.name: n for n in fake_plan("use_joystick:=True")[0].nodes}
    joy, teleop = " ".join(by_name["joy_node"].cmd), " ".join(by_name["teleop_node"].cmd)
    assert joy.startswith("/bin/pppbot_control/joy_node ") and "config/joystick.yaml" in joy
    assert teleop.startswith("/bin/pppbot_control/teleop_node ") and "config/joystick.yaml" in teleop
    assert "-r __node:=teleop_node" in teleop and "-r cmd_vel:=/cmd_vel_teleop" in teleop
    assert not by_name["joy_node"].required and not by_name["teleop_node"].required  # no joystick: the rest runs
    mine = tmp_path / "my_joystick.yaml"
    mine.write_text((ROOT / "config" / "joystick.yaml").read_text())
    by_name = {n.name: n for n in fake_plan("use_joystick:=true", f"joy_params:={mine}")[0].nodes}
    assert f"--params-file {mine}" in " ".join(by_name["joy_node"].cmd)
    assert f"--params-file {mine}" in " ".join(by_name["teleop_node"].cmd)


def test_stop_timeouts_are_ros2_launchs_and_default_to_5_s():
    assert values().stop_timeouts() == (5.0, 5.0)
    assert values("sigterm_timeout:=20", "sigkill_timeout:=2.5").stop_timeouts() == (20.0, 2.5)
    with pytest.raises(ArgumentError, match="sigterm_timeout:=nan: must be a positive number"):
        values("sigterm_timeout:=nan").stop_timeouts()


class FakeProbes:
    """What the plan asks the graph: (topic, type, latched) of first messages, nodes' endpoints
    and lockstep joins."""

    def __init__(self) -> None:
        self.asked: list[tuple[str, str, bool]] = []
        self.joins: list[str] = []
        self.endpoints_asked: dict[str, dict[str, tuple[str, ...]]] = {}
        self.lifecycle_asked: list[str] = []

    def endpoints(self, node, publishes=(), subscribes=(), action_servers=()):
        self.endpoints_asked[node] = {"publishes": tuple(publishes), "subscribes": tuple(subscribes),
                                      "action_servers": tuple(action_servers)}
        return lambda: True

    def first_message(self, topic, type_name, latched):
        self.asked.append((topic, type_name, latched))
        return lambda: True

    def joined(self, participant):
        self.joins.append(participant)
        return lambda: True

    def lifecycle_active(self, node):
        self.lifecycle_asked.append(node)
        return lambda: True

    def __contains__(self, item) -> bool:
        return item in self.asked


def fake_plan(*argv: str, terminal: bool = False, rviz: str | None = None, extra_participants=()):
    probes = FakeProbes()
    p = plan(values(*argv), ROOT / "worlds" / "maze.sdf", Path("/tmp/robot.urdf"),
             lambda pkg, exe: f"/bin/{pkg}/{exe}", probes, terminal, rviz, extra_participants)
    return p, probes


def test_plan_follows_ppp_bots_order_and_wiring():
    p, probes = fake_plan("world:=maze", "real_time_factor:=3", terminal=True, rviz="/usr/bin/rviz2")
    names = [n.name for n in p.nodes]
    # The controllers run in the simulator's process (the robot's gz_ros2_control plugin names them),
    # and so do robot_state_publisher and twist_mux (composed, as Nav2 composes its servers).
    assert names == ["simulator", "slam_toolbox", "rviz2", "teleop_keyboard"]
    by_name = {n.name: n for n in p.nodes}
    assert set(by_name["teleop_keyboard"].after) == {"simulator", "slam_toolbox"}
    slam = " ".join(by_name["slam_toolbox"].cmd)
    assert slam.startswith("/bin/pppbot_slam/slam ") and "mapper_params_online_async.yaml" in slam
    assert "use_sim_time:=true" in slam and by_name["slam_toolbox"].after == ("simulator",)
    assert ("/map", "nav_msgs/msg/OccupancyGrid", True) in probes
    assert by_name["teleop_keyboard"].terminal and not by_name["simulator"].terminal
    sim = " ".join(by_name["simulator"].cmd)
    assert sim.startswith("/bin/pppbot_sim/simulator --host robot_state_publisher --host twist_mux --ros-args ")
    assert "simulator:world:=" in sim and "maze.sdf" in sim and "simulator:real_time_factor:=3.0" in sim
    assert "simulator:use_sim_time" not in sim
    assert "lockstep" not in " ".join(" ".join(n.cmd) for n in p.nodes)  # wall-clock time by default
    assert "-p simulator:cameras:=true" in sim  # rendered while someone watches
    assert "-p simulator:cameras:=false" in " ".join(fake_plan("cameras:=false")[0].nodes[0].cmd)
    assert all(n.env is None for n in p.nodes)
    # Each hosted node's parameters and remappings scoped to it; their clock the simulator's.
    assert "-p robot_state_publisher:robot_description:=/tmp/robot.urdf" in sim
    assert "-r twist_mux:cmd_vel_out:=/diff_drive_base_controller/cmd_vel_unstamped" in sim
    assert "twist_mux:use_sim_time:=false" in sim and "config/twist_mux.yaml" in sim
    assert ("/robot_description", "std_msgs/msg/String", True) in probes
    assert by_name["simulator"].ready.description == "a first /clock, /robot_description, twist_mux's inputs"
    # A process each (use_composition:=false): ppp_bot's launch files' order and wiring.
    apart = fake_plan("world:=maze", "use_composition:=false", terminal=True)[0]
    assert [n.name for n in apart.nodes] == ["simulator", "robot_state_publisher", "twist_mux", "slam_toolbox",
                                             "teleop_keyboard"]
    by_name = {n.name: n for n in apart.nodes}
    assert by_name["robot_state_publisher"].after == ("simulator",) and by_name["twist_mux"].after == ("simulator",)
    assert by_name["slam_toolbox"].after == ("robot_state_publisher",)
    assert "--host" not in by_name["simulator"].cmd and "-p world:=" in " ".join(by_name["simulator"].cmd)
    mux = " ".join(by_name["twist_mux"].cmd)
    assert "-r cmd_vel_out:=/diff_drive_base_controller/cmd_vel_unstamped" in mux and "use_sim_time:=true" in mux
    assert all(n.required for n in p.nodes if n.name not in ("rviz2", "teleop_keyboard"))
    # Readiness from the graph, never from log text: twist_mux once it has its output and inputs.
    assert probes.endpoints_asked["twist_mux"] == {
        "publishes": ("/diff_drive_base_controller/cmd_vel_unstamped",),
        "subscribes": ("/cmd_vel", "/cmd_vel_teleop"), "action_servers": ()}


def test_twist_mux_inputs_come_from_its_parameter_file(tmp_path):
    from pppbot_bringup.node_specs import twist_mux_inputs

    good = tmp_path / "mux.yaml"
    good.write_text("/**:\n  ros__parameters:\n    topics:\n      a: {topic: /x/in, timeout: 0.5, priority: 1}\n"
                    "    locks:\n      stop: {topic: e_stop, timeout: 0.0, priority: 255}\n")
    assert twist_mux_inputs(good) == ("/e_stop", "/x/in")
    bad = tmp_path / "bad.yaml"
    bad.write_text("other_node:\n  ros__parameters: {}\n")
    with pytest.raises(ArgumentError, match="bad.yaml: not a twist_mux parameter file"):
        twist_mux_inputs(bad)


def test_plan_without_terminal_rviz_or_mapping_says_so():
    p, _ = fake_plan("use_slam:=false")
    assert [n.name for n in p.nodes][-1] == "simulator"
    info = " ".join(p.start_info)  # information, not warnings: nothing to act on
    assert "run ./pppbot teleop in another terminal" in info
    assert "rviz2 is not on PATH" not in info and p.notes == []
    assert "rviz2 is not on PATH" in p.once["no_rviz2"]  # an absent optional tool: said once, not every start
    assert "bag_record" not in [n.name for n in p.nodes]
    assert [n.name for n in fake_plan()[0].nodes][-1] == "slam_toolbox"


def test_localization_serves_the_worlds_map_and_starts_amcl_at_the_spawn_pose_instead_of_slam():
    # Composed (the default): one process; each parameter is given to its own node.
    p, _ = fake_plan("world:=maze", "localization:=true", "x:=1.5", "yaw:=0.5")
    by_name = {n.name: n for n in p.nodes}
    assert "slam_toolbox" not in by_name and not {"map_server", "amcl"} & by_name.keys()
    both = " ".join(by_name["localization"].cmd)
    assert both.startswith("/bin/pppbot_nav/localization ") and "nav2_params.yaml" in both
    assert f"map_server:yaml_filename:={ROOT / 'maps' / 'maze.yaml'}" in both
    for scoped in ("amcl:set_initial_pose:=true", "amcl:initial_pose.x:=1.5", "amcl:initial_pose.yaw:=0.5",
                   "amcl:seed:=0"):  # the launch's seed: AMCL's particles are the same on every run
        assert scoped in both
    assert by_name["localization"].after == ("simulator",) and by_name["localization"].required
    assert by_name["navigation"].after == ("localization",)
    # A process each: the same parameters, unscoped.
    p, probes = fake_plan("world:=maze", "localization:=true", "x:=1.5", "yaw:=0.5", "use_composition:=false")
    by_name = {n.name: n for n in p.nodes}
    assert "slam_toolbox" not in by_name and "localization" not in by_name
    server = " ".join(by_name["map_server"].cmd)
    assert server.startswith("/bin/pppbot_nav/map_server ") and "nav2_params.yaml" in server
    assert f"yaml_filename:={ROOT / 'maps' / 'maze.yaml'}" in server
    amcl = " ".join(by_name["amcl"].cmd)
    assert amcl.startswith("/bin/pppbot_nav/amcl ") and "nav2_params.yaml" in amcl
    assert "set_initial_pose:=true" in amcl and "initial_pose.x:=1.5" in amcl and "initial_pose.yaw:=0.5" in amcl
    assert by_name["amcl"].after == ("robot_state_publisher",)
    assert "seed:=0" in amcl
    assert by_name["amcl"].required and by_name["map_server"].required
    # Each its own process: a lifecycle manager brings them up once both run, and is ready once
    # AMCL publishes a first pose (the map comes only once map_server is active).
    manager = by_name["lifecycle_manager_localization"]
    assert manager.cmd[0] == "/bin/pppbot_nav/lifecycle_manager" and manager.after == ("map_server", "amcl")
    assert "node_names:=['map_server', 'amcl']" in manager.cmd and "autostart:=true" in manager.cmd
    assert "__node:=lifecycle_manager_localization" in manager.cmd and manager.required
    assert manager.ready.description == "a first /amcl_pose"
    assert by_name["planner_server"].after == ("lifecycle_manager_localization",)
    assert ("/amcl_pose", "geometry_msgs/msg/PoseWithCovarianceStamped", True) in probes
    # Each navigation server up once it serves its action, the velocity chain once it listens;
    # navigation once the last node (waypoint_follower, after bt_navigator) is active.
    assert {name: asked["action_servers"] for name, asked in probes.endpoints_asked.items()
            if asked["action_servers"]} == {"planner_server": ("/compute_path_to_pose",),
                                            "controller_server": ("/follow_path",),
                                            "smoother_server": ("/smooth_path",),
                                            "behavior_server": ("/spin",),
                                            "bt_navigator": ("/navigate_to_pose",),
                                            "waypoint_follower": ("/follow_waypoints",)}
    assert probes.endpoints_asked["collision_monitor"]["subscribes"] == ("/cmd_vel_smoothed",)
    assert by_name["bt_navigator"].ready.description == "its navigate_to_pose action server"
    nav_manager = by_name["lifecycle_manager_navigation"]
    assert f"node_names:={list(NAVIGATION_NODES)}" in nav_manager.cmd
    assert nav_manager.after == NAVIGATION_NODES
    assert nav_manager.ready.description == "waypoint_follower active"
    assert probes.lifecycle_asked == ["waypoint_follower"]
    # The velocity chain of Jazzy's bringup, by node-scoped remappings.
    assert "controller_server:cmd_vel:=cmd_vel_nav" in by_name["controller_server"].cmd
    assert "velocity_smoother:cmd_vel:=cmd_vel_nav" in by_name["velocity_smoother"].cmd
    other = {n.name: n for n in fake_plan("localization:=true", f"map:={ROOT / 'maps' / 'room.yaml'}")[0].nodes}
    assert f"yaml_filename:={ROOT / 'maps' / 'room.yaml'}" in " ".join(other["localization"].cmd)


def test_navigation_without_localization_or_slam_needs_parameters_that_navigate_in_odom(tmp_path):
    with pytest.raises(ArgumentError) as info:
        fake_plan("use_slam:=false", "navigation:=true")
    assert "navigates in odom" in str(info.value) and "bt_navigator global_frame: map (not odom)" in str(info.value)
    free = map_free_params(ROOT / "config" / "nav2_params.yaml", tmp_path / "free.yaml", 20)
    p, _ = fake_plan("use_slam:=false", "navigation:=true", "lockstep:=true", f"params_file:={free}")
    by_name = {n.name: n for n in p.nodes}
    assert "localization" not in by_name and "slam_toolbox" not in by_name
    assert by_name["navigation"].after == ("simulator",) and str(free) in " ".join(by_name["navigation"].cmd)


def test_lockstep_makes_the_data_path_participants_and_tells_the_simulator_whom_to_wait_for():
    p, probes = fake_plan("lockstep:=true", "real_time_factor:=0", "localization:=true", "navigation:=true",
                          extra_participants=("pppbot_eval",))
    by_name = {n.name: " ".join(n.cmd) for n in p.nodes}
    # The planner, controller_server and navigator composed in one process: one participant.
    # map_server and amcl composed likewise; robot_state_publisher and twist_mux run in the
    # simulator's process, on its side of lockstep.
    participants = ["localization", "navigation"]
    for name in participants:
        assert "lockstep:=true" in by_name[name] and f"lockstep_name:={name}" in by_name[name]
    sim = by_name["simulator"]
    assert "simulator:lockstep:=true" in sim and "simulator:real_time_factor:=0.0" in sim
    assert f"simulator:lockstep_participants:={[*participants, 'pppbot_eval']}" in sim
    # A process each: robot_state_publisher too (its wheel transforms are on /tf, which lockstep
    # counts), twist_mux, amcl; map_server is not on the data path: never waited for.
    apart = {n.name: " ".join(n.cmd) for n in fake_plan("lockstep:=true", "localization:=true",
                                                        "use_composition:=false")[0].nodes}
    for name in ("twist_mux", "robot_state_publisher", "amcl"):
        assert f"lockstep_name:={name}" in apart[name]
    assert "lockstep" not in apart["map_server"]
    # A participant is ready once the simulator lists it as joined (not at a first message).
    assert probes.joins == participants
    assert ("/clock", "rosgraph_msgs/msg/Clock", False) in probes


def test_navigation_is_one_composed_process_unless_use_composition_is_false():
    composed = {n.name: n for n in fake_plan("localization:=true", "lockstep:=true")[0].nodes}
    nav = composed["navigation"]
    assert nav.cmd[0] == "/bin/pppbot_nav/navigation" and nav.after == ("localization",) and nav.required
    assert "lockstep_name:=navigation" in nav.cmd and "nav2_params.yaml" in " ".join(nav.cmd)
    assert not {"planner_server", "controller_server", "bt_navigator"} & composed.keys()
    assert nav.ready.description == "navigation (joined lockstep)"  # and all active
    separate = {n.name: n for n in fake_plan("localization:=true", "lockstep:=true", "use_composition:=false")[0].nodes}
    assert "navigation" not in separate
    for name in NAVIGATION_NODES:
        assert separate[name].cmd[0] == f"/bin/pppbot_nav/{name}" and f"lockstep_name:={name}" in separate[name].cmd
    free_running = {n.name: n for n in fake_plan("localization:=true")[0].nodes}  # composed too, as Nav2's bringup
    assert not {"planner_server", "controller_server", "bt_navigator"} & free_running.keys()
    assert free_running["navigation"].ready.description == "waypoint_follower active"
    assert not any("lockstep" in arg for arg in free_running["navigation"].cmd)
    apart = {n.name for n in fake_plan("localization:=true", "use_composition:=false")[0].nodes}
    assert "navigation" not in apart and {*NAVIGATION_NODES, "lifecycle_manager_navigation"} <= apart


@pytest.mark.parametrize("switches, managed, remaps", [
    ((), NAVIGATION_NODES, ["controller_server:cmd_vel:=cmd_vel_nav", "behavior_server:cmd_vel:=cmd_vel_nav",
                            "velocity_smoother:cmd_vel:=cmd_vel_nav"]),
    (("use_collision_monitor:=false",), tuple(n for n in NAVIGATION_NODES if n != "collision_monitor"),
     ["controller_server:cmd_vel:=cmd_vel_nav", "behavior_server:cmd_vel:=cmd_vel_nav",
      "velocity_smoother:cmd_vel:=cmd_vel_nav", "velocity_smoother:cmd_vel_smoothed:=cmd_vel"]),
    (("use_velocity_smoother:=false",), tuple(n for n in NAVIGATION_NODES if n != "velocity_smoother"),
     ["controller_server:cmd_vel:=cmd_vel_smoothed", "behavior_server:cmd_vel:=cmd_vel_smoothed"]),
    (("use_velocity_smoother:=false", "use_collision_monitor:=false"),
     tuple(n for n in NAVIGATION_NODES if n not in ("velocity_smoother", "collision_monitor")), []),
], ids=["both", "no-monitor", "no-smoother", "neither"])
def test_the_velocity_chain_is_on_by_default_and_each_part_can_be_left_out(switches, managed, remaps):
    composed = {n.name: n for n in fake_plan("localization:=true", *switches)[0].nodes}["navigation"].cmd
    rules = [composed[i + 1] for i, arg in enumerate(composed) if arg == "-r"]
    assert rules == remaps
    left_out = [composed[i + 1] for i, arg in enumerate(composed) if arg == "--without"]
    assert left_out == [n for n in ("velocity_smoother", "collision_monitor") if n not in managed]
    apart = {n.name: n for n in fake_plan("localization:=true", "use_composition:=false", *switches)[0].nodes}
    assert f"node_names:={list(managed)}" in apart["lifecycle_manager_navigation"].cmd
    assert {"velocity_smoother", "collision_monitor"} & apart.keys() == {"velocity_smoother", "collision_monitor"} & {
        *managed}
    for name in managed:
        own = [apart[name].cmd[i + 1] for i, arg in enumerate(apart[name].cmd) if arg == "-r"]
        assert own == [rule for rule in remaps if rule.startswith(f"{name}:")]


@pytest.mark.parametrize("section", NAVIGATION_NODES)
def test_a_params_file_without_a_nodes_section_runs_it_on_defaults_or_leaves_out_the_monitor(section, tmp_path):
    """ppp_bot's nav2_params.yaml (Humble's shape) has no collision_monitor: Jazzy's bringup runs one,
    Humble's did not, and no default zones make sense, so it is left out (velocity_smoother's
    output bridged to twist_mux); every other node runs on Nav2's defaults. One line says which."""
    document = yaml.safe_load((ROOT / "config" / "nav2_params.yaml").read_text())
    del document[section]
    own = tmp_path / "nav2_params.yaml"
    own.write_text(yaml.safe_dump(document))
    p, _ = fake_plan("localization:=true", f"params_file:={own}")
    composed = {n.name: n for n in p.nodes}["navigation"].cmd
    left_out = [composed[i + 1] for i, arg in enumerate(composed) if arg == "--without"]
    notes = [line for line in p.start_info if "has no section" in line]
    assert len(notes) == 1 and notes[0].startswith("nav2_params.yaml has no section for 1 node(s): ")
    if section == "collision_monitor":
        assert left_out == ["collision_monitor"] and "collision_monitor left out" in notes[0]
        assert "velocity_smoother:cmd_vel_smoothed:=cmd_vel" in composed  # bridged to twist_mux
    else:
        assert left_out == [] and notes[0].endswith(f"{section} on Nav2's defaults")
    full, _ = fake_plan("localization:=true")
    assert not [line for line in full.start_info if "has no section" in line]


def test_record_adds_a_recorder_right_after_the_simulator(tmp_path):
    from pppbot_bag.cli import RecordOptions

    p, probes = fake_plan("record:=true", f"bag_path:={tmp_path / 'b'}")
    recorder = p.nodes[1]
    assert recorder.name == "bag_record" and recorder.after == ("simulator",) and not recorder.required
    # Ready once the recorder's node (rosbag2's name) subscribes to the simulator's /clock.
    assert probes.endpoints_asked[RecordOptions.node_name]["subscribes"] == ("/clock",)
    assert list(recorder.cmd) == ["/bin/pppbot_bringup/pppbot", "bag", "record", "-a", "--use-sim-time",
                                  "-o", str(tmp_path / "b")]
    (tmp_path / "b").mkdir()
    with pytest.raises(ArgumentError, match="exists already"):
        fake_plan("record:=true", f"bag_path:={tmp_path / 'b'}")


def test_slam_params_file_replaces_the_default_and_must_exist(tmp_path):
    own = tmp_path / "extend_maze.yaml"
    own.write_text("slam_toolbox:\n  ros__parameters:\n    map_file_name: maps/maze\n")
    p, _ = fake_plan(f"slam_params_file:={own}")
    slam = next(n for n in p.nodes if n.name == "slam_toolbox")
    assert str(own) in slam.cmd and "mapper_params_online_async.yaml" not in " ".join(slam.cmd)
    with pytest.raises(ArgumentError, match=f"slam_params_file:={tmp_path / 'missing.yaml'}: no such file"):
        fake_plan(f"slam_params_file:={tmp_path / 'missing.yaml'}")


def test_live_view_runs_on_localhost_with_its_own_settings(tmp_path):
    from pppbot_viz.viewer import ViewerKind

    from pppbot_bringup.node_specs import VizPlan

    probes = FakeProbes()
    viz = VizPlan(grpc_port=4001, web_port=4002, page_port=4003, native=False, state_dir=tmp_path / "rerun")
    p = plan(values("world:=maze", "viz_port:=4003"), ROOT / "worlds" / "maze.sdf", Path("/tmp/robot.urdf"),
             lambda pkg, exe: f"/bin/{pkg}/{exe}", probes, True, None, viz=viz)
    by_name = {n.name: n for n in p.nodes}
    assert [n.name for n in p.nodes][-3:] == ["rerun", "viz", "teleop_keyboard"]
    server = list(by_name["rerun"].cmd)
    assert server[0].endswith("rerun_cli/rerun") and "--serve-web" in server
    assert server[server.index("--bind") + 1] == "127.0.0.1"
    assert (server[server.index("--port") + 1], server[server.index("--web-viewer-port") + 1]) == ("4001", "4002")
    # rerun's settings (analytics off) in pppbot's directory, not the user's home
    assert by_name["rerun"].env == {"XDG_CONFIG_HOME": str(tmp_path / "rerun" / "config"),
                                    "XDG_DATA_HOME": str(tmp_path / "rerun" / "data"), "RUST_LOG": "warn"}
    node = " ".join(by_name["viz"].cmd)
    assert node.startswith("/bin/pppbot_viz/viz ") and "-p rerun_port:=4001" in node and "-p port:=4003" in node
    assert by_name["viz"].after == ("rerun", "simulator") and not by_name["viz"].required
    assert probes.endpoints_asked["viz"]["publishes"] == ("/goal_pose", "/initialpose")
    assert "-p announce:=false" in node and "-p images_while_watched:=true" in node  # the launch prints the URL
    assert p.info == ["live view: http://127.0.0.1:4003/ <- open it in a browser (2D Goal Pose / 2D Pose Estimate: "
                      "a button, then two clicks on the map)"]
    moved = plan(values("world:=maze", "viz_port:=9090"), ROOT / "worlds" / "maze.sdf", Path("/tmp/robot.urdf"),
                 lambda pkg, exe: f"/bin/{pkg}/{exe}", probes, True, None, viz=viz)
    assert moved.info[0].startswith("live view: http://127.0.0.1:4003/ <- open it in a browser; port 9090 was taken")
    # with a display: a native viewer window on the same server too
    native = plan(values("world:=maze"), ROOT / "worlds" / "maze.sdf", Path("/tmp/robot.urdf"),
                  lambda pkg, exe: f"/bin/{pkg}/{exe}", FakeProbes(), False, None,
                  viz=VizPlan(4001, 4002, 4003, True, tmp_path))
    viewer = next(n for n in native.nodes if n.name == "rerun_viewer")
    assert viewer.cmd[1:3] == ["--connect", "rerun+http://127.0.0.1:4001/proxy"] and viewer.after == ("rerun",)
    assert ViewerKind.AUTO.native({"DISPLAY": ":0"}) and not ViewerKind.AUTO.native({})
    assert ViewerKind.NATIVE.native({}) and not ViewerKind.WEB.native({"WAYLAND_DISPLAY": "wayland-0"})


def test_a_view_recording_alone_is_the_viz_node_writing_a_file_without_a_server(tmp_path):
    from pppbot_bringup.node_specs import VizPlan

    p = plan(values("world:=maze", "use_viz:=false"), ROOT / "worlds" / "maze.sdf", Path("/tmp/robot.urdf"),
             lambda pkg, exe: f"/bin/{pkg}/{exe}", FakeProbes(), False, None, view_recording=tmp_path / "view.rrd")
    names = [n.name for n in p.nodes]
    assert "viz" in names and "rerun" not in names and "rerun_viewer" not in names and p.info == []
    node = next(n for n in p.nodes if n.name == "viz")
    assert f"-p recording_path:={tmp_path / 'view.rrd'}" in " ".join(node.cmd)
    assert "-p scan_max_rate_hz:=2.0" in " ".join(node.cmd)
    assert not any("rerun_port" in arg or arg.startswith("port:=") for arg in node.cmd)
    assert node.after == ("simulator",)
    # with the live view as well: one viz node streams to the server and writes the file
    both = plan(values("world:=maze"), ROOT / "worlds" / "maze.sdf", Path("/tmp/robot.urdf"),
                lambda pkg, exe: f"/bin/{pkg}/{exe}", FakeProbes(), False, None,
                viz=VizPlan(4001, 4002, 4003, False, tmp_path), view_recording=tmp_path / "view.rrd")
    vizzes = [n for n in both.nodes if n.name == "viz"]
    assert len(vizzes) == 1 and "-p rerun_port:=4001" in " ".join(vizzes[0].cmd)
    assert "recording_path:=" in " ".join(vizzes[0].cmd)


def test_a_taken_viz_port_moves_the_page_instead_of_stopping_the_robot(monkeypatch, tmp_path):
    import socket

    from pppbot_bringup.ros import launch_sim as ros_launch_sim
    from pppbot_viz import viewer

    monkeypatch.setattr(viewer, "state_directory", lambda checkout: tmp_path)
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        viz, notes = ros_launch_sim.viz_plan(values(f"viz_port:={port}"))
    assert viz.page_port != port and len({viz.page_port, viz.grpc_port, viz.web_port}) == 3
    assert notes == [f"viz_port:={port} is taken (another launch_sim?): the live view takes port {viz.page_port} "
                     "instead"]
    assert (tmp_path / "config" / "rerun" / "analytics.json").is_file()
    with pytest.raises(VizError, match="viz_port:=70000: must be a port number"):
        ros_launch_sim.viz_plan(values("viz_port:=70000"))


@pytest.mark.parametrize(("argv", "environ", "message"), [
    (["real_time_factor:=-1"], {}, "real_time_factor:=-1: must be a number from 0 to 1000"),
    (["wheel_slip:=0.5"], {}, "wheel_slip:=0.5: must be a number from 0 to 0.2"),
    (["x:=nan"], {}, "x:=nan: must be a number from -1e+06 to 1e+06"),
    (["z:=inf"], {}, "z:=inf: must be a number (or nan: resting on the ground)"),
    (["seed:=-3"], {}, "seed:=-3: must be a whole number from 0"),
    (["viz_port:=70000"], {}, "viz_port:=70000: must be a port number from 0 (a free one) to 65535"),
    (["sigterm_timeout:=0"], {}, "sigterm_timeout:=0: must be a positive number of seconds"),
    (["headless:=false"], {}, "headless:=false opens a window, and there is no display here"),
    (["viz_viewer:=native"], {}, "viz_viewer:=native opens a window, and there is no display here"),
])
def test_every_argument_is_checked_before_anything_starts(argv, environ, message):
    with pytest.raises(ArgumentError) as info:
        values(*argv).validate(environ)
    assert message in str(info.value)
    values(*argv[:0]).validate({})  # the defaults pass
    values("headless:=false").validate({"DISPLAY": ":0"})  # with a display, a window is fine


def test_a_bad_value_or_world_stops_the_launch_before_any_process(tmp_path):
    broken = tmp_path / "broken.sdf"
    broken.write_text("<sdf><world name='w'><model name='m'><link name='l'><collision name='c'><geometry>"
                      "<box><size>1 1</size></box></geometry></collision></link></model></world></sdf>")
    for argv, message in ((["real_time_factor:=-1"], "launch_sim: real_time_factor:=-1: must be a number"),
                          ([f"world:={broken}"], f"launch_sim: {broken}:1: <size> needs 3 numbers, not '1 1'")):
        result = subprocess.run([PPPBOT, "launch_sim", "use_teleop:=false", *argv], capture_output=True, text=True,
                                timeout=60)
        assert result.returncode == 2 and message in result.stderr, result.stderr
        assert "process started" not in result.stdout


def test_slam_localization_mode_needs_an_existing_pose_graph(tmp_path):
    base = (ROOT / "config" / "mapper_params_online_async.yaml").read_text()
    without = tmp_path / "no_graph.yaml"
    without.write_text(base.replace("mode: mapping", "mode: localization"))
    with pytest.raises(ArgumentError, match="mode: localization needs map_file_name"):
        fake_plan(f"slam_params_file:={without}")
    missing = tmp_path / "missing_graph.yaml"
    missing.write_text(base.replace("mode: mapping", f"mode: localization\n    map_file_name: {tmp_path}/maze"))
    with pytest.raises(ArgumentError, match=r"map_file_name: .*/maze: no pose graph maze.posegraph"):
        fake_plan(f"slam_params_file:={missing}")
    (tmp_path / "maze.posegraph").write_bytes(b"graph")
    nodes = {n.name: " ".join(n.cmd) for n in fake_plan(f"slam_params_file:={missing}")[0].nodes}
    assert "slam_toolbox" in nodes  # the slam node localizes in it (tests/pppbot_slam)


def test_a_malformed_map_is_refused_before_anything_starts(tmp_path):
    bad_yaml = tmp_path / "bad.yaml"
    bad_yaml.write_text("image: bad.pgm\nresolution: [0.05\n")
    with pytest.raises(ArgumentError, match=r"map:=.*bad.yaml"):
        fake_plan("localization:=true", f"map:={bad_yaml}")
    header = tmp_path / "header.yaml"
    header.write_text("image: header.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\n"
                      "occupied_thresh: 0.65\nfree_thresh: 0.25\n")
    (tmp_path / "header.pgm").write_bytes(b"P5\nforty 40\n255\n" + bytes(1600))
    with pytest.raises(ArgumentError, match=r"map:=.*header.pgm"):
        fake_plan("localization:=true", f"map:={header}")


def test_a_note_said_once_is_said_the_first_time_only(tmp_path):
    from pppbot_bringup.notices import first_time

    assert first_time("no_rviz2", tmp_path)
    assert not first_time("no_rviz2", tmp_path)
    assert first_time("other", tmp_path)  # each note on its own
    unwritable = tmp_path / "file"
    unwritable.write_text("")
    assert first_time("no_rviz2", unwritable) and first_time("no_rviz2", unwritable)  # can't remember: said again
    with pytest.raises(ValueError, match="lower-case letters"):
        first_time("../escape", tmp_path)


def test_respawn_restarts_every_node_but_the_simulator_and_the_terminals_and_not_in_lockstep():
    p, _ = fake_plan("respawn:=true", "respawn_delay:=0.5", "localization:=true", "record:=true", terminal=True)
    by_name = {n.name: n for n in p.nodes}
    assert not any(by_name[n].respawn for n in ("simulator", "teleop_keyboard"))
    others = [n for n in p.nodes if n.name not in ("simulator", "teleop_keyboard")]
    assert {"localization", "navigation", "bag_record"} <= {n.name for n in others}
    assert by_name["bag_record"].cmd[-1] == "--resume"  # started again, it records on into its own bag
    assert "--resume" not in next(n for n in fake_plan("record:=true")[0].nodes if n.name == "bag_record").cmd
    assert all(n.respawn and n.respawn_delay_s == 0.5 for n in others)
    assert [n.max_respawns for n in others if n.max_respawns != -1] == [3]  # the recorder's: a few times
    assert by_name["bag_record"].max_respawns == 3
    assert not any(n.respawn for n in fake_plan("localization:=true")[0].nodes)
    slam = next(n for n in fake_plan("respawn:=true")[0].nodes if n.name == "slam_toolbox")
    assert "autosave_name:=/tmp/slam_autosave" in " ".join(slam.cmd)  # in the run's directory, beside robot.urdf
    with pytest.raises(ArgumentError, match="respawn:=true needs lockstep:=false"):
        values("respawn:=true", "lockstep:=true").validate({})
    with pytest.raises(ArgumentError, match="respawn:=true needs use_composition:=true"):
        values("respawn:=true", "use_composition:=false").validate({})
    with pytest.raises(ArgumentError, match="respawn_delay:=-1: must be a number of seconds from 0 to 3600"):
        values("respawn_delay:=-1").validate({})
