"""ScanOdometry: scans held until odometry reaches their stamps, and what a bad scan does.

The node's subscription callbacks are called directly (the messages a DDS subscription
would hand them), so these tests need no other process.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from geometry_msgs.msg import TransformStamped
from rclpy.time import Time
from sensor_msgs.msg import LaserScan
from tf2_msgs.msg import TFMessage

from pppbot_lockstep.ros.runner import Warnings
from pppbot_lockstep.ros.scan_odometry import ScanOdometry


def transform(parent: str, child: str, t_s: float, x: float) -> TransformStamped:
    msg = TransformStamped()
    msg.header.frame_id, msg.child_frame_id = parent, child
    msg.header.stamp = Time(seconds=t_s).to_msg()
    msg.transform.translation.x = x
    msg.transform.rotation.w = 1.0
    return msg


def scan(t_s: float) -> LaserScan:
    msg = LaserScan()
    msg.header.frame_id = "lidar_frame"
    msg.header.stamp = Time(seconds=t_s).to_msg()
    msg.angle_min, msg.angle_max, msg.angle_increment = -math.pi, math.pi, 2 * math.pi / 8
    msg.ranges = [1.0] * 8
    return msg


def callback(node: Any, topic: str) -> Any:
    return next(s.callback for s in node.subscriptions if s.topic_name == topic)


@pytest.fixture
def tf_of(ros_node: Any) -> Any:
    def make(ready: Any) -> tuple[ScanOdometry, Any]:
        scans = ScanOdometry(ros_node, "odom", "base_link", ready, Warnings(ros_node))
        callback(ros_node, "/tf_static")(TFMessage(transforms=[transform("base_link", "lidar_frame", 0.0, 0.05)]))
        return scans, callback(ros_node, "/tf")
    return make


def test_a_scan_waits_for_odometry_and_gets_the_pose_at_its_stamp(tf_of: Any) -> None:
    got: list[tuple[float, np.ndarray, np.ndarray]] = []
    scans, on_tf = tf_of(lambda msg, t, frame, odom, sensor: got.append((t, odom, sensor)))
    on_tf(TFMessage(transforms=[transform("odom", "base_link", 1.0, 0.0)]))
    scans.add(scan(1.5))
    assert got == []  # odometry has not reached 1.5 s yet
    on_tf(TFMessage(transforms=[transform("odom", "base_link", 2.0, 1.0)]))
    assert len(got) == 1
    t, odom, sensor = got[0]
    assert t == pytest.approx(1.5)
    assert odom == pytest.approx([0.5, 0.0, 0.0])  # interpolated at the scan's stamp
    assert sensor == pytest.approx([0.05, 0.0, 0.0])


def test_a_scan_the_owner_fails_on_after_waiting_is_dropped_and_the_next_goes_on(tf_of: Any) -> None:
    """Scans that waited are handed on from the /tf callback: an error there drops that scan
    (with a warning) instead of ending the node, and later scans still get through."""
    got: list[float] = []

    def ready(msg: LaserScan, t: float, *_: Any) -> None:
        if t < 2.0:
            raise RuntimeError("a scan the owner cannot take")
        got.append(t)

    scans, on_tf = tf_of(ready)
    on_tf(TFMessage(transforms=[transform("odom", "base_link", 1.0, 0.0)]))
    scans.add(scan(1.5))
    on_tf(TFMessage(transforms=[transform("odom", "base_link", 2.0, 1.0)]))  # must not raise
    scans.add(scan(2.5))
    on_tf(TFMessage(transforms=[transform("odom", "base_link", 3.0, 2.0)]))
    assert got == [pytest.approx(2.5)]
