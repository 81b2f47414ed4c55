"""Camera tags and image math without OpenGL: topics, frames, intrinsics, formats, noise, depth, points."""
from __future__ import annotations

import math

import numpy as np
import pytest
from lxml import etree

from pppbot_description.urdf_model import Sensor, parse_urdf
from pppbot_description.xacro_model import process_xacro
from pppbot_sim.camera_model import lumped_link
from pppbot_sim.camera_worker import OPTICAL_IN_SENSOR, frame_rng, points_in_frame
from pppbot_sim.cameras import (
    POINT_STEP,
    CameraKind,
    CameraSpec,
    PixelFormat,
    apply_image_noise,
    depth_from_zbuffer,
    depth_gray,
    encode,
    finalize_depth,
    info_topic_of,
    optical_points,
    point_cloud_data,
    ray_lengths,
)
from pppbot_sim.errors import SpawnError

LINKS = {"base_link", "camera_link", "camera_link_optical", "depth_link"}
ZERO_POSE = (0.0,) * 6


def tag(body: str, kind: str = "camera", link: str = "camera_link", name: str = "cam") -> Sensor:
    element = etree.fromstring(f'<sensor name="{name}" type="{kind}">{body}</sensor>')
    return Sensor(name, kind, link, element)


def spec_of(body: str, kind: str = "camera", link: str = "camera_link") -> CameraSpec:
    spec, _ = CameraSpec.from_tag(tag(body, kind, link), robot_links=LINKS, pose=ZERO_POSE,
                                  default_topic_prefix="/world/w/model/m/link/base_link/sensor/cam")
    return spec


def ppp_bot_camera() -> CameraSpec:
    robot = parse_urdf(process_xacro())
    (camera,) = robot.sensors_of_type("camera")
    spec, notes = CameraSpec.from_tag(camera, robot_links=set(robot.links), pose=ZERO_POSE,
                                      default_topic_prefix="/unused")
    assert notes == []
    return spec


def test_ppp_bots_camera_as_gazebo_and_its_bridge_publish_it() -> None:
    spec = ppp_bot_camera()
    assert (spec.kind, spec.topic, spec.info_topic, spec.points_topic) == (
        CameraKind.COLOR, "camera/image_raw", "camera/camera_info", "")
    assert (spec.frame_id, spec.width, spec.height, spec.rate_hz) == ("camera_link_optical", 640, 480, 10.0)
    assert (spec.pixel_format.encoding, spec.near_m, spec.far_m) == ("rgb8", 0.05, 8.0)
    fx = 640 / (2 * math.tan(1.089 / 2))
    assert spec.k_matrix() == pytest.approx([fx, 0, 320, 0, fx, 240, 0, 0, 1])
    assert spec.p_matrix() == pytest.approx([fx, 0, 320, 0, 0, fx, 240, 0, 0, 0, 1, 0])
    # the vertical field of view MuJoCo's camera gets keeps the pixels square
    assert math.tan(math.radians(spec.fovy_deg) / 2) * 640 / 480 == pytest.approx(math.tan(1.089 / 2))


def test_ppp_bots_optical_frame_is_a_urdf_joint_robot_state_publisher_publishes() -> None:
    robot = parse_urdf(process_xacro())
    joint = robot.joints["camera_optical_joint"]
    assert (joint.parent, joint.child) == ("camera_link", "camera_link_optical")
    assert joint.origin.rpy == pytest.approx((-math.pi / 2, 0.0, -math.pi / 2))
    # rotating the sensor's axes (x forward, z up) by the joint gives the optical axes
    from pppbot_description.kinematics import rpy_matrix
    np.testing.assert_allclose(rpy_matrix(*joint.origin.rpy), OPTICAL_IN_SENSOR, atol=1e-12)
    assert lumped_link(robot, "camera_link") == "base_link"  # Gazebo's link for default topic names


