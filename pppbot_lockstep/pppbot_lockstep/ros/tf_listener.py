"""``/tf`` and ``/tf_static`` into a planar transform buffer: tf2_ros's TransformListener for pppbot's nodes.

One listener per process: composed nodes (the planner's and the controller's costmaps and the
navigator in ``navigation``) share one buffer and one pair of subscriptions, as Nav2's servers
use their costmap's buffer, instead of each taking every ``/tf`` message.
"""
from __future__ import annotations

import functools
import math
import weakref
from collections.abc import Callable
from typing import Any

from rclpy.node import Node
from tf2_msgs.msg import TFMessage

from pppbot_common.ros.planar import planar_transforms
from pppbot_common.ros.qos import LATCHED
from pppbot_common.transforms import TransformBuffer
from pppbot_lockstep.ros.node import port_of, subscribe
from pppbot_lockstep.ros.runner import Warnings, guarded


class TfListener:
    """Keeps ``buffer`` (at least ``cache_s`` seconds of history) filled; ``on_tf`` is called after
    each dynamic TF message (in lockstep, at the next step). A malformed transform is dropped with a
    throttled warning, and so is any error ``on_tf`` raises (it hands on scans that waited for
    odometry: one bad scan must not end the node). ``needs_static``: in lockstep the node's process
    joins only once ``/tf_static`` has delivered (a scan's user needs the sensor's mounting from
    the start). ``quiet``: ``on_tf`` sends nothing (it files what the node's timers read); while
    every listening node's is, the process's ``/tf`` subscription is quiet, and what others send on
    ``/tf`` needs no round of its own (:meth:`StepNode.create_subscription`). Listeners of nodes in
    one process share one buffer (:class:`_Shared`)."""

    def __init__(self, node: Node, warn: Warnings, cache_s: float = 10.0,
                 on_tf: Callable[[], None] | None = None, needs_static: bool = False, quiet: bool = False) -> None:
        if not (math.isfinite(cache_s) and cache_s > 0):  # checked here too: a later listener only widens
            raise ValueError(f"cache_s must be a positive number of seconds, not {cache_s}")
        shared = _SHARED.get(node.context)
        if shared is None or not shared.alive():
            shared = _SHARED[node.context] = _Shared(node, warn, cache_s)  # as long as the context lives
        shared.buffer.cache_s = max(shared.buffer.cache_s, cache_s)
        shared.add(node, on_tf, port_of(node).require("the static transforms (/tf_static)") if needs_static else None,
                   quiet)
        self.buffer = shared.buffer


class _Shared:
    """The process's buffer and subscriptions (made by the first node that listens, ``owner``),
    and what each listening node wants told. The owner is to be destroyed last (composed
    processes destroy their nodes in reverse order of making): once it is gone, the buffer
    no longer fills, and the next listener made starts a new one."""

    def __init__(self, owner: Node, warn: Warnings, cache_s: float) -> None:
        self.buffer = TransformBuffer(cache_s=cache_s)
        self.owner = owner
        self._warn = warn
        self._on_tf: list[tuple[Node, Callable[[], None]]] = []
        self._static_waiting: list[Callable[[], None]] = []
        self._static_seen = False
        self._loud = False  # a node's on_tf sends
        subscribe(owner, TFMessage, "/tf", guarded(owner, self._dynamic, "TFMessage"), 200, data_path=True,
                  quiet=lambda: not self._loud)
        owner.create_subscription(TFMessage, "/tf_static", guarded(owner, self._static, "TFMessage"), LATCHED)

    def alive(self) -> bool:
        """Whether the owner (and so the subscriptions) still exists: a process may make nodes
        again after destroying the first ones (tests do)."""
        return _exists(self.owner)

    def add(self, node: Node, on_tf: Callable[[], None] | None, static_arrived: Callable[[], None] | None,
            quiet: bool = False) -> None:
        if on_tf is not None:  # guarded by its own node: its error is that node's to report, and the others go on
            self._loud |= not quiet
            self._on_tf.append((node, functools.partial(guarded(node, lambda _: on_tf(), "TFMessage"), None)))
        if static_arrived is not None:
            if self._static_seen:
                static_arrived()
            else:
                self._static_waiting.append(static_arrived)

    def _store(self, msg: TFMessage, static: bool) -> None:
        for t in planar_transforms(msg):
            try:
                self.buffer.set_transform(t.parent, t.child, t.stamp_s, (t.x, t.y, t.yaw), static)
            except ValueError as exc:
                self._warn("tf", f"ignoring a transform: {exc}")

    def _dynamic(self, msg: TFMessage) -> None:
        self._store(msg, static=False)
        if not all(_exists(node) for node, _ in self._on_tf):  # a composed node destroyed before the owner
            self._on_tf = [(node, on_tf) for node, on_tf in self._on_tf if _exists(node)]
        for node, on_tf in self._on_tf:
            port_of(node).in_step(on_tf)

    def _static(self, msg: TFMessage) -> None:
        self._store(msg, static=True)
        self._static_seen = True
        waiting, self._static_waiting = self._static_waiting, []
        for arrived in waiting:
            arrived()


def _exists(node: Node) -> bool:
    return bool(node.handle.pointer)


#: Each rclpy context's shared listener (a process's nodes share the default context).
_SHARED: weakref.WeakKeyDictionary[Any, _Shared] = weakref.WeakKeyDictionary()
