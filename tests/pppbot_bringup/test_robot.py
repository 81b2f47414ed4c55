"""Bring your own robot: ``description:=`` and ``xacro_args:=``, what the bringup takes from the
description (drive, frames, topics, resting height), and a user's robot with Gazebo's DiffDrive
plugin driving and mapping under ``launch_sim``."""
from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml
from geometry_msgs.msg import Twist
from nav_msgs.msg import OccupancyGrid, Odometry

from pppbot_bringup.launch_sim import LaunchArgs, controllers_file, plan
from pppbot_bringup.node_specs import twist_mux_inputs
from pppbot_bringup.paths import config_directory
from pppbot_bringup.robot import (
    MUX_OWN_OUTPUT,
    PPP_BOT,
    Drive,
    adapt_parameters,
    description_path,
    load_description,
    parse_xacro_args,
    robot_facts,
)
from pppbot_common.launch_args import ArgumentError
from pppbot_common.ros.qos import LATCHED
from pppbot_common.ros.wait import wait_until
from pppbot_description.errors import DescriptionError

ROOT = Path(__file__).resolve().parents[2]
PPPBOT = str(ROOT / "pppbot")
MY_BOT = Path(__file__).parent / "data" / "my_bot" / "my_bot.urdf.xacro"
MUX_INPUTS = twist_mux_inputs(config_directory() / "twist_mux.yaml")


def facts(description: str = "", xacro_args: str = ""):
    urdf, source = load_description(description, xacro_args, controllers_file())
    return robot_facts(urdf, source, MUX_INPUTS)


def test_ppp_bot_by_default_is_the_shipped_files_robot() -> None:
    assert facts() == PPP_BOT
    # the same file through the ament index
    assert facts("package://pppbot_description/urdf/robot.urdf.xacro") == PPP_BOT


def test_ppp_bot_with_ignition_control_puts_twist_mux_in_front_of_its_plugin() -> None:
    robot = facts(xacro_args="use_ros2_control:=false")
    assert robot.drive is Drive.GAZEBO_PLUGIN
    # the plugin's /cmd_vel is twist_mux's navigation input: the mux keeps cmd_vel_out, the plugin listens there
    assert (robot.command_topic, robot.simulator_cmd_vel_topic) == (MUX_OWN_OUTPUT, MUX_OWN_OUTPUT)
    assert robot.notes == ()  # nothing to act on: it is told, not warned
    assert robot.info == ("the DiffDrive plugin's topic /cmd_vel is one of twist_mux's inputs: twist_mux publishes "
                          "on /cmd_vel_out and the plugin listens there",)


def test_a_users_robot_declares_its_own_frames_and_topics() -> None:
    robot = facts(str(MY_BOT), "wheel_radius:=0.08")
    assert (robot.name, robot.drive, robot.command_topic) == ("my_bot", Drive.GAZEBO_PLUGIN, "/my_bot/cmd_vel")
    assert (robot.odom_topic, robot.odom_frame, robot.scan_topic) == ("/my_bot/odom", "my_bot/odom", "/laser_scan")
    # no base_footprint or base_link: its root link, "base", for SLAM, AMCL and the costmaps
    assert (robot.localization_base_frame, robot.navigation_base_frame) == ("base", "base")


def test_parameter_files_follow_the_robot_where_they_say_ppp_bots() -> None:
    robot = facts(str(MY_BOT))
    nav = yaml.safe_load((config_directory() / "nav2_params.yaml").read_text())
    changes = adapt_parameters(nav, robot)
    amcl = nav["amcl"]["ros__parameters"]
    assert (amcl["base_frame_id"], amcl["odom_frame_id"], amcl["scan_topic"]) == ("base", "my_bot/odom", "/laser_scan")
    local = nav["local_costmap"]["local_costmap"]["ros__parameters"]
    assert (local["global_frame"], local["robot_base_frame"], local["voxel_layer"]["scan"]["topic"]) == \
        ("my_bot/odom", "base", "/laser_scan")
    assert nav["global_costmap"]["global_costmap"]["ros__parameters"]["global_frame"] == "map"  # not ppp_bot's odom
    assert nav["controller_server"]["ros__parameters"]["odom_topic"] == "/my_bot/odom"
    assert nav["bt_navigator"]["ros__parameters"]["robot_base_frame"] == "base"
    assert "base_frame_id: base_footprint → base" in changes
    # ppp_bot's own files need no change for ppp_bot
    assert adapt_parameters(yaml.safe_load((config_directory() / "nav2_params.yaml").read_text()), PPP_BOT) == []


