"""robot_state_publisher over DDS: latched description, /tf_static, /tf from /joint_states,
bad input, and republishing when the parameter changes."""
from __future__ import annotations

import itertools
import math
from pathlib import Path

import pytest
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage

from pppbot_common.ros.qos import LATCHED
from pppbot_common.ros.wait import wait_for_messages, wait_until
from pppbot_description.ros.robot_state_publisher import TF_STATIC_QOS

pytestmark = pytest.mark.ros
PPPBOT = str(Path(__file__).resolve().parents[2] / "pppbot")
TOY_URDF = ('<robot name="toy"><link name="base_link"/><link name="flag"/>'
            '<joint name="flag_joint" type="fixed"><parent link="base_link"/><child link="flag"/>'
            '<origin xyz="0 0 1"/></joint></robot>')


@pytest.fixture
def rsp(spawn):
    child = spawn([PPPBOT, "run", "pppbot_description", "robot_state_publisher", "--ros-args",
                   "-p", "publish_frequency:=50"], name="rsp")
    child.wait_for_output(r"robot 'ppp_bot' from .*: 10 links, 7 fixed and 2 moving joints", 30)
    return child


def test_description_is_latched_for_late_subscribers(ros_node, rsp):
    (msg,) = wait_for_messages(ros_node, String, "/robot_description", qos=LATCHED, timeout_s=10)
    assert msg.data.lstrip().startswith("<?xml") and '<robot name="ppp_bot">' in msg.data


def test_static_transforms_once_with_ppp_bot_offsets(ros_node, rsp):
    (msg,) = wait_for_messages(ros_node, TFMessage, "/tf_static", qos=TF_STATIC_QOS, timeout_s=10)
    by_child = {t.child_frame_id: t for t in msg.transforms}
    assert set(by_child) == {"base_footprint", "chassis", "caster_wheel", "lidar_frame", "camera_link",
                             "camera_link_optical", "imu_link"}
    lidar = by_child["lidar_frame"]
    assert lidar.header.frame_id == "chassis"
    v = lidar.transform.translation
    assert (v.x, v.y, v.z) == pytest.approx((0.15, 0.0, 0.15))


def publish_joint_states(node, names, positions, sec):
    pub = node.create_publisher(JointState, "/joint_states", 10)
    wait_until(lambda: pub.get_subscription_count() > 0, 10, "robot_state_publisher's subscription")
    msg = JointState(name=names, position=positions)
    msg.header.stamp.sec = sec
    return pub, msg


def wheel_transforms(node, pub, msg):
    """The first /tf for ``msg``, publishing it until one arrives.

    Discovery can drop the first messages, and the node rate-limits by message time, so
    each retry is one second later: ``msg``'s stamp ends as the last one sent.
    """
    received: list[TFMessage] = []
    sub = node.create_subscription(TFMessage, "/tf", received.append, 10)
    wait_until(lambda: sub.get_publisher_count() > 0, 10, "the /tf subscription to match", node=node)

    def publish_again():
        if received:
            return True
        pub.publish(msg)
        msg.header.stamp.sec += 1
        return False

    wait_until(publish_again, 10, "/tf", node=node)
    msg.header.stamp.sec -= 1
    node.destroy_subscription(sub)
    return received[0]


def test_wheel_transform_follows_joint_state(ros_node, rsp):
    pub, msg = publish_joint_states(ros_node, ["left_wheel_joint", "right_wheel_joint"], [math.pi / 2, 0.0], 42)
    tf = wheel_transforms(ros_node, pub, msg)
    by_child = {t.child_frame_id: t for t in tf.transforms}
    left = by_child["left_wheel"]
    assert left.header.frame_id == "base_link"
    assert 42 <= left.header.stamp.sec <= msg.header.stamp.sec
    q = left.transform.rotation
    expected = Rotation.from_euler("xyz", [-math.pi / 2, 0, 0]) * Rotation.from_rotvec([0, 0, math.pi / 2])
    assert Rotation.from_quat([q.x, q.y, q.z, q.w]).approx_equal(expected, atol=1e-9)
    assert left.transform.translation.y == pytest.approx(0.175)


def test_unknown_and_non_finite_joints_are_ignored_with_a_warning(ros_node, rsp):
    pub, msg = publish_joint_states(ros_node, ["ghost_joint", "left_wheel_joint", "right_wheel_joint"],
                                    [1.0, math.nan, 0.5], 7)
    tf = wheel_transforms(ros_node, pub, msg)
    assert [t.child_frame_id for t in tf.transforms] == ["right_wheel"]
    rsp.wait_for_output(r"ignoring unknown joint\(s\) ghost_joint", 10)
    rsp.wait_for_output(r"ignoring non-finite position\(s\) of left_wheel_joint", 10)
    # Mismatched lengths are dropped, and the node lives on.
    pub.publish(JointState(name=["left_wheel_joint"], position=[]))
    rsp.wait_for_output(r"dropping a JointState with 1 names but 0 positions", 10)
    assert rsp.running()


