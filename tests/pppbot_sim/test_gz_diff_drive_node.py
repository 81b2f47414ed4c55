"""Gazebo's DiffDrive plugins over DDS, as ros_gz_bridge shows them: a world model's vehicle on its
/model/<name>/... topics, and ppp_bot driven by ignition_control.xacro on /cmd_vel, /odom and /tf."""
from __future__ import annotations

import math
from pathlib import Path

import pytest
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from tf2_msgs.msg import TFMessage

from pppbot_common.ros.wait import wait_for_messages, wait_until
from pppbot_description.xacro_model import process_xacro

pytestmark = pytest.mark.ros
PPPBOT = str(Path(__file__).resolve().parents[2] / "pppbot")
BUILT = str(Path(__file__).parent / "data" / "corpus" / "gazebo_built.sdf")


def start(spawn, *params: str):
    args = [PPPBOT, "run", "pppbot_sim", "simulator", "--ros-args", "-p", "real_time_factor:=4.0"]
    for p in params:
        args += ["-p", p]
    child = spawn(args, name="simulator")
    child.wait_for_output(r"DiffDrive plugin of", 30)
    return child


def drive_until(node, topic: str, odom_topic: str, done, timeout_s: float = 20.0) -> Odometry:
    """Publish 0.5 m/s on ``topic`` until an odometry message on ``odom_topic`` satisfies ``done``."""
    pub = node.create_publisher(Twist, topic, 10)
    seen: list[Odometry] = []
    sub = node.create_subscription(Odometry, odom_topic, seen.append, 10)
    twist = Twist()
    twist.linear.x = 0.5

    def check():
        pub.publish(twist)
        return seen[-1] if seen and done(seen[-1]) else None

    try:
        return wait_until(check, timeout_s, f"{odom_topic} past the goal", node=node)
    finally:
        node.destroy_subscription(sub)
        node.destroy_publisher(pub)


def test_world_vehicle_on_its_model_topics(ros_node, spawn) -> None:
    sim = start(spawn, f"world:={BUILT}")
    odom = drive_until(ros_node, "/model/vehicle/cmd_vel", "/model/vehicle/odometry",
                       lambda m: m.pose.pose.position.x > 0.5)
    assert (odom.header.frame_id, odom.child_frame_id) == ("vehicle/odom", "vehicle/chassis")
    assert abs(odom.pose.pose.position.y) < 0.05 and odom.twist.twist.linear.x > 0.3
    (tf,) = wait_for_messages(ros_node, TFMessage, "/model/vehicle/tf", count=1)
    transform = tf.transforms[0]
    assert (transform.header.frame_id, transform.child_frame_id) == ("vehicle/odom", "vehicle/chassis")
    # a command with NaN is dropped with a warning; the plugin and the node go on
    bad = ros_node.create_publisher(Twist, "/model/vehicle/cmd_vel", 10)
    nan = Twist()
    nan.linear.x = math.nan
    wait_until(lambda: bad.publish(nan) or "dropping a command: non-finite" in sim.output, 10, "the warning",
               node=ros_node)
    assert sim.running()


def test_ppp_bot_with_ignition_control_drives_on_cmd_vel(ros_node, spawn, tmp_path: Path) -> None:
    urdf = tmp_path / "ppp_bot.urdf"
    urdf.write_text(process_xacro(mappings={"use_ros2_control": "false"}))
    sim = start(spawn, "world:=empty", f"robot_description:={urdf}")
    odom = drive_until(ros_node, "/cmd_vel", "/odom", lambda m: m.pose.pose.position.x > 0.3)
    assert (odom.header.frame_id, odom.child_frame_id) == ("odom", "base_link")
    tf = wait_until(lambda: next((t for t in wait_for_messages(ros_node, TFMessage, "/tf", count=5)
                                  if t.transforms[0].child_frame_id == "base_link"), None), 10, "odom → base_link",
                    node=ros_node)
    assert tf.transforms[0].header.frame_id == "odom"
    assert "in this process" not in sim.output  # no ros2_control controllers without gz_ros2_control's plugin


def test_robot_plugin_listens_where_the_bringup_remaps_it(ros_node, spawn, tmp_path: Path) -> None:
    urdf = tmp_path / "ppp_bot.urdf"
    urdf.write_text(process_xacro(mappings={"use_ros2_control": "false"}))
    start(spawn, "world:=empty", f"robot_description:={urdf}", "cmd_vel_topic:=/cmd_vel_out")
    odom = drive_until(ros_node, "/cmd_vel_out", "/odom", lambda m: m.pose.pose.position.x > 0.2)
    assert odom.pose.pose.position.x > 0.2
