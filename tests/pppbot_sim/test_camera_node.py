"""The simulator's cameras over DDS: ppp_bot's camera (Image + CameraInfo at its 10 Hz in sim time, in
its optical frame, which robot_state_publisher puts on /tf_static), its depth camera (depth image and
points), and a machine without a working OpenGL backend (cameras off, the rest runs)."""
from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest
from rclpy.qos import DurabilityPolicy, QoSProfile
from sensor_msgs.msg import CameraInfo, Image, LaserScan, PointCloud2, PointField
from tf2_msgs.msg import TFMessage

from pppbot_common.ros.wait import wait_for_messages, wait_until
from pppbot_description.kinematics import rpy_quaternion
from pppbot_description.xacro_model import process_xacro

pytestmark = pytest.mark.ros
PPPBOT = str(Path(__file__).resolve().parents[2] / "pppbot")
BOX_ROOM = str(Path(__file__).parent / "data" / "box_room.sdf")


def start_simulator(spawn, *params: str, env: dict[str, str] | None = None, ready: str = r"camera 'camera'"):
    args = [PPPBOT, "run", "pppbot_sim", "simulator", "--ros-args", "-p", f"world:={BOX_ROOM}"]
    for p in params:
        args += ["-p", p]
    child = spawn(args, name="simulator", env=env)
    child.wait_for_output(ready, 30)
    return child


class Collector:
    """Every message of some topics, from subscriptions made before the first one comes."""

    def __init__(self, node, topics: dict[str, type]) -> None:
        self.node = node
        self.messages: dict[str, list] = {topic: [] for topic in topics}
        for topic, kind in topics.items():
            node.create_subscription(kind, topic, self.messages[topic].append, 10)

    def until(self, counts: dict[str, int], timeout_s: float = 30.0) -> dict[str, list]:
        wait_until(lambda: all(len(self.messages[t]) >= n for t, n in counts.items()), timeout_s,
                   f"{counts} messages", node=self.node)
        return self.messages


def stamp_s(msg) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def test_ppp_bots_camera_publishes_image_and_info_at_its_rate_in_sim_time(opengl, ros_node, spawn) -> None:
    start_simulator(spawn, "real_time_factor:=1.0")
    spawn([PPPBOT, "run", "pppbot_description", "robot_state_publisher", "--ros-args", "-p", "use_sim_time:=true"],
          name="robot_state_publisher")
    got = Collector(ros_node, {"/camera/image_raw": Image, "/camera/camera_info": CameraInfo}).until(
        {"/camera/image_raw": 6, "/camera/camera_info": 6})
    images, infos = got["/camera/image_raw"], got["/camera/camera_info"]
    image = images[-1]
    assert (image.encoding, image.width, image.height, image.step, len(image.data)) == (
        "rgb8", 640, 480, 1920, 640 * 480 * 3)
    assert {m.header.frame_id for m in images + infos} == {"camera_link_optical"}
    pixels = np.frombuffer(bytes(image.data), np.uint8)
    assert pixels.max() > 50  # the box room's walls are in view
    # stamped with the sim time of the state each shows: on the 10 Hz grid, one period apart
    stamps = [stamp_s(m) for m in images]
    assert all(abs(t * 10 - round(t * 10)) < 1e-6 for t in stamps)
    steps = np.round(np.diff(stamps) * 10).astype(int)
    assert (steps >= 1).all() and np.median(steps) == 1
    info_stamps = sorted(stamp_s(m) for m in infos)  # an info with every image (the subscriptions
    assert {t for t in stamps if info_stamps[0] <= t <= info_stamps[-1]} <= set(info_stamps)  # match apart)
    info = infos[-1]
    fx = 640 / (2 * math.tan(1.089 / 2))
    assert (info.width, info.height, info.distortion_model) == (640, 480, "plumb_bob")
    assert list(info.k) == pytest.approx([fx, 0, 320, 0, fx, 240, 0, 0, 1])
    assert list(info.d) == [0.0] * 5 and list(info.r) == [1, 0, 0, 0, 1, 0, 0, 0, 1]
    latched = QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    (static,) = wait_for_messages(ros_node, TFMessage, "/tf_static", qos=latched, timeout_s=20)
    (optical,) = [t for t in static.transforms if t.child_frame_id == "camera_link_optical"]
    assert optical.header.frame_id == "camera_link"
    q = optical.transform.rotation
    w, x, y, z = rpy_quaternion(-math.pi / 2, 0.0, -math.pi / 2)
    assert abs(abs(np.dot([q.w, q.x, q.y, q.z], [w, x, y, z])) - 1) < 1e-9


