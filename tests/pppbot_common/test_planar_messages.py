"""Planar values ↔ TF messages: transform_message is what planar_transforms reads back."""
from __future__ import annotations

import math

import pytest
from builtin_interfaces.msg import Time
from tf2_msgs.msg import TFMessage

from pppbot_common.ros.planar import planar_transforms, transform_message


@pytest.mark.parametrize("pose", [(1.5, -2.0, 0.3), (0.0, 0.0, math.pi), (-4.25, 7.0, -2.9)])
def test_transform_message_round_trips_through_planar_transforms(pose):
    msg = transform_message("map", "odom", Time(sec=12, nanosec=500_000_000), pose)
    assert (msg.header.frame_id, msg.child_frame_id) == ("map", "odom")
    assert msg.transform.translation.z == 0.0 and msg.transform.rotation.x == msg.transform.rotation.y == 0.0
    (back,) = planar_transforms(TFMessage(transforms=[msg]))
    assert (back.parent, back.child, back.stamp_s) == ("map", "odom", 12.5)
    assert (back.x, back.y) == pytest.approx(pose[:2])
    assert math.remainder(back.yaw - pose[2], 2 * math.pi) == pytest.approx(0.0, abs=1e-12)
