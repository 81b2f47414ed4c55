"""Messages ↔ planar values: stamps in seconds, TF transforms as (parent, child, stamp, x, y, yaw)."""
from __future__ import annotations

from collections.abc import Iterator
from typing import NamedTuple

from builtin_interfaces.msg import Time
from geometry_msgs.msg import TransformStamped
from tf2_msgs.msg import TFMessage

from pppbot_common.se2 import PoseLike, quaternion_from_yaw, yaw_from_quaternion


class PlanarTransform(NamedTuple):
    parent: str
    child: str
    stamp_s: float
    x: float
    y: float
    yaw: float


def stamp_seconds(stamp: Time) -> float:
    return float(stamp.sec) + stamp.nanosec * 1e-9


def planar_transforms(msg: TFMessage) -> Iterator[PlanarTransform]:
    """Each transform of a TF message in the plane (frame names without a leading '/')."""
    for t in msg.transforms:
        tr, q = t.transform.translation, t.transform.rotation
        yield PlanarTransform(t.header.frame_id.lstrip("/"), t.child_frame_id.lstrip("/"),
                              stamp_seconds(t.header.stamp), tr.x, tr.y, yaw_from_quaternion(q.x, q.y, q.z, q.w))


def transform_message(parent: str, child: str, stamp: Time, pose: PoseLike) -> TransformStamped:
    """``child`` at the planar ``pose`` (x, y, yaw) in ``parent``: the message
    :func:`planar_transforms` reads back."""
    t = TransformStamped()
    t.header.stamp, t.header.frame_id, t.child_frame_id = stamp, parent, child
    t.transform.translation.x, t.transform.translation.y = float(pose[0]), float(pose[1])
    r = t.transform.rotation
    r.x, r.y, r.z, r.w = quaternion_from_yaw(float(pose[2]))
    return t