def test_ppp_bots_depth_camera_xacro() -> None:
    robot = parse_urdf(process_xacro(mappings={"use_depth_camera": "true"}))
    assert [s.type for s in robot.sensors if s.link == "camera_link"] == ["depth"]
    (tag_,) = robot.sensors_of_type("depth")
    spec, _ = CameraSpec.from_tag(tag_, robot_links=set(robot.links), pose=ZERO_POSE, default_topic_prefix="/x")
    assert (spec.kind, spec.topic, spec.info_topic, spec.points_topic, spec.frame_id) == (
        CameraKind.DEPTH, "camera/depth/image_raw", "camera/depth/camera_info", "camera/depth/image_raw/points",
        "camera_link_optical")
    assert spec.pixel_format.encoding == "32FC1" and spec.render_near_m == pytest.approx(0.01)


@pytest.mark.parametrize(("kind", "last"), [("camera", "image"), ("depth", "depth_image"),
                                            ("depth_camera", "depth_image")])
def test_without_a_topic_gazebos_scoped_default(kind: str, last: str) -> None:
    spec = spec_of("<camera><image><width>4</width><height>2</height></image></camera>", kind)
    scoped = "/world/w/model/m/link/base_link/sensor/cam"
    assert (spec.topic, spec.info_topic) == (f"{scoped}/{last}", f"{scoped}/camera_info")


@pytest.mark.parametrize(("topic", "info"), [("camera/image_raw", "camera/camera_info"), ("/camera", "/camera_info"),
                                             ("camera", "camera_info"), ("/a/b/c/", "/a/b/camera_info")])
def test_camera_info_beside_the_image_as_gazebo_advertises_it(topic: str, info: str) -> None:
    assert info_topic_of(topic) == info


@pytest.mark.parametrize(("body", "link", "frame"), [
    ("<gz_frame_id>my_frame</gz_frame_id>", "camera_link", "my_frame"),
    ("<ignition_frame_id>ign</ignition_frame_id>", "camera_link", "ign"),
    ("<plugin name='p' filename='libgazebo_ros_camera.so'><frame_name>classic</frame_name></plugin>",
     "camera_link", "classic"),
    ("", "camera_link", "camera_link_optical"),  # the robot has <link>_optical
    ("", "depth_link", "depth_link"),  # it has not
])
def test_frame_id(body: str, link: str, frame: str) -> None:
    assert spec_of(body, link=link).frame_id == frame


@pytest.mark.parametrize(("name", "encoding"), [("R8G8B8", "rgb8"), ("B8G8R8", "bgr8"), ("L8", "mono8"),
                                                ("L_INT16", "mono16"), ("RGBA_INT8", "rgba8"),
                                                ("BAYER_RGGB8", "bayer_rggb8")])
def test_image_formats(name: str, encoding: str) -> None:
    spec = spec_of(f"<camera><image><format>{name}</format></image></camera>")
    assert spec.pixel_format.encoding == encoding


@pytest.mark.parametrize(("body", "named"), [
    ("<camera><image><format>YUV</format></image></camera>", "image format 'YUV'"),
    ("<camera><image><width>0</width></image></camera>", "image 0 x 240"),
    ("<camera><horizontal_fov>3.2</horizontal_fov></camera>", "horizontal_fov 3.2"),
    ("<camera><clip><near>2</near><far>1</far></clip></camera>", "clip 2.0..1.0"),
    ("<update_rate>-1</update_rate>", "update_rate -1.0"),
    ("<camera><noise><type>gaussian</type><stddev>-0.1</stddev></noise></camera>", "noise stddev -0.1"),
])
def test_bad_values_are_named(body: str, named: str) -> None:
    with pytest.raises(SpawnError, match="camera 'cam' on link 'camera_link'") as raised:
        spec_of(body)
    assert named in str(raised.value)


