"""Scans paired with odometry at their stamps: what tf2's message filter does for slam_toolbox and AMCL.

A :class:`ScanOdometry` listens to ``/tf`` and ``/tf_static`` into a planar
:class:`~pppbot_common.transforms.TransformBuffer` and holds each scan until the
``odom_frame → base_frame`` transform reaches its stamp. Then it hands the scan on with
the base's pose in the odometry frame at that stamp and the lidar's mounting in the base
frame. A scan that cannot be transformed is dropped with a throttled warning naming the
frames.
"""
from __future__ import annotations

from collections import deque
from collections.abc import Callable

import numpy as np
from rclpy.node import Node
from sensor_msgs.msg import LaserScan

from pppbot_common.ros.planar import stamp_seconds
from pppbot_common.transforms import TransformError
from pppbot_lockstep.ros.runner import Warnings
from pppbot_lockstep.ros.tf_listener import TfListener

#: Scans wait for odometry to reach their stamps for at most this much scan time (s): the
#: oldest is dropped once a pending scan is this much newer. While a node is busy, /tf
#: (100+ messages a second) backs up far more than /scan, and the executor takes one
#: message of each per turn, so scans arrive well ahead of their odometry for a while.
MAX_PENDING_S = 10.0

#: ``ready(scan, stamp_s, scan_frame, odom_pose, sensor_pose)``: poses are (x, y, yaw) arrays.
Ready = Callable[[LaserScan, float, str, np.ndarray, np.ndarray], None]


class ScanOdometry:
    def __init__(self, node: Node, odom_frame: str, base_frame: str, ready: Ready, warn: Warnings,
                 cache_s: float = 10.0) -> None:
        self.odom_frame, self.base_frame = odom_frame, base_frame  # the owner may change them
        self._ready = ready
        self._warn = warn
        self._pending: deque[LaserScan] = deque()
        self.tf = TfListener(node, warn, cache_s, on_tf=self._on_tf, needs_static=True).buffer

    def add(self, msg: LaserScan) -> None:
        """Queue the scan until odometry reaches its stamp."""
        self._pending.append(msg)
        self._drain()

    def _on_tf(self) -> None:
        if self._pending:
            self._drain()

    def _drain(self) -> None:
        odom, base = self.odom_frame, self.base_frame
        while self._pending:
            msg = self._pending[0]
            stamp = stamp_seconds(msg.header.stamp)
            frame = msg.header.frame_id.lstrip("/")
            try:
                newest = self.tf.latest_time(odom, base)
            except TransformError:
                newest = None
            waited_s = stamp_seconds(self._pending[-1].header.stamp) - stamp
            if (newest is None or newest < stamp) and waited_s <= MAX_PENDING_S:
                # Odometry has not reached this scan yet. Waiting is bounded by the scans'
                # own stamps, not by the clock: while the node is busy, /clock and /tf queue
                # up alike, and the clock would say "late" for transforms already queued.
                return
            self._pending.popleft()
            try:
                odom_pose = np.array(self.tf.lookup(odom, base, stamp))
                sensor = np.array(self.tf.lookup(base, frame))
            except TransformError as exc:
                self._warn("transform", f"dropping a scan: no transform {odom} → {base} → {frame} "
                                        f"at t = {stamp:.3f} s ({exc})")
                continue
            self._warn.settled("transform")
            self._ready(msg, stamp, frame, odom_pose, sensor)
