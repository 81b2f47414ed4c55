"""Message templates: patched bytes equal rclpy's own serialization of the same values."""
from __future__ import annotations

import numpy as np
import pytest
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState, LaserScan

from pppbot_common.ros.wire import MessageTemplate, TemplateError, stamp_fields, stamp_values, vector


def test_odometry_fields_patched_in_place_serialize_as_rclpy_does():
    prototype = Odometry()
    prototype.header.frame_id, prototype.child_frame_id = "odom", "base_link"
    prototype.pose.covariance[0] = 0.001
    fields = [*stamp_fields(), *vector("pose.pose.position"), *vector("pose.pose.orientation", "xyzw"),
              *vector("twist.twist.linear"), *vector("twist.twist.angular")]
    template = MessageTemplate(prototype, fields)
    rng = np.random.default_rng(3)
    for _ in range(20):
        values = {name: float(rng.normal()) for name in fields if not name.startswith("header")}
        values.update(stamp_values(int(rng.integers(0, 10**12))))
        expected = Odometry()
        expected.header.frame_id, expected.child_frame_id = "odom", "base_link"
        expected.pose.covariance[0] = 0.001
        for name, value in values.items():
            owner = expected
            *parents, leaf = name.split(".")
            for part in parents:
                owner = getattr(owner, part)
            setattr(owner, leaf, value)
        assert deserialize_message(template.serialize(values), Odometry) == expected
        assert len(template.serialize(values)) == len(serialize_message(expected))


def test_fixed_length_arrays_and_integers_are_patched():
    scan = LaserScan(ranges=[1.0] * 640, angle_min=-3.14)
    scan.header.frame_id = "lidar_frame"
    template = MessageTemplate(scan, [*stamp_fields(), "ranges"])
    ranges = np.linspace(0.1, 20.0, 640, dtype=np.float32)
    data = template.serialize({"ranges": ranges, **stamp_values(12_345_000_000)})
    back = deserialize_message(data, LaserScan)
    assert np.array_equal(np.asarray(back.ranges, dtype=np.float32), ranges)
    assert (back.header.stamp.sec, back.header.stamp.nanosec) == (12, 345_000_000)
    assert back.header.frame_id == "lidar_frame" and back.angle_min == pytest.approx(-3.14)
    joints = JointState(name=["left", "right"], position=[0.0, 0.0], velocity=[0.0, 0.0], effort=[0.0, 0.0])
    template = MessageTemplate(joints, ["position", "velocity"])
    back = deserialize_message(template.serialize({"position": [1.5, -2.5], "velocity": [0.25, 0.5]}), JointState)
    assert list(back.position) == [1.5, -2.5] and list(back.velocity) == [0.25, 0.5] and back.name == ["left", "right"]
    clock = MessageTemplate(Clock(), stamp_fields("clock"))
    assert deserialize_message(clock.serialize(stamp_values(7, "clock")), Clock).clock.nanosec == 7


def test_transforms_and_step_messages_round_trip_with_their_bools_and_integers():
    from geometry_msgs.msg import TransformStamped
    from tf2_msgs.msg import TFMessage

    from pppbot_interfaces.msg import LockstepAck, LockstepStep

    tf = TFMessage(transforms=[TransformStamped(child_frame_id="base_link")])
    tf.transforms[0].header.frame_id = "odom"
    template = MessageTemplate(tf, [*stamp_fields("transforms.0.header.stamp"), "transforms.0.transform.rotation.w"])
    back = deserialize_message(template.serialize({**stamp_values(3_500_000_000, "transforms.0.header.stamp"),
                                                   "transforms.0.transform.rotation.w": 0.5}), TFMessage)
    assert back.transforms[0].header.stamp.sec == 3 and back.transforms[0].transform.rotation.w == 0.5
    assert back.transforms[0].child_frame_id == "base_link" and back.transforms[0].header.frame_id == "odom"
    step = MessageTemplate(LockstepStep(), ["seq", *stamp_fields("stamp"), "round", "timers"])
    back_step = deserialize_message(step.serialize({"seq": 2**40, "round": 3, "timers": True,
                                                    **stamp_values(7, "stamp")}), LockstepStep)
    assert (back_step.seq, back_step.round, back_step.timers, back_step.stamp.nanosec) == (2**40, 3, True, 7)
    ack = MessageTemplate(LockstepAck(participant="twist_mux", kind=LockstepAck.DONE),
                          ["seq", "sent", "settled", "graph_nodes", *stamp_fields("next_wakeup")])
    back_ack = deserialize_message(ack.serialize({"seq": 9, "sent": True, "settled": False, "graph_nodes": 12,
                                                  **stamp_values(10**9, "next_wakeup")}), LockstepAck)
    assert (back_ack.participant, back_ack.kind, back_ack.seq, back_ack.sent, back_ack.settled, back_ack.graph_nodes,
            back_ack.next_wakeup.sec) == ("twist_mux", LockstepAck.DONE, 9, True, False, 12, 1)


def test_what_cannot_be_patched_is_named():
    with pytest.raises(TemplateError, match="Odometry has no patchable field 'pose.nowhere'"):
        MessageTemplate(Odometry(), ["pose.nowhere"])
    with pytest.raises(TemplateError, match="no patchable field 'child_frame_id'"):
        MessageTemplate(Odometry(), ["child_frame_id"])
    with pytest.raises(TemplateError, match="no patchable field 'ranges'"):  # empty: nothing to patch
        MessageTemplate(LaserScan(), ["ranges"])
    template = MessageTemplate(LaserScan(ranges=[1.0, 2.0]), ["ranges"])
    with pytest.raises(TemplateError, match="'ranges': 3 values for 2"):
        template.serialize({"ranges": [1.0, 2.0, 3.0]})