def test_the_plan_wires_the_users_robot(tmp_path: Path) -> None:
    robot = facts(str(MY_BOT))
    p = plan(LaunchArgs.parse(["world:=empty", "localization:=false"]), ROOT / "worlds" / "empty.sdf",
             tmp_path / "robot.urdf", lambda pkg, exe: f"/bin/{pkg}/{exe}", _Probes(), False, None, robot=robot)
    nodes = {n.name: " ".join(n.cmd) for n in p.nodes}
    assert "-r twist_mux:cmd_vel_out:=/my_bot/cmd_vel" in nodes["simulator"]  # twist_mux in its process
    assert "-p simulator:z:=nan " in nodes["simulator"] + " " and "cmd_vel_topic" not in nodes["simulator"]
    slam_file = tmp_path / "mapper_params_online_async.yaml"
    assert f"--params-file {slam_file}" in nodes["slam_toolbox"]
    slam = yaml.safe_load(p.files[slam_file])["slam_toolbox"]["ros__parameters"]
    assert (slam["odom_frame"], slam["base_frame"], slam["scan_topic"]) == ("my_bot/odom", "base", "/laser_scan")
    assert any("mapper_params_online_async.yaml follows robot 'my_bot'" in note for note in p.start_info)


class _Probes:
    def first_message(self, topic, type_name, latched):
        return lambda: True

    def endpoints(self, node, publishes=(), subscribes=(), action_servers=()):
        return lambda: True

    def joined(self, participant):
        return lambda: True

    def lifecycle_active(self, node):
        return lambda: True


@pytest.mark.parametrize(("description", "xacro_args", "error", "message"), [
    ("", "use_ros2_control", ArgumentError, "xacro_args: 'use_ros2_control' is not of the form name:=value"),
    ("/nowhere/robot.urdf", "", ArgumentError, r"description:=/nowhere/robot.urdf: no such file"),
    ("package://no_such_pkg/urdf/r.xacro", "", ArgumentError, r"description:=package://no_such_pkg/urdf/r.xacro: "),
    (str(Path(__file__)), "", ArgumentError, r"expected a .urdf or .xacro file, not '.py'"),
    ("", "wheels:=3", DescriptionError, r"unknown xacro argument\(s\) wheels"),
])
def test_bad_descriptions_are_named(description: str, xacro_args: str, error: type, message: str) -> None:
    with pytest.raises(error, match=message):
        facts(description, xacro_args)


def test_xacro_args_and_paths() -> None:
    assert parse_xacro_args("a:=1 b:=x/y") == {"a": "1", "b": "x/y"}
    assert description_path(f"file://{MY_BOT}") == MY_BOT


@pytest.mark.ros
def test_users_robot_drives_and_maps_under_launch_sim(ros_node, spawn) -> None:
    launch = spawn([PPPBOT, "launch_sim", "world:=room", f"description:={MY_BOT}", "xacro_args:=wheel_radius:=0.07",
                    "use_teleop:=false", "use_rviz:=false", "use_viz:=false", "real_time_factor:=2.0"],
                   name="launch_sim")
    launch.wait_for_output(r"my_bot is up in 'room'", 90)
    truths: list[Odometry] = []
    odoms: list[Odometry] = []
    maps: list[OccupancyGrid] = []
    ros_node.create_subscription(Odometry, "/ground_truth/odom", truths.append, 10)
    ros_node.create_subscription(Odometry, "/my_bot/odom", odoms.append, 10)
    ros_node.create_subscription(OccupancyGrid, "/map", maps.append, LATCHED)
    pub = ros_node.create_publisher(Twist, "/cmd_vel_teleop", 10)
    wait_until(lambda: truths and pub.get_subscription_count() >= 1, 20, "ground truth and twist_mux", node=ros_node)
    start = truths[-1].pose.pose.position
    turn = Twist()
    turn.linear.x, turn.angular.z = 0.3, 0.4
    wait_until(lambda: (pub.publish(turn), math.hypot(truths[-1].pose.pose.position.x - start.x,
                                                      truths[-1].pose.pose.position.y - start.y) > 0.6)[1],
               40, "my_bot to drive 0.6 m through teleop → twist_mux → its DiffDrive plugin", node=ros_node)
    assert odoms and odoms[-1].header.frame_id == "my_bot/odom" and odoms[-1].child_frame_id == "base"
    # SLAM, on the robot's own scan topic and frames, made a map
    wait_until(lambda: maps, 30, "a /map", node=ros_node)
    assert maps[-1].header.frame_id == "map" and (max(maps[-1].data) == 100)


def test_launches_started_in_the_same_second_get_a_log_directory_each(tmp_path):
    from pppbot_bringup.paths import new_run_dir

    first, second, third = (new_run_dir(tmp_path / "launch_sim", "2026-11-28-21-17-55") for _ in range(3))
    assert [p.name for p in (first, second, third)] == \
        ["2026-11-28-21-17-55", "2026-11-28-21-17-55-2", "2026-11-28-21-17-55-3"]
    assert all(p.is_dir() for p in (first, second, third))
