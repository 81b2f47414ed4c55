"""Joint transforms: origins, rotation about the axis, prismatic shifts, mimic, skipping."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pppbot_description.kinematics import KinematicTree, joint_transform
from pppbot_description.urdf_model import parse_urdf
from pppbot_description.xacro_model import process_xacro

PPP_BOT = parse_urdf(process_xacro())


def test_left_wheel_transform_at_zero_is_its_origin():
    t = joint_transform(PPP_BOT.joints["left_wheel_joint"], 0.0)
    assert (t.parent, t.child, t.translation) == ("base_link", "left_wheel", (0.0, 0.175, 0.0))
    np.testing.assert_allclose(t.rotation, Rotation.from_euler("xyz", [-math.pi / 2, 0, 0]).as_quat())


def test_a_quarter_turn_of_the_left_wheel():
    t = joint_transform(PPP_BOT.joints["left_wheel_joint"], math.pi / 2)
    expected = Rotation.from_euler("xyz", [-math.pi / 2, 0, 0]) * Rotation.from_rotvec([0, 0, math.pi / 2])
    assert Rotation.from_quat(t.rotation).approx_equal(expected)
    # A point on the wheel's rim at +x of the wheel frame moves to -z of base_link (rolls forward).
    rim = Rotation.from_quat(t.rotation).apply([0.05, 0, 0])
    np.testing.assert_allclose(rim, [0, 0, -0.05], atol=1e-12)


def test_frame_prefix_applies_to_both_frames():
    t = joint_transform(PPP_BOT.joints["laser_joint"], 0.0, frame_prefix="r1/")
    assert (t.parent, t.child) == ("r1/chassis", "r1/lidar_frame")


TOY = parse_urdf("""
<robot name="toy">
  <link name="base"/><link name="slider"/><link name="a"/><link name="b"/>
  <joint name="slide" type="prismatic"><parent link="base"/><child link="slider"/>
    <origin xyz="1 0 0" rpy="0 0 1.5707963267948966"/><axis xyz="1 0 0"/>
    <limit lower="0" upper="1" effort="1" velocity="1"/></joint>
  <joint name="drive" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="follow" type="revolute"><parent link="base"/><child link="b"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/><mimic joint="drive" multiplier="-2" offset="0.1"/></joint>
</robot>""")


def test_prismatic_moves_along_the_rotated_axis():
    t = joint_transform(TOY.joints["slide"], 0.5)
    np.testing.assert_allclose(t.translation, [1.0, 0.5, 0.0], atol=1e-12)


def test_mimic_follows_its_joint():
    tree = KinematicTree(TOY)
    by_child = {t.child: t for t in tree.moving_transforms({"drive": 0.3})}
    assert set(by_child) == {"a", "b"}
    angle_b = Rotation.from_quat(by_child["b"].rotation).as_rotvec()[2]
    assert angle_b == pytest.approx(-2 * 0.3 + 0.1)


def test_non_finite_and_unknown_positions_are_skipped():
    tree = KinematicTree(PPP_BOT)
    out = tree.moving_transforms({"left_wheel_joint": math.nan, "right_wheel_joint": 1.0, "ghost": 2.0})
    assert [t.child for t in out] == ["right_wheel"]
    assert tree.unknown_names(["ghost", "left_wheel_joint", "laser_joint"]) == ["ghost"]


def test_fixed_transforms_cover_every_fixed_joint():
    fixed = KinematicTree(PPP_BOT).fixed_transforms()
    assert {t.child for t in fixed} == {"base_footprint", "chassis", "caster_wheel", "lidar_frame",
                                        "camera_link", "camera_link_optical", "imu_link"}
    lidar = next(t for t in fixed if t.child == "lidar_frame")
    assert (lidar.parent, lidar.translation, lidar.rotation) == ("chassis", (0.15, 0.0, 0.15), (0.0, 0.0, 0.0, 1.0))
