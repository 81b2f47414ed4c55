"""Messages → planar values: stamps in seconds, TF transforms as (parent, child, stamp, x, y, yaw)."""
from __future__ import annotations

from collections.abc import Iterator
from typing import NamedTuple

from builtin_interfaces.msg import Time
from tf2_msgs.msg import TFMessage

from pppbot_common.se2 import yaw_from_quaternion


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
