"""Real 2D laser logs in CARMEN's text format, read, given odometry, and written as rosbag2 bags.

The "corrected" CARMEN logs of Radish (the Intel Research Lab, ACES, MIT CSAIL, ...) hold
``FLASER n r1 … rn x y theta odom_x odom_y odom_theta timestamp host logger_timestamp`` lines:
a 180° front laser (n beams from −90° to +90°, metres; 80 m and more is "no return") and the
robot pose a reference SLAM solution estimated for it (the ground truth), repeated in the
odometry fields. There is no raw odometry, so :func:`synthesize_odometry` makes it, with AMCL's
odometry noise model and a seed.

:func:`write_bag` turns a log into what a robot would have recorded: ``/scan``
(``sensor_msgs/LaserScan`` in ``laser_frame``, the log's angles and ranges, no return as
+inf), ``/odom`` (``nav_msgs/Odometry``, ``odom`` → ``base_frame``) and ``/tf`` (the same
transform) at every scan's stamp, ``/tf_static`` (``base_frame`` → ``laser_frame``: the
logs' laser pose is the robot's), on the log's own clock (``./pppbot bag play --clock``
publishes it as sim time). So the ``slam`` node maps a real log as slam_toolbox users map a
bag. No ROS here (messages are serialized with rosbags).
"""
from __future__ import annotations

import gzip
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.typesys import Stores, get_typestore

from pppbot_bag.definitions import type_definition
from pppbot_bag.errors import BagError
from pppbot_bag.metadata import qos
from pppbot_bag.writer import BagWriter
from pppbot_common.se2 import quaternion_from_yaw, wrap_angles

#: A reading at or beyond this (m) is the laser's "no return".
NO_RETURN_M = 80.0
#: Logs whose stamps cannot tell their duration (CSAIL's are written to 10 000 s): Hess et al.,
#: "Real-Time Loop Closure in 2D LIDAR SLAM", ICRA 2016, Table II.
KNOWN_DURATIONS_S = {"csail": 424.0}
ORIGINALS = ("the public originals: Radish (radish.sourceforge.net) and the Freiburg SLAM benchmark "
             "(ais.informatik.uni-freiburg.de/slamevaluation), the 'corrected' CARMEN logs")


class CarmenError(BagError, ValueError):
    """A missing or malformed log; the message names the file and line."""


@dataclass(frozen=True)
class CarmenLog:
    name: str
    stamps_s: np.ndarray  # (N,)
    ranges_m: np.ndarray  # (N, B); +inf where the laser got no return
    poses: np.ndarray  # (N, 3) corrected (x, y, yaw)
    angle_min_rad: float
    angle_increment_rad: float

    def head(self, count: int) -> CarmenLog:
        """The log's first ``count`` scans."""
        return CarmenLog(self.name, self.stamps_s[:count], self.ranges_m[:count], self.poses[:count],
                         self.angle_min_rad, self.angle_increment_rad)

    @property
    def duration_s(self) -> float:
        """How long the log ran: its stamps' span, or, where they were written with too few digits
        to tell, the duration published for it (NaN when there is none)."""
        if len(self.stamps_s) > 1 and np.median(np.diff(self.stamps_s)) > 0:
            return float(self.stamps_s[-1] - self.stamps_s[0])
        return KNOWN_DURATIONS_S.get(self.name, math.nan)

    def clock_s(self) -> np.ndarray:
        """Increasing stamps (s) for the scans: the log's, or, where they cannot tell the scans apart,
        evenly spread over :attr:`duration_s` from the first (one second apart without one)."""
        if len(self.stamps_s) < 2 or np.all(np.diff(self.stamps_s) > 0):
            return self.stamps_s.copy()
        span = self.duration_s if math.isfinite(self.duration_s) else float(len(self.stamps_s) - 1)
        return float(self.stamps_s[0]) + np.linspace(0.0, span, len(self.stamps_s))