def test_distortion_noise_and_what_is_not_simulated() -> None:
    spec, notes = CameraSpec.from_tag(tag(
        "<camera><distortion><k1>-0.25</k1><k2>0.12</k2><k3>0.01</k3><p1>-0.0003</p1><p2>0.0005</p2></distortion>"
        "<noise><type>gaussian</type><mean>0.01</mean><stddev>0.007</stddev></noise>"
        "<lens><type>stereographic</type></lens></camera>"),
        robot_links=LINKS, pose=ZERO_POSE, default_topic_prefix="/x")
    assert spec.distortion == (-0.25, 0.12, -0.0003, 0.0005, 0.01)  # plumb_bob's k1 k2 p1 p2 k3
    assert (spec.noise_mean, spec.noise_stddev) == (0.01, 0.007)
    assert len(notes) == 1 and "<lens> is not simulated" in notes[0]


def test_depth_clip_from_depth_camera_element() -> None:
    spec = spec_of("<camera><clip><near>0.1</near><far>100</far></clip>"
                   "<depth_camera><clip><near>0.3</near><far>9</far></clip></depth_camera></camera>", "depth")
    assert (spec.near_m, spec.far_m) == (0.3, 9.0)


# ------------------------------------------------------------------------------------- pixels
def test_encodings() -> None:
    rgb = np.array([[[10, 20, 30], [200, 100, 50]], [[0, 255, 0], [1, 2, 3]]], dtype=np.uint8)
    np.testing.assert_array_equal(encode(rgb, PixelFormat("bgr8", 3))[0, 0], [30, 20, 10])
    assert encode(rgb, PixelFormat("mono8", 1))[1, 0, 0] == round(0.587 * 255)
    assert encode(rgb, PixelFormat("mono16", 2)).dtype == np.uint16
    np.testing.assert_array_equal(encode(rgb, PixelFormat("rgba8", 4))[0, 1], [200, 100, 50, 255])
    bayer = encode(rgb, PixelFormat("bayer_rggb8", 1))[:, :, 0]
    np.testing.assert_array_equal(bayer, [[10, 100], [255, 3]])  # R G / G B


def test_image_noise_is_gazebos_and_reproducible() -> None:
    grey = np.full((400, 500, 3), 128, dtype=np.uint8)
    noisy = apply_image_noise(grey, 0.01, 0.05, frame_rng(7, 0, 1.5, 10.0)).astype(float) - 128
    # one sample per pixel, the same on every channel
    np.testing.assert_array_equal(noisy[:, :, 0], noisy[:, :, 2])
    assert noisy[:, :, 0].mean() == pytest.approx(0.01 * 255, abs=0.1)
    assert noisy[:, :, 0].std() == pytest.approx(0.05 * 255, rel=0.02)
    again = apply_image_noise(grey, 0.01, 0.05, frame_rng(7, 0, 1.5, 10.0)).astype(float) - 128
    other = apply_image_noise(grey, 0.01, 0.05, frame_rng(7, 0, 1.6, 10.0)).astype(float) - 128
    np.testing.assert_array_equal(noisy, again)
    assert not np.array_equal(noisy, other)
    # clamped at full scale
    assert apply_image_noise(np.full((50, 50, 3), 250, np.uint8), 0.0, 0.2, frame_rng(0, 0, 0, 1)).max() == 255
    assert apply_image_noise(grey, 0.0, 0.0, frame_rng(0, 0, 0, 1)) is grey


# -------------------------------------------------------------------------------------- depth
def reversed_z(depth: np.ndarray, near: float, far: float) -> np.ndarray:
    """What OpenGL writes into a reversed-Z depth buffer for a metric depth (the forward mapping)."""
    return (near * (far - depth) / (depth * (far - near))).astype(np.float32)


def test_depth_from_mujocos_reversed_z_buffer() -> None:
    depth = np.array([[0.01, 0.5, 2.7], [7.9, 30.0, 90.0]])
    np.testing.assert_allclose(depth_from_zbuffer(reversed_z(depth, 0.01, 100.0), 0.01, 100.0), depth, rtol=1e-4)
    assert depth_from_zbuffer(np.zeros((1, 1), np.float32), 0.01, 8.0)[0, 0] == np.inf  # nothing drawn


