"""The expanded URDF: read by yourdfpy (an independent reader) and by pppbot's parser,
with ppp_bot's geometry, frames, inertias, sensors and ros2_control limits."""
from __future__ import annotations

import io
import math

import numpy as np
import pytest
import yourdfpy

from pppbot_description.errors import DescriptionError
from pppbot_description.kinematics import KinematicTree
from pppbot_description.urdf_model import JointType, parse_urdf
from pppbot_description.xacro_model import process_xacro

URDF = process_xacro()
MODEL = parse_urdf(URDF)
EXPECTED_FRAMES = {
    "base_link", "base_footprint", "chassis", "left_wheel", "right_wheel", "caster_wheel",
    "lidar_frame", "camera_link", "camera_link_optical", "imu_link",
}


@pytest.fixture(scope="module")
def independent():
    return yourdfpy.URDF.load(io.StringIO(URDF), build_scene_graph=True, load_meshes=False)


def test_yourdfpy_reads_the_same_tree(independent):
    assert set(independent.link_map) == set(MODEL.links) == EXPECTED_FRAMES
    assert set(independent.joint_map) == set(MODEL.joints)
    assert independent.base_link == MODEL.root == "base_link"
    for name, joint in independent.joint_map.items():
        ours = MODEL.joints[name]
        assert (joint.parent, joint.child, joint.type) == (ours.parent, ours.child, ours.type.value)


def test_link_poses_agree_with_yourdfpy(independent):
    poses = KinematicTree(MODEL).link_poses()
    for link in EXPECTED_FRAMES:
        expected = independent.get_transform(link, "base_link")
        translation, rotation = poses[link]
        np.testing.assert_allclose(translation, expected[:3, 3], atol=1e-9, err_msg=link)
        np.testing.assert_allclose(rotation, expected[:3, :3], atol=1e-9, err_msg=link)


@pytest.mark.parametrize("link, xyz", [
    ("chassis", (-0.1, 0.0, 0.0)),
    ("lidar_frame", (0.05, 0.0, 0.15)),
    ("camera_link", (0.205, 0.0, 0.08)),
    ("caster_wheel", (0.14, 0.0, 0.0)),
    ("left_wheel", (0.0, 0.175, 0.0)),
    ("right_wheel", (0.0, -0.175, 0.0)),
    ("base_footprint", (0.0, 0.0, 0.0)),
])
def test_frames_sit_where_ppp_bot_has_them(link, xyz):
    translation, _ = KinematicTree(MODEL).link_poses()[link]
    np.testing.assert_allclose(translation, xyz, atol=1e-12)


def test_wheel_axes_point_the_same_way_in_base_link():
    """Both wheels spin about +y of base_link for forward motion (ppp_bot's mirrored joints)."""
    poses = KinematicTree(MODEL).link_poses()
    for side in ("left", "right"):
        joint = MODEL.joints[f"{side}_wheel_joint"]
        assert joint.type is JointType.CONTINUOUS
        axis_in_base = poses[f"{side}_wheel"][1] @ joint.axis
        np.testing.assert_allclose(axis_in_base, (0.0, 1.0, 0.0), atol=1e-12)


def test_optical_frame_looks_along_base_x():
    _, rotation = KinematicTree(MODEL).link_poses()["camera_link_optical"]
    np.testing.assert_allclose(rotation @ [0, 0, 1], [1, 0, 0], atol=1e-12)  # z forward
    np.testing.assert_allclose(rotation @ [1, 0, 0], [0, -1, 0], atol=1e-12)  # x right


def test_every_physical_link_has_visual_collision_and_inertial():
    frames_only = {"base_link", "base_footprint", "camera_link_optical"}
    for name, link in MODEL.links.items():
        if name in frames_only:
            assert link.inertial is None and not link.visuals
            continue
        assert link.visuals and link.collisions and link.inertial is not None, name


@pytest.mark.parametrize("name", sorted(n for n, link in MODEL.links.items() if link.inertial is not None))
def test_masses_positive_and_inertias_physical(name):
    inertial = MODEL.links[name].inertial
    assert inertial is not None and inertial.mass > 0
    eig = np.linalg.eigvalsh(np.array(inertial.matrix()))
    assert (eig > 0).all()
    a, b, c = sorted(eig)
    assert a + b >= c - 1e-12  # triangle inequality of principal moments