def read_carmen(path: Path) -> CarmenLog:
    """The ``FLASER`` records of a (gzipped) CARMEN log.

    Raises:
        CarmenError: the file is missing or a ``FLASER`` line is malformed (file and line named).
    """
    if not path.is_file():
        raise CarmenError(f"{path}: no such log; {ORIGINALS}")
    stamps: list[float] = []
    scans: list[list[float]] = []
    poses: list[tuple[float, float, float]] = []
    opener = gzip.open if path.suffix == ".gz" else open
    try:
        with opener(path, "rt") as lines:
            for number, line in enumerate(lines, 1):
                fields = line.split()
                if not fields or fields[0] != "FLASER":
                    continue
                try:
                    count = int(fields[1])
                    ranges = [float(v) for v in fields[2:2 + count]]
                    x, y, yaw = (float(v) for v in fields[2 + count:5 + count])
                    stamp = float(fields[8 + count])
                except (ValueError, IndexError) as exc:
                    raise CarmenError(f"{path}:{number}: malformed FLASER record ({exc})") from None
                if len(ranges) != count or (scans and count != len(scans[0])):
                    raise CarmenError(f"{path}:{number}: FLASER has {len(ranges)} of {count} readings "
                                      f"(earlier scans had {len(scans[0]) if scans else count})")
                stamps.append(stamp)
                scans.append(ranges)
                poses.append((x, y, yaw))
    except (OSError, EOFError, UnicodeDecodeError) as exc:
        raise CarmenError(f"{path}: not a readable CARMEN log ({exc})") from exc
    if not scans:
        raise CarmenError(f"{path}: no FLASER records")
    ranges_m = np.array(scans)
    ranges_m[ranges_m >= NO_RETURN_M] = np.inf
    beams = ranges_m.shape[1]
    # 181 or 361 beams span −90°..+90° inclusive; 180 or 360 stop one beam short of +90°
    increment = math.pi / (beams - 1) if beams % 2 else math.pi / beams
    return CarmenLog(path.name.split(".")[0], np.array(stamps), ranges_m, np.array(poses), -math.pi / 2, increment)


def synthesize_odometry(poses: np.ndarray, alphas: tuple[float, float, float, float],
                        rng: np.random.Generator) -> np.ndarray:
    """Odometry poses (N, 3) from reference poses: each step's (rot1, trans, rot2) with noise of
    AMCL's odometry model (α1 rot from rot, α2 rot from trans, α3 trans from trans, α4 trans from rot),
    starting at the first reference pose."""
    a1, a2, a3, a4 = alphas
    odom = [poses[0].copy()]
    for previous, current in zip(poses[:-1], poses[1:], strict=True):
        dx, dy = current[0] - previous[0], current[1] - previous[1]
        trans = math.hypot(dx, dy)
        rot1 = float(wrap_angles(math.atan2(dy, dx) - previous[2])) if trans > 1e-4 else 0.0
        rot2 = float(wrap_angles(current[2] - previous[2] - rot1))
        # driving backwards is a small turn, not a half turn
        if abs(rot1) > math.pi / 2:
            rot1, trans, rot2 = float(wrap_angles(rot1 + math.pi)), -trans, float(wrap_angles(rot2 + math.pi))
        n_rot1 = rng.normal(0.0, a1 * abs(rot1) + a2 * abs(trans))
        n_trans = rng.normal(0.0, a3 * abs(trans) + a4 * (abs(rot1) + abs(rot2)))
        n_rot2 = rng.normal(0.0, a1 * abs(rot2) + a2 * abs(trans))
        x, y, yaw = odom[-1]
        heading = yaw + rot1 + n_rot1
        step = trans + n_trans
        odom.append(np.array([x + step * math.cos(heading), y + step * math.sin(heading),
                              float(wrap_angles(heading + rot2 + n_rot2))]))
    return np.array(odom)


@dataclass(frozen=True)
class BagFrames:
    """The frames the bag's messages are in (the ``slam`` node's defaults but the laser's)."""

    odom: str = "odom"
    base: str = "base_link"
    laser: str = "laser_frame"


