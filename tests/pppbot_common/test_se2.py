"""Planar pose helpers."""
from __future__ import annotations

import math

import pytest
from scipy.spatial.transform import Rotation

from pppbot_common.se2 import finite_pose, quaternion_from_yaw, wrap_angle, yaw_from_quaternion


@pytest.mark.parametrize("yaw", [0.0, 0.7, -2.5, math.pi, 3.0])
def test_yaw_round_trips_and_matches_scipy(yaw):
    q = quaternion_from_yaw(yaw)
    assert Rotation.from_quat(q).approx_equal(Rotation.from_euler("z", yaw))
    assert wrap_angle(yaw_from_quaternion(*q) - yaw) == pytest.approx(0.0, abs=1e-12)


def test_yaw_of_a_tilted_quaternion_is_its_heading():
    x, y, z, w = Rotation.from_euler("xyz", [0.2, -0.1, 1.2]).as_quat()
    assert yaw_from_quaternion(x, y, z, w) == pytest.approx(1.2)


def test_finite_pose_gives_an_array_or_the_callers_error_naming_what_and_the_value():
    assert finite_pose((1, 2.5, -0.5), "pose").tolist() == [1.0, 2.5, -0.5]

    class AmclLikeError(Exception):
        pass

    for bad in [(0.0, math.nan, 0.0), (0.0, 0.0), (0.0, 0.0, 0.0, 0.0), "abc", None, (0.0, math.inf, 0.0)]:
        with pytest.raises(AmclLikeError, match=r"^an odometry pose must be three finite numbers \(x, y, yaw\), not "):
            finite_pose(bad, "an odometry pose", AmclLikeError)
    with pytest.raises(ValueError, match=r"not \(1, 2\)$"):
        finite_pose((1, 2), "pose")
