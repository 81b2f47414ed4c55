"""``/tf`` and ``/tf_static`` into a planar transform buffer: tf2_ros's TransformListener for pppbot's nodes."""
from __future__ import annotations

from typing import Any, Callable

from rclpy.node import Node
from tf2_msgs.msg import TFMessage

from pppbot_common.ros.lockstep import in_step, require, require_match
from pppbot_common.ros.node_main import Warnings, guarded
from pppbot_common.ros.planar import planar_transforms
from pppbot_common.ros.qos import LATCHED
from pppbot_common.transforms import TransformBuffer


class TfListener:
    """Keeps ``buffer`` (``cache_s`` seconds of history) filled; ``on_tf`` is called after each
    dynamic TF message (in lockstep, at the next step). A malformed transform is dropped with a
    throttled warning, and so is any error ``on_tf`` raises (it hands on scans that waited for
    odometry: one bad scan must not end the node). ``needs_static``: in lockstep the node's
    process joins only once ``/tf_static`` has delivered (a scan's user needs the sensor's
    mounting from the start).

    The nodes of a process run by :func:`pppbot_common.ros.node_main.run_nodes` (composed: a
    server, its costmap, the navigator) share one buffer and one pair of subscriptions: each
    TF message is taken and parsed once, not once per node."""

    def __init__(self, node: Node, warn: Warnings, cache_s: float = 10.0,
                 on_tf: Callable[[], None] | None = None, needs_static: bool = False) -> None:
        shared = _Subscriptions.of(node, warn, cache_s) if _Subscriptions.sharing else _Subscriptions(node, warn, cache_s)
        self.buffer = shared.buffer
        if on_tf is not None:
            shared.on_tf.append((warn, lambda: in_step(node, on_tf)))
        if needs_static and not shared.static_arrived:
            shared.on_static.append(require(node, "the static transforms (/tf_static)"))


def share_in_process(on: bool) -> None:
    """From now on (``on``) the listeners of this process share one buffer and its subscriptions,
    made on the first node that listens; ``off`` forgets them (the nodes are going)."""
    _Subscriptions.sharing = on
    _Subscriptions.shared = None


class _Subscriptions:
    """/tf and /tf_static subscriptions and the buffer they fill."""

    sharing = False
    shared: _Subscriptions | None = None

    def __init__(self, node: Node, warn: Warnings, cache_s: float) -> None:
        self.buffer = TransformBuffer(cache_s=cache_s)
        self.on_tf: list[tuple[Warnings, Callable[[], Any]]] = []
        self.on_static: list[Callable[[], None]] = []
        self.static_arrived = False
        self._warn = warn
        require_match(node, node.create_subscription(TFMessage, "/tf", guarded(node, self._dynamic, "TFMessage"), 200))
        node.create_subscription(TFMessage, "/tf_static", guarded(node, self._static, "TFMessage"), LATCHED)

    @classmethod
    def of(cls, node: Node, warn: Warnings, cache_s: float) -> _Subscriptions:
        """The process's subscriptions, made on ``node`` if it is the first to listen."""
        if cls.shared is None:
            cls.shared = cls(node, warn, cache_s)
        cls.shared.buffer.cache_s = max(cls.shared.buffer.cache_s, cache_s)
        return cls.shared

    def _store(self, msg: TFMessage, static: bool) -> None:
        for t in planar_transforms(msg):
            try:
                self.buffer.set_transform(t.parent, t.child, t.stamp_s, (t.x, t.y, t.yaw), static)
            except ValueError as exc:
                self._warn("tf", f"ignoring a transform: {exc}")

    def _dynamic(self, msg: TFMessage) -> None:
        self._store(msg, static=False)
        for warn, call in self.on_tf:  # each node's own: one's error must not starve the others
            try:
                call()
            except Exception as exc:
                warn("on_tf", f"after a TFMessage: {type(exc).__name__}: {exc}")

    def _static(self, msg: TFMessage) -> None:
        self._store(msg, static=True)
        self.static_arrived = True
        for arrived in self.on_static:
            arrived()
        self.on_static.clear()