def test_inertia_macros_follow_the_solid_body_formulas():
    chassis, wheel, caster = (MODEL.links[n].inertial for n in ("chassis", "left_wheel", "caster_wheel"))
    assert chassis is not None and wheel is not None and caster is not None
    m, x, y, z = 0.5, 0.3, 0.3, 0.15
    assert chassis.mass == m
    np.testing.assert_allclose(np.diag(chassis.matrix()), np.array([m * (y*y + z*z) / 12, m * (x*x + z*z) / 12,
                                                                    m * (x*x + y*y) / 12]))
    assert chassis.origin.xyz == (0.15, 0.0, 0.075)
    np.testing.assert_allclose(np.diag(wheel.matrix()),
                               np.array([0.1 * (3 * 0.05**2 + 0.04**2) / 12] * 2 + [0.1 * 0.05**2 / 2]))
    np.testing.assert_allclose(np.diag(caster.matrix()), np.full(3, 0.4 * 0.1 * 0.05**2))


def test_wheel_and_caster_geometry():
    wheel = MODEL.links["left_wheel"].collisions[0].geometry
    assert (wheel.kind, wheel.size) == ("cylinder", (0.05, 0.04))
    caster = MODEL.links["caster_wheel"].collisions[0].geometry
    assert (caster.kind, caster.size) == ("sphere", (0.05,))
    assert MODEL.gazebo_settings["caster_wheel"]["mu1"] == "0.001"
    assert MODEL.gazebo_settings["caster_wheel"]["mu2"] == "0.001"


def test_lidar_sensor_tag_is_ppp_bots():
    (lidar,) = MODEL.sensors_of_type("gpu_lidar")
    assert (lidar.name, lidar.link, lidar.topic, lidar.update_rate_hz) == ("laser", "lidar_frame", "scan", 10.0)
    f = lidar.find_float
    assert f("lidar/scan/horizontal/samples", 0) == 640
    assert (f("lidar/scan/horizontal/min_angle", 0), f("lidar/scan/horizontal/max_angle", 0)) == (-3.14, 3.14)
    assert (f("lidar/range/min", 0), f("lidar/range/max", 0), f("lidar/range/resolution", 0)) == (0.08, 20.0, 0.01)
    assert lidar.find_text("lidar/noise/type") == "gaussian"


def test_camera_and_imu_tags():
    (camera,) = MODEL.sensors_of_type("camera")
    assert camera.frame_id == "camera_link_optical"
    assert camera.find_float("camera/horizontal_fov", 0) == 1.089
    assert (camera.find_float("camera/image/width", 0), camera.find_float("camera/image/height", 0)) == (640, 480)
    (imu,) = MODEL.sensors_of_type("imu")
    assert imu.update_rate_hz == 100 and imu.topic == "imu"
    assert imu.find_float("imu/angular_velocity/z/noise/stddev", 0) == 2e-4


def test_ros2_control_block_declares_wheel_interfaces():
    assert set(MODEL.control_joints) == {"left_wheel_joint", "right_wheel_joint"}
    for joint in MODEL.control_joints.values():
        assert joint.command_interfaces == {"velocity": (-10.0, 10.0)}
        assert set(joint.state_interfaces) == {"position", "velocity"}


# --------------------------------------------------------------- malformed URDFs
BASE = '<link name="a"/><link name="b"/>'


@pytest.mark.parametrize("body, message", [
    (BASE + '<joint name="j" type="fixed"><parent link="a"/><child link="c"/></joint>',
     "joint 'j' refers to unknown link 'c'"),
    (BASE, "one root; roots found: a, b"),
    (BASE + '<joint name="j" type="hinge"><parent link="a"/><child link="b"/></joint>',
     "joint 'j' has type 'hinge'"),
    (BASE + '<joint name="j" type="fixed"><parent link="a"/><child link="b"/>'
            '<origin xyz="0 zero 0"/></joint>', "xyz='0 zero 0'>: not numbers"),
    ('<link name="a"><collision><geometry><cone/></geometry></collision></link>', "unknown geometry <cone>"),
    ('<link name="a"/><link name="a"/>', "link 'a' is defined twice"),
])
def test_malformed_urdf_is_named(body, message):
    with pytest.raises(DescriptionError, match=message):
        parse_urdf(f'<robot name="r">{body}</robot>', "t.urdf")


def test_xml_error_carries_the_line():
    with pytest.raises(DescriptionError, match=r"^t\.urdf:3: malformed XML"):
        parse_urdf('<robot name="r">\n<link name="a">\n</robot>', "t.urdf")


def test_cycle_is_rejected():
    body = ('<link name="a"/><link name="b"/><link name="c"/>'
            '<joint name="j1" type="fixed"><parent link="b"/><child link="c"/></joint>'
            '<joint name="j2" type="fixed"><parent link="c"/><child link="b"/></joint>')
    with pytest.raises(DescriptionError, match="cycle|one root"):
        parse_urdf(f'<robot name="r">{body}</robot>')


def test_continuous_joints_have_velocity_but_no_position_limits():
    joint = MODEL.joints["left_wheel_joint"]
    assert math.isinf(joint.lower) and math.isinf(joint.upper)
    assert joint.velocity_limit == 10.0
