"""Recovery behaviours (Nav2's ``behavior_server`` plugins) and their round robin, without ROS.

Each behaviour is started at the robot's pose and then stepped with the current pose and
time; a step returns the velocity to command, (v m/s, ω rad/s), or None when the behaviour
has finished. :class:`Spin` turns by ``spin_dist`` (ramping its speed down near the end, as
Nav2's spin), :class:`BackUp` drives ``backup_dist`` backwards at ``backup_speed``,
:class:`Wait` stands still; each gives up after ``time_allowance_s``. :func:`collision_ahead`
says, from the local costmap, when a behaviour must stop short as Nav2's collision check
would: a spin on a cell within ``robot_radius`` of an obstacle (the footprint circle touches
it), backing up onto such a cell.
:class:`RecoveryRoundRobin` is the default tree's RoundRobin: clear the costmaps, spin, wait,
back up, then again from the start.
"""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field

import numpy as np

from pppbot_common.maps import OccupancyGrid
from pppbot_common.se2 import wrap_angle

Pose = tuple[float, float, float]
Velocity = tuple[float, float]


class Recovery(enum.Enum):
    CLEAR_COSTMAPS = "clear_costmaps"
    SPIN = "spin"
    WAIT = "wait"
    BACKUP = "backup"


@dataclass
class Spin:
    spin_dist_rad: float = 1.57
    max_rotational_vel: float = 1.0
    min_rotational_vel: float = 0.4
    rotational_acc_lim: float = 3.2
    time_allowance_s: float = 10.0
    _turned: float = field(default=0.0, init=False)
    _last_yaw: float = field(default=0.0, init=False)
    _start_s: float = field(default=0.0, init=False)

    def start(self, pose: Pose, now_s: float) -> None:
        self._turned, self._last_yaw, self._start_s = 0.0, pose[2], now_s

    def step(self, pose: Pose, now_s: float) -> Velocity | None:
        self._turned += wrap_angle(pose[2] - self._last_yaw)
        self._last_yaw = pose[2]
        remaining = abs(self.spin_dist_rad) - abs(self._turned)
        if remaining <= 0.0 or now_s - self._start_s > self.time_allowance_s:
            return None
        # Reach zero speed at the target with the acceleration limit: v = sqrt(2·a·remaining).
        speed = min(self.max_rotational_vel, max(self.min_rotational_vel,
                                                 math.sqrt(2.0 * self.rotational_acc_lim * remaining)))
        return 0.0, math.copysign(speed, self.spin_dist_rad)


@dataclass
class BackUp:
    backup_dist_m: float = 0.30
    backup_speed: float = 0.05
    time_allowance_s: float = 10.0
    _start: Pose = field(default=(0.0, 0.0, 0.0), init=False)
    _start_s: float = field(default=0.0, init=False)

    def start(self, pose: Pose, now_s: float) -> None:
        self._start, self._start_s = pose, now_s

    def step(self, pose: Pose, now_s: float) -> Velocity | None:
        travelled = math.hypot(pose[0] - self._start[0], pose[1] - self._start[1])
        if travelled >= self.backup_dist_m or now_s - self._start_s > self.time_allowance_s:
            return None
        return -abs(self.backup_speed), 0.0


@dataclass
class Wait:
    wait_duration_s: float = 5.0
    _start_s: float = field(default=0.0, init=False)

    def start(self, pose: Pose, now_s: float) -> None:
        self._start_s = now_s

    def step(self, pose: Pose, now_s: float) -> Velocity | None:
        return None if now_s - self._start_s >= self.wait_duration_s else (0.0, 0.0)


#: Occupancy values of the published costmap (nav_msgs/OccupancyGrid, 0–100) from which a cell
#: is inscribed (the robot's centre there puts its footprint circle on an obstacle) or lethal.
INSCRIBED_OCCUPANCY = 99
#: How far behind the robot's centre backing up looks (m): about a control period's travel ahead.
BACKUP_LOOK_BEHIND_M = 0.1


def collision_ahead(behavior: Spin | BackUp | Wait, costmap: OccupancyGrid | None, pose: Pose) -> str | None:
    """Why ``behavior`` must stop at ``pose`` (in the costmap's frame), or None to go on.

    A spin is refused on an inscribed or lethal cell: the footprint circle touches an obstacle,
    and the body's corners sweep close to it (Nav2's spin fails there with "Collision Ahead").
    Backing up stops when the cell :data:`BACKUP_LOOK_BEHIND_M` behind the centre is inscribed
    or lethal. Unknown cells, cells off the costmap and a missing costmap are no reason to stop.
    """
    if costmap is None or isinstance(behavior, Wait):
        return None
    x, y, yaw = pose
    where = "at the robot"
    if isinstance(behavior, BackUp):
        x, y = x - BACKUP_LOOK_BEHIND_M * math.cos(yaw), y - BACKUP_LOOK_BEHIND_M * math.sin(yaw)
        where = f"{BACKUP_LOOK_BEHIND_M:g} m behind the robot"
    row, col = (int(i) for i in costmap.cell_of(np.array(x), np.array(y)))
    if not (0 <= row < costmap.height and 0 <= col < costmap.width):
        return None
    value = int(costmap.data[row, col])
    if value < INSCRIBED_OCCUPANCY:
        return None
    kind = "lethal" if value > INSCRIBED_OCCUPANCY else "inscribed"
    return f"collision ahead: the cell {where} ({x:.2f}, {y:.2f}) is {kind} (occupancy {value})"


class RecoveryRoundRobin:
    """The recoveries in turn; ``next()`` gives the one to run and moves on."""

    ORDER = (Recovery.CLEAR_COSTMAPS, Recovery.SPIN, Recovery.WAIT, Recovery.BACKUP)

    def __init__(self) -> None:
        self._index = 0

    def reset(self) -> None:
        self._index = 0

    def next(self) -> Recovery:
        recovery = self.ORDER[self._index % len(self.ORDER)]
        self._index += 1
        return recovery