def test_depth_rep118_with_gazebos_range_rule() -> None:
    width, height, hfov = 9, 5, 1.2
    rays = ray_lengths(width, height, hfov)
    assert rays[2, 4] == 1.0 and rays[0, 0] > rays[0, 4] > 1.0
    far = 5.0
    depth = np.full((height, width), 4.5)
    depth[2, 2] = 0.2
    out = finalize_depth(depth, rays, near_m=0.5, far_m=far)
    assert out.dtype == np.float32 and out[2, 2] == -np.inf
    assert out[2, 4] == pytest.approx(4.5)
    assert out[0, 0] == np.inf  # its depth 4.5 m is within 5 m, its range is not
    assert (np.isfinite(out) == (depth * rays <= far) & (depth >= 0.5)).all()
    at_far = finalize_depth(np.full((height, width), far), rays, 0.5, far)  # drawn on the far plane
    assert (at_far == np.inf).all()
    assert (finalize_depth(np.full((height, width), np.inf), rays, 0.5, far) == np.inf).all()  # nothing drawn


def test_depth_noise_is_seeded() -> None:
    rays = np.ones((300, 300))
    a = finalize_depth(np.full((300, 300), 2.0), rays, 0.1, 8.0, noise_stddev=0.01, rng=frame_rng(3, 1, 0.2, 5.0))
    b = finalize_depth(np.full((300, 300), 2.0), rays, 0.1, 8.0, noise_stddev=0.01, rng=frame_rng(3, 1, 0.2, 5.0))
    np.testing.assert_array_equal(a, b)
    assert float(a.std()) == pytest.approx(0.01, rel=0.03) and float(a.mean()) == pytest.approx(2.0, abs=1e-3)


def test_points_project_back_to_their_pixels() -> None:
    width, height, hfov = 64, 48, 1.089
    depth = np.linspace(1.0, 3.0, width * height, dtype=np.float32).reshape(height, width)
    depth[0, 0], depth[0, 1] = np.inf, -np.inf
    points = optical_points(depth, hfov)
    f = width / (2 * math.tan(hfov / 2))
    v, u = 30, 17
    x, y, z = points[v, u]
    assert z == depth[v, u]
    assert (f * x / z + (width - 1) / 2, f * y / z + (height - 1) / 2) == pytest.approx((u, v), abs=1e-4)
    assert (points[0, 0] == np.inf).all() and (points[0, 1] == -np.inf).all()


def test_point_cloud_layout_is_gazebos() -> None:
    points = np.arange(2 * 3 * 3, dtype=np.float32).reshape(2, 3, 3)
    depth = np.array([[1.0, 2.0, np.inf], [4.0, -np.inf, 2.0]], dtype=np.float32)
    data, dense = point_cloud_data(points, depth_gray(depth))
    assert len(data) == 6 * POINT_STEP and dense
    dtype = np.dtype({"names": ["x", "y", "z", "rgb"], "formats": ["<f4", "<f4", "<f4", "<u4"],
                      "offsets": [0, 4, 8, 16], "itemsize": POINT_STEP})
    cloud = data.view(dtype)
    np.testing.assert_array_equal(cloud["y"], points.reshape(-1, 3)[:, 1])
    grey = cloud["rgb"] & 0xFF
    assert list(grey) == [191, 127, 0, 0, 0, 127]  # 255 - 255 d / 4, truncated; not finite: 0
    assert (cloud["rgb"] == grey * 0x010101).all()
    assert not point_cloud_data(np.full((1, 1, 3), np.inf, np.float32), np.zeros((1, 1), np.uint8))[1]


def test_points_moved_into_a_frame_keep_their_infinities() -> None:
    points = np.array([[[0.5, -0.25, 2.0], [np.inf, np.inf, np.inf]]], dtype=np.float32)
    # a frame with the sensor's axes (x forward): what the optical frame is in it
    moved = points_in_frame(points, OPTICAL_IN_SENSOR, np.array([0.1, 0.0, 0.0]))
    np.testing.assert_allclose(moved[0, 0], [2.1, -0.5, 0.25])
    assert (moved[0, 1] == np.inf).all()
    assert points_in_frame(points, np.eye(3), np.zeros(3)) is points
