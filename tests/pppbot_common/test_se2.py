"""Planar pose helpers."""
from __future__ import annotations

import math

import pytest
from scipy.spatial.transform import Rotation

from pppbot_common.se2 import quaternion_from_yaw, wrap_angle, yaw_from_quaternion


@pytest.mark.parametrize("yaw", [0.0, 0.7, -2.5, math.pi, 3.0])
def test_yaw_round_trips_and_matches_scipy(yaw):
    q = quaternion_from_yaw(yaw)
    assert Rotation.from_quat(q).approx_equal(Rotation.from_euler("z", yaw))
    assert wrap_angle(yaw_from_quaternion(*q) - yaw) == pytest.approx(0.0, abs=1e-12)


def test_yaw_of_a_tilted_quaternion_is_its_heading():
    x, y, z, w = Rotation.from_euler("xyz", [0.2, -0.1, 1.2]).as_quat()
    assert yaw_from_quaternion(x, y, z, w) == pytest.approx(1.2)
