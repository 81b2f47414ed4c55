"""Gazebo's DiffDrive plugins: read with Gazebo's defaults and names, limited as Gazebo limits, and
driving a world model's wheels and the robot's (ppp_bot with ignition_control.xacro or
gazebo_control.xacro) the commanded distance."""
from __future__ import annotations

import math
from pathlib import Path

import pytest
from lxml import etree

from pppbot_description.urdf_model import parse_urdf
from pppbot_description.xacro_model import process_xacro
from pppbot_sim.errors import PluginError
from pppbot_sim.gz_plugins import DiffDriveSystem, Flavor, read_diff_drive, robot_plugins, world_plugins
from pppbot_sim.mj_build import SpawnPose
from pppbot_sim.sdf_world import read_sdf_world
from pppbot_sim.simulation import Simulation, load_world
from pppbot_sim.worlds import find_world, model_paths

CORPUS = Path(__file__).parent / "data" / "corpus"
BUILT = CORPUS / "gazebo_built.sdf"


def plugin(xml: str, flavor: Flavor = Flavor.GZ, model: str = "bot"):
    element = etree.fromstring(xml)
    return read_diff_drive(element, flavor, model, "base", lambda j: j,
                           lambda e: f"robot.urdf:{e.sourceline if e is not None else '?'}")


def test_world_model_plugin_takes_gazebos_defaults() -> None:
    (spec,) = world_plugins(read_sdf_world(BUILT, model_paths(BUILT)).plugins).diff_drives
    assert spec.flavor is Flavor.GZ
    assert (spec.left_joints, spec.right_joints) == (("vehicle::left_wheel_joint",), ("vehicle::right_wheel_joint",))
    assert (spec.topic, spec.odom_topic, spec.tf_topic) == ("/model/vehicle/cmd_vel", "/model/vehicle/odometry",
                                                            "/model/vehicle/tf")
    assert (spec.frame_id, spec.child_frame_id, spec.body) == ("vehicle/odom", "vehicle/chassis", "vehicle::chassis")
    assert (spec.wheel_separation_m, spec.wheel_radius_m, spec.odom_rate_hz) == (0.5, 0.1, 20.0)
    assert spec.linear.max_acceleration == 1.0 and math.isnan(spec.linear.max_velocity)


def test_ppp_bots_ignition_and_classic_plugins() -> None:
    gz = robot_plugins(parse_urdf(process_xacro(mappings={"use_ros2_control": "false"})).plugins, "ppp_bot",
                       "base_link")
    (spec,) = gz.diff_drives
    assert gz.warnings == []  # the JointStatePublisher system is the simulator's /joint_states
    assert (spec.topic, spec.odom_topic, spec.tf_topic) == ("/cmd_vel", "/odom", "/tf")
    assert (spec.frame_id, spec.child_frame_id, spec.odom_rate_hz) == ("odom", "base_link", 50.0)
    assert (spec.wheel_separation_m, spec.wheel_radius_m) == pytest.approx((0.35, 0.05))
    assert (spec.linear.max_velocity, spec.linear.min_acceleration, spec.angular.max_acceleration) == (2.0, -1.0, 1.0)
    classic = robot_plugins(parse_urdf(process_xacro(mappings={"use_ros2_control": "false", "gazebo": "classic"}))
                            .plugins, "ppp_bot", "base_link")
    (spec,) = classic.diff_drives
    assert spec.flavor is Flavor.CLASSIC and spec.odometry_from_world  # no <odometry_source>: the world's
    assert (spec.topic, spec.odom_topic, spec.tf_topic, spec.publish_odom) == ("/cmd_vel", "/odom", "/tf", True)
    assert (spec.wheel_radius_m, spec.max_wheel_torque, spec.wheel_acceleration) == pytest.approx((0.05, 200, 10))


def test_classic_namespace_and_remapping() -> None:
    spec = plugin("""<plugin filename="libgazebo_ros_diff_drive.so" name="d">
        <ros><namespace>/demo</namespace><remapping>cmd_vel:=cmd_demo</remapping>
             <remapping>odom:=/odom_demo</remapping></ros>
        <left_joint>l</left_joint><right_joint>r</right_joint><odometry_source>0</odometry_source>
        <command_topic>cmd_vel</command_topic></plugin>""", Flavor.CLASSIC)
    assert (spec.topic, spec.odom_topic) == ("/demo/cmd_demo", "/odom_demo")
    assert (spec.frame_id, spec.child_frame_id, spec.tf_topic) == ("odom", "base_footprint", None)
    assert not spec.odometry_from_world and not spec.publish_odom
    assert (spec.wheel_separation_m, spec.wheel_radius_m, spec.max_wheel_torque) == (0.34, 0.075, 5.0)
    # ROS 1's <command_topic> does nothing in Gazebo classic's ROS 2 plugin: named, not honoured
    assert spec.warnings == ("robot.urdf:5: <command_topic> is not a parameter of libgazebo_ros_diff_drive: "
                             "ignored (as Gazebo does)",)