def test_ppp_bots_depth_camera_publishes_depth_and_points(opengl, ros_node, spawn, tmp_path: Path) -> None:
    urdf = tmp_path / "ppp_bot_depth.urdf"
    urdf.write_text(process_xacro(mappings={"use_depth_camera": "true"}))
    start_simulator(spawn, "real_time_factor:=1.0", f"robot_description:={urdf}", ready=r"depth 'depth_camera'")
    collector = Collector(ros_node, {"/camera/depth/image_raw": Image, "/camera/depth/camera_info": CameraInfo,
                                     "/camera/depth/image_raw/points": PointCloud2})
    got = collector.until({"/camera/depth/camera_info": 2})

    def a_frame():
        """A frame's depth image and its points (the subscriptions match at different times)."""
        return next(((d, c) for c in got["/camera/depth/image_raw/points"] for d in got["/camera/depth/image_raw"]
                     if stamp_s(d) == stamp_s(c)), None)

    depth_msg, cloud = wait_until(a_frame, 30, "a depth image and its points", node=ros_node)
    assert (depth_msg.encoding, depth_msg.width, depth_msg.height, depth_msg.step) == ("32FC1", 640, 480, 2560)
    depth = np.frombuffer(bytes(depth_msg.data), np.float32).reshape(480, 640)
    # ppp_bot stands in the middle of the box room: the east wall's face is 2 m ahead of base_link, the
    # camera 0.205 m ahead of base_link
    assert depth[240, 320] == pytest.approx(2.0 - 0.205, abs=0.01)
    assert (cloud.width, cloud.height, cloud.point_step, cloud.row_step, cloud.header.frame_id) == (
        640, 480, 24, 640 * 24, "camera_link_optical")
    assert [(f.name, f.offset, f.datatype, f.count) for f in cloud.fields] == [
        ("x", 0, PointField.FLOAT32, 1), ("y", 4, PointField.FLOAT32, 1), ("z", 8, PointField.FLOAT32, 1),
        ("rgb", 16, PointField.FLOAT32, 1)]
    points = np.frombuffer(bytes(cloud.data), np.float32).reshape(480, 640, 6)
    centre = points[240, 320, :3]
    assert centre[2] == depth[240, 320] and abs(centre[0]) < 0.01


@pytest.mark.parametrize("environment", [{"MUJOCO_GL": "bogus"}, {"MUJOCO_GL": "egl", "MUJOCO_EGL_DEVICE_ID": "99"}],
                         ids=["unknown-backend", "no-egl-device"])
def test_without_opengl_the_cameras_turn_off_and_the_rest_runs(ros_node, spawn, environment) -> None:
    """An unknown backend is known at the start; a backend that cannot make a context, when the
    first frame is wanted."""
    sim = start_simulator(spawn, "real_time_factor:=2.0", env={**os.environ, **environment},
                          ready=r"camera 'camera'|cameras off:")
    ros_node.create_subscription(Image, "/camera/image_raw", lambda msg: None, 10)
    wait_until(lambda: "cameras off:" in sim.output, 30, "the cameras-off line", node=ros_node)
    assert sim.output.count("cameras off:") == 1
    scans = wait_for_messages(ros_node, LaserScan, "/scan", count=5, timeout_s=20)
    assert len(scans) == 5 and sim.running()


def test_cameras_false_has_no_camera_topics(ros_node, spawn) -> None:
    start_simulator(spawn, "cameras:=false", ready=r"cameras off \(cameras:=false\): camera")
    wait_for_messages(ros_node, LaserScan, "/scan", count=1, timeout_s=20)
    assert ros_node.count_publishers("/camera/image_raw") == 0
