"""``/tf`` and ``/tf_static`` into a planar transform buffer: tf2_ros's TransformListener for pppbot's nodes."""
from __future__ import annotations

from typing import Callable

from rclpy.node import Node
from tf2_msgs.msg import TFMessage

from pppbot_common.ros.lockstep import in_step, require, require_match
from pppbot_common.ros.node_main import Warnings, guarded
from pppbot_common.ros.planar import planar_transforms
from pppbot_common.ros.qos import LATCHED
from pppbot_common.transforms import TransformBuffer


class TfListener:
    """Keeps ``buffer`` (``cache_s`` seconds of history) filled; ``on_tf`` is called after each
    dynamic TF message (in lockstep, at the next step). A malformed transform is dropped with a throttled warning, and so is
    any error ``on_tf`` raises (it hands on scans that waited for odometry: one bad scan
    must not end the node). ``needs_static``: in lockstep the node's process joins only once
    ``/tf_static`` has delivered (a scan's user needs the sensor's mounting from the start)."""

    def __init__(self, node: Node, warn: Warnings, cache_s: float = 10.0,
                 on_tf: Callable[[], None] | None = None, needs_static: bool = False) -> None:
        self.buffer = TransformBuffer(cache_s=cache_s)
        self._warn = warn
        self._on_tf = on_tf
        self._static_arrived = require(node, "the static transforms (/tf_static)") if needs_static else None
        self._node = node
        require_match(node, node.create_subscription(TFMessage, "/tf", guarded(node, self._dynamic, "TFMessage"), 200))
        node.create_subscription(TFMessage, "/tf_static", guarded(node, self._static, "TFMessage"), LATCHED)

    def _store(self, msg: TFMessage, static: bool) -> None:
        for t in planar_transforms(msg):
            try:
                self.buffer.set_transform(t.parent, t.child, t.stamp_s, (t.x, t.y, t.yaw), static)
            except ValueError as exc:
                self._warn("tf", f"ignoring a transform: {exc}")

    def _dynamic(self, msg: TFMessage) -> None:
        self._store(msg, static=False)
        if self._on_tf is not None:
            in_step(self._node, self._on_tf)

    def _static(self, msg: TFMessage) -> None:
        self._store(msg, static=True)
        if self._static_arrived is not None:
            self._static_arrived()
            self._static_arrived = None