def write_bag(log: CarmenLog, odometry: np.ndarray, output: Path, frames: BagFrames = BagFrames(),
              range_max_m: float = NO_RETURN_M) -> int:
    """Write ``log`` with ``odometry`` (N, 3, in ``frames.odom``) as a rosbag2 MCAP bag at
    ``output``; returns the number of messages.

    Raises:
        BagError: ``output`` exists, or the odometry does not fit the log.
    """
    if odometry.shape != (len(log.ranges_m), 3):
        raise BagError(f"{len(odometry)} odometry poses for {len(log.ranges_m)} scans")
    store = get_typestore(Stores.ROS2_JAZZY)
    types = store.types
    stamps = log.clock_s()
    count = 0
    with BagWriter(output) as writer:
        for topic, type_name, offered in (("/scan", "sensor_msgs/msg/LaserScan", qos()),
                                          ("/odom", "nav_msgs/msg/Odometry", qos()),
                                          ("/tf", "tf2_msgs/msg/TFMessage", qos(depth=100)),
                                          ("/tf_static", "tf2_msgs/msg/TFMessage",
                                           qos(durability="transient_local", depth=1))):
            writer.add_topic(topic, type_definition(type_name), [offered])
        first_ns = int(round(float(stamps[0]) * 1e9))
        tf_static = _tf(types, first_ns, frames.base, frames.laser, np.zeros(3))
        writer.write("/tf_static", bytes(store.serialize_cdr(tf_static, "tf2_msgs/msg/TFMessage")), first_ns)
        count += 1
        beams = log.ranges_m.shape[1]
        for i in range(len(stamps)):
            ns = int(round(float(stamps[i]) * 1e9))
            header = types["std_msgs/msg/Header"](stamp=_time(types, ns), frame_id=frames.laser)
            ranges = np.where(np.isfinite(log.ranges_m[i]), log.ranges_m[i], np.inf).astype(np.float32)
            scan = types["sensor_msgs/msg/LaserScan"](
                header=header, angle_min=log.angle_min_rad,
                angle_max=log.angle_min_rad + (beams - 1) * log.angle_increment_rad,
                angle_increment=log.angle_increment_rad, time_increment=0.0,
                scan_time=float(stamps[i] - stamps[i - 1]) if i else 0.0, range_min=0.0, range_max=range_max_m,
                ranges=ranges, intensities=np.zeros(0, dtype=np.float32))
            pose = odometry[i]
            odom = types["nav_msgs/msg/Odometry"](
                header=types["std_msgs/msg/Header"](stamp=_time(types, ns), frame_id=frames.odom),
                child_frame_id=frames.base,
                pose=types["geometry_msgs/msg/PoseWithCovariance"](
                    pose=types["geometry_msgs/msg/Pose"](
                        position=types["geometry_msgs/msg/Point"](x=float(pose[0]), y=float(pose[1]), z=0.0),
                        orientation=_quaternion(types, float(pose[2]))),
                    covariance=np.zeros(36)),
                twist=types["geometry_msgs/msg/TwistWithCovariance"](
                    twist=types["geometry_msgs/msg/Twist"](
                        linear=types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
                        angular=types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)),
                    covariance=np.zeros(36)))
            # odometry first: a scan finds its transform already there, as on a robot
            transform = _tf(types, ns, frames.odom, frames.base, pose)
            writer.write("/tf", bytes(store.serialize_cdr(transform, "tf2_msgs/msg/TFMessage")), ns)
            writer.write("/odom", bytes(store.serialize_cdr(odom, "nav_msgs/msg/Odometry")), ns)
            writer.write("/scan", bytes(store.serialize_cdr(scan, "sensor_msgs/msg/LaserScan")), ns)
            count += 3
    return count


def _time(types: Mapping[str, Any], ns: int) -> Any:
    sec, nanosec = divmod(ns, 1_000_000_000)
    return types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec)


def _quaternion(types: Mapping[str, Any], yaw: float) -> Any:
    x, y, z, w = quaternion_from_yaw(yaw)
    return types["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w)


def _tf(types: Mapping[str, Any], ns: int, parent: str, child: str, pose: np.ndarray) -> Any:
    transform = types["geometry_msgs/msg/TransformStamped"](
        header=types["std_msgs/msg/Header"](stamp=_time(types, ns), frame_id=parent), child_frame_id=child,
        transform=types["geometry_msgs/msg/Transform"](
            translation=types["geometry_msgs/msg/Vector3"](x=float(pose[0]), y=float(pose[1]), z=0.0),
            rotation=_quaternion(types, float(pose[2]))))
    return types["tf2_msgs/msg/TFMessage"](transforms=[transform])