def test_misspelt_parameter_is_named_not_honoured() -> None:
    spec = plugin("""<plugin filename="gz-sim-diff-drive-system" name="gz::sim::systems::DiffDrive">
        <left_joint>l</left_joint><right_joint>r</right_joint>
        <odom_publisher_frequency>100</odom_publisher_frequency></plugin>""")
    assert spec.odom_rate_hz == 50.0
    assert spec.warnings == ("robot.urdf:3: <odom_publisher_frequency> is not a parameter of Gazebo's DiffDrive "
                             "system: ignored (as Gazebo does)",)


@pytest.mark.parametrize(("body", "message"), [
    ("<left_joint>l</left_joint>", r"robot.urdf:1: the DiffDrive plugin of 'bot' needs at least one <left_joint>"),
    ("<left_joint>l</left_joint><right_joint>r</right_joint><wheel_radius>-1</wheel_radius>",
     r"<wheel_radius> must be a positive number, not '-1'"),
    ("<left_joint>l</left_joint><right_joint>r</right_joint><min_linear_acceleration>2</min_linear_acceleration>",
     r"<min_linear_acceleration> 2.0 must be negative"),
])
def test_bad_plugins_are_refused_with_file_and_line(body: str, message: str) -> None:
    with pytest.raises(PluginError, match=message):
        plugin(f'<plugin filename="gz-sim-diff-drive-system" name="x">{body}</plugin>')


def test_limits_ramp_the_command_and_odometry_integrates_wheel_angles() -> None:
    spec = plugin("""<plugin filename="gz-sim-diff-drive-system" name="x"><left_joint>l</left_joint>
        <right_joint>r</right_joint><wheel_separation>0.5</wheel_separation><wheel_radius>0.1</wheel_radius>
        <max_linear_acceleration>1</max_linear_acceleration><max_linear_velocity>0.8</max_linear_velocity>
        </plugin>""")
    system = DiffDriveSystem(spec)
    system.command(2.0, 0.0)
    speeds = [system.wheel_speeds(0.1)["l"] for _ in range(12)]
    assert speeds[0] == pytest.approx(1.0)  # 1 m/s² for 0.1 s = 0.1 m/s = 1 rad/s at r = 0.1
    assert speeds[-1] == pytest.approx(8.0)  # capped at 0.8 m/s
    with pytest.raises(ValueError, match="non-finite"):
        system.command(math.nan, 0.0)
    # a quarter turn on the spot: each wheel rolls π/2 · 0.25 m (half the separation) the other way
    system.integrate(0.0, 0.0, 0.0)
    roll = math.pi / 2 * 0.25 / 0.1
    pose = system.integrate(-roll, roll, 1.0)
    assert (pose.x, pose.y, pose.yaw, pose.w) == pytest.approx((0.0, 0.0, math.pi / 2, math.pi / 2))


def run_plugin(sim: Simulation, index: int, v: float, seconds: float) -> tuple[float, float]:
    """Drive plugin ``index`` at ``v`` m/s as the simulator does (an update each period); its odometry x, y."""
    spec = sim.diff_drives[index]
    system = DiffDriveSystem(spec)
    system.command(v, 0.0)
    period = 1.0 / spec.update_rate_hz
    pose = None
    end = sim.time_s + seconds
    while sim.time_s < end - 1e-9:
        sim.set_wheel_velocities(system.wheel_speeds(period))
        left, right = sim.joint_positions((spec.left_joints[0], spec.right_joints[0]))
        pose = system.integrate(left, right, period)
        sim.advance(int(round(period / sim.step_s)))
    assert pose is not None
    return pose.x, pose.y


def test_the_vehicle_drives_the_commanded_distance() -> None:
    spec, world = load_world(BUILT, model_paths(BUILT))
    sim = Simulation(spec, parse_urdf(process_xacro()), world=world)
    start = sim.planar_state("vehicle::chassis")
    x, y = run_plugin(sim, 0, 0.5, 4.0)
    # 0.5 s to reach 0.5 m/s at 1 m/s², then 3.5 s at it: 0.125 + 1.75 m, along the model's +y (yaw 90°)
    expected = 0.125 + 1.75
    end = sim.planar_state("vehicle::chassis")
    assert end[1] - start[1] == pytest.approx(expected, rel=0.05)
    assert abs(end[0] - start[0]) < 0.05
    assert x == pytest.approx(expected, rel=0.05) and abs(y) < 0.05


@pytest.mark.parametrize("gazebo", ["ignition", "classic"])
def test_ppp_bot_driven_by_its_gazebo_plugin(gazebo: str) -> None:
    path = find_world("empty")
    robot = parse_urdf(process_xacro(mappings={"use_ros2_control": "false", "gazebo": gazebo}))
    sim = Simulation(load_world(path, model_paths(path))[0], robot, SpawnPose())
    (spec,) = sim.diff_drives
    assert sim.handles.wheel_joints == ["left_wheel_joint", "right_wheel_joint"]
    x, _ = run_plugin(sim, 0, 0.4, 5.0)
    truth = sim.ground_truth().position[0]
    # ignition: 1 m/s² to 0.4 m/s (0.08 m), then 4.6 s; classic: 10 m/s² at the wheels (0.008 m), then 4.96 s
    expected = 0.08 + 0.4 * 4.6 if gazebo == "ignition" else 0.008 + 0.4 * 4.96
    assert truth == pytest.approx(expected, rel=0.03)
    assert x == pytest.approx(truth, abs=0.02)