def set_parameters(node, params):
    client = node.create_client(SetParameters, "/robot_state_publisher/set_parameters")
    assert client.wait_for_service(timeout_sec=10)
    future = client.call_async(SetParameters.Request(parameters=[p.to_parameter_msg() for p in params]))
    return wait_until(lambda: future.result() if future.done() else None, 10, "set_parameters", node=node).results


def test_changing_robot_description_republishes(ros_node, rsp):
    (result,) = set_parameters(ros_node, [Parameter("robot_description", value=TOY_URDF)])
    assert result.successful, result.reason
    msgs = wait_for_messages(ros_node, String, "/robot_description", qos=LATCHED, timeout_s=10,
                             predicate=lambda m: 'name="toy"' in m.data)
    assert msgs[0].data == TOY_URDF
    (static,) = wait_for_messages(ros_node, TFMessage, "/tf_static", qos=TF_STATIC_QOS, timeout_s=10,
                                  predicate=lambda m: len(m.transforms) == 1)
    assert static.transforms[0].child_frame_id == "flag"


def test_invalid_updates_are_refused_with_the_reason(ros_node, rsp):
    (bad_urdf,) = set_parameters(ros_node, [Parameter("robot_description", value="<robot><link></robot>")])
    assert not bad_urdf.successful and "malformed XML" in bad_urdf.reason
    (bad_rate,) = set_parameters(ros_node, [Parameter("publish_frequency", value=-1.0)])
    assert not bad_rate.successful and "'publish_frequency' = -1.0" in bad_rate.reason
    # Still the ppp_bot description.
    (msg,) = wait_for_messages(ros_node, String, "/robot_description", qos=LATCHED, timeout_s=10)
    assert '<robot name="ppp_bot">' in msg.data


def test_echo_reads_the_latched_description(rsp):
    import subprocess

    result = subprocess.run([PPPBOT, "topic", "echo", "/robot_description", "--once", "--field", "data"],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert '<robot name="ppp_bot">' in result.stdout


def test_bad_parameter_at_start_stops_the_node(spawn):
    child = spawn([PPPBOT, "run", "pppbot_description", "robot_state_publisher", "--ros-args",
                   "-p", "frame_prefix:=has space"], name="rsp-bad")
    assert child.wait(30) == 1
    assert "parameter 'frame_prefix' = 'has space': must not contain white space" in child.output


def test_rate_limit_by_message_time(ros_node, spawn):
    """At 1 Hz, a second message 0.5 s later (message time) is not published; 1 s later is."""
    child = spawn([PPPBOT, "run", "pppbot_description", "robot_state_publisher", "--ros-args",
                   "-p", "publish_frequency:=1.0"], name="rsp-1hz")
    child.wait_for_output("10 links", 30)
    pub, msg = publish_joint_states(ros_node, ["left_wheel_joint"], [0.0], 100)
    wheel_transforms(ros_node, pub, msg)  # the first message, at t0 = 100 s (or a retry's later t0), is published
    t0 = msg.header.stamp.sec
    sub_msgs: list[TFMessage] = []
    sub = ros_node.create_subscription(TFMessage, "/tf", sub_msgs.append, QoSProfile(depth=50))

    def joint_state(sec: int, nsec: int = 0) -> None:
        m = JointState(name=["left_wheel_joint"], position=[0.1])
        m.header.stamp.sec, m.header.stamp.nanosec = sec, nsec
        pub.publish(m)

    def stamps() -> list[tuple[int, int]]:
        return [(x.transforms[0].header.stamp.sec, x.transforms[0].header.stamp.nanosec) for x in sub_msgs]

    # A new subscription misses what is published before discovery matches it, on both sides:
    # a whole second later each time (every one published) until one comes through.
    sent: list[int] = []
    seconds = itertools.count(t0 + 1)
    def send_and_look() -> bool:
        sent.append(next(seconds))
        joint_state(sent[-1])
        return bool(stamps())

    wait_until(send_and_look, 20, "the /tf subscription to match", node=ros_node)
    t1 = sent[-1]  # the last one published: the next within a second must not be
    for sec, nsec in ((t1, 500_000_000), (t1 + 1, 0)):
        joint_state(sec, nsec)
    wait_until(lambda: (t1 + 1, 0) in stamps(), 10, "the t1 + 1 s /tf", node=ros_node)
    assert (t1, 500_000_000) not in stamps()
    ros_node.destroy_subscription(sub)
