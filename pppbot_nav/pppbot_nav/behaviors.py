"""Nav2's behaviours (``behavior_server`` plugins), without ROS.

Each behaviour is started at the robot's pose and then stepped with the current pose and
time; a step returns the velocity to command, (v m/s, ω rad/s), or the :class:`Outcome` it
ended with. :class:`Spin` turns by a relative angle (ramping its speed down near the end, as
Nav2's spin), :class:`DriveOnHeading` drives a distance straight ahead or (negative) back at
a speed (:func:`back_up` is Nav2's backup), :class:`Wait` stands still; each times out after
its ``time_allowance_s``. :func:`collision_ahead` says, from the local costmap, when a
behaviour must stop as Nav2's collision check would: it simulates the command
``simulate_ahead_time_s`` ahead (no further than the behaviour still has to go) and refuses
once a simulated pose puts the footprint circle on an obstacle. :func:`assisted` is Nav2's
assisted teleop: a teleop command scaled down by how soon it would collide.
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


class Outcome(enum.Enum):
    """How a behaviour ended."""

    DONE = "done"  # it turned, drove or waited what it was asked
    TIMEOUT = "timeout"  # its time allowance ran out first


@dataclass
class Spin:
    """Turn ``spin_dist_rad`` (signed, relative) on the spot."""

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

    @property
    def progress(self) -> float:
        """The angle turned so far (rad, unsigned)."""
        return abs(self._turned)

    @property
    def remaining(self) -> float:
        """What is left to turn (rad, unsigned)."""
        return max(0.0, abs(self.spin_dist_rad) - abs(self._turned))

    def step(self, pose: Pose, now_s: float) -> Velocity | Outcome:
        self._turned += wrap_angle(pose[2] - self._last_yaw)
        self._last_yaw = pose[2]
        if self.remaining <= 0.0:
            return Outcome.DONE
        if now_s - self._start_s > self.time_allowance_s:
            return Outcome.TIMEOUT
        # Reach zero speed at the target with the acceleration limit: v = sqrt(2·a·remaining).
        speed = min(self.max_rotational_vel, max(self.min_rotational_vel,
                                                 math.sqrt(2.0 * self.rotational_acc_lim * self.remaining)))
        return 0.0, math.copysign(speed, self.spin_dist_rad)


@dataclass
class DriveOnHeading:
    """Drive ``distance_m`` along the heading the robot had at the start, at ``speed`` (m/s; both
    negative to drive backwards)."""

    distance_m: float = 0.15
    speed: float = 0.025
    time_allowance_s: float = 10.0
    _start: Pose = field(default=(0.0, 0.0, 0.0), init=False)
    _start_s: float = field(default=0.0, init=False)
    _travelled: float = field(default=0.0, init=False)

    def start(self, pose: Pose, now_s: float) -> None:
        self._start, self._start_s, self._travelled = pose, now_s, 0.0

    @property
    def progress(self) -> float:
        """The distance driven so far (m, unsigned)."""
        return self._travelled

    @property
    def remaining(self) -> float:
        """What is left to drive (m, unsigned)."""
        return max(0.0, abs(self.distance_m) - self._travelled)

    def step(self, pose: Pose, now_s: float) -> Velocity | Outcome:
        self._travelled = math.hypot(pose[0] - self._start[0], pose[1] - self._start[1])
        if self.remaining <= 0.0:
            return Outcome.DONE
        if now_s - self._start_s > self.time_allowance_s:
            return Outcome.TIMEOUT
        return self.speed, 0.0


def back_up(distance_m: float = 0.15, speed: float = 0.025, time_allowance_s: float = 10.0) -> DriveOnHeading:
    """Nav2's backup: :class:`DriveOnHeading` backwards, whatever the signs given."""
    return DriveOnHeading(-abs(distance_m), -abs(speed), time_allowance_s)


def drive_on_heading_problem(distance_m: float, speed: float) -> str | None:
    """Why a drive_on_heading request cannot run (Nav2's INVALID_INPUT), or None."""
    if not (math.isfinite(distance_m) and math.isfinite(speed)):
        return f"distance {distance_m} and speed {speed} must be finite"
    if speed == 0.0:
        return "speed is 0: the robot would never get there"
    if distance_m * speed < 0.0:
        return f"the signs of the distance ({distance_m:g} m) and the speed ({speed:g} m/s) differ"
    return None


@dataclass
class Wait:
    wait_duration_s: float = 5.0
    _start_s: float = field(default=0.0, init=False)
    _now_s: float = field(default=0.0, init=False)

    def start(self, pose: Pose, now_s: float) -> None:
        self._start_s = self._now_s = now_s

    @property
    def remaining(self) -> float:
        """Time left to wait (s)."""
        return max(0.0, self.wait_duration_s - (self._now_s - self._start_s))

    def step(self, pose: Pose, now_s: float) -> Velocity | Outcome:
        self._now_s = now_s
        return Outcome.DONE if self.remaining <= 0.0 else (0.0, 0.0)


Behavior = Spin | DriveOnHeading | Wait

#: Occupancy values of the published costmap (nav_msgs/OccupancyGrid, 0–100) from which a cell
#: is inscribed (the robot's centre there puts its footprint circle on an obstacle) or lethal.
INSCRIBED_OCCUPANCY = 99


def _footprint_hits(costmap: OccupancyGrid, x: float, y: float) -> int | None:
    """The occupancy under the robot's centre at (x, y) when it is inscribed or lethal, else None
    (unknown and off-map cells are no reason to stop)."""
    row, col = (int(i) for i in costmap.cell_of(np.array(x), np.array(y)))
    if not (0 <= row < costmap.height and 0 <= col < costmap.width):
        return None
    value = int(costmap.data[row, col])
    return value if value >= INSCRIBED_OCCUPANCY else None


def collision_ahead(behavior: Behavior, costmap: OccupancyGrid | None, pose: Pose, command: Velocity, *,
                    simulate_ahead_time_s: float = 2.0, cycle_frequency_hz: float = 10.0) -> str | None:
    """Why ``behavior`` must stop at ``pose`` (in the costmap's frame) with ``command``, or None.

    As Nav2's behaviours check: the command is simulated in steps of 1 / ``cycle_frequency_hz``
    up to ``simulate_ahead_time_s`` ahead, no further than the behaviour still has to go; a
    simulated pose whose cell is inscribed or lethal (the footprint circle on an obstacle) is a
    collision ahead. A spin turns on the spot: only the robot's own cell matters. A missing
    costmap is no reason to stop.
    """
    if costmap is None or isinstance(behavior, Wait):
        return None
    x, y, yaw = pose
    v, _ = command
    steps = max(1, int(simulate_ahead_time_s * cycle_frequency_hz))
    for i in range(steps + 1):
        ahead = v * i / cycle_frequency_hz
        if isinstance(behavior, DriveOnHeading) and i > 0 and abs(ahead) >= behavior.remaining:
            break
        px, py = x + ahead * math.cos(yaw), y + ahead * math.sin(yaw)
        value = _footprint_hits(costmap, px, py)
        if value is not None:
            kind = "lethal" if value > INSCRIBED_OCCUPANCY else "inscribed"
            where = "at the robot" if i == 0 else f"{abs(ahead):.2f} m {'ahead' if v > 0 else 'behind'}"
            return f"collision ahead: the cell {where} ({px:.2f}, {py:.2f}) is {kind} (occupancy {value})"
        if isinstance(behavior, Spin) or v == 0.0:
            break
    return None


def assisted(command: Velocity, pose: Pose, costmap: OccupancyGrid | None, *, projection_time_s: float = 1.0,
             simulation_time_step_s: float = 0.1) -> Velocity:
    """Nav2's assisted teleop: ``command`` as it is when the robot can follow it for
    ``projection_time_s`` without its footprint on an obstacle; scaled by t / projection_time_s
    when the first collision is t seconds ahead; zero when it is one step ahead."""
    if costmap is None:
        return command
    v, w = command
    x, y, yaw = pose
    t = 0.0
    while t + simulation_time_step_s <= projection_time_s + 1e-9:
        # Integrate one step of the unicycle (straight, or along the arc).
        dt = simulation_time_step_s
        if abs(w) < 1e-9:
            x, y = x + v * dt * math.cos(yaw), y + v * dt * math.sin(yaw)
        else:
            x += v / w * (math.sin(yaw + w * dt) - math.sin(yaw))
            y -= v / w * (math.cos(yaw + w * dt) - math.cos(yaw))
            yaw += w * dt
        t += dt
        if _footprint_hits(costmap, x, y) is not None:
            if t <= simulation_time_step_s + 1e-9:
                return 0.0, 0.0
            scale = t / projection_time_s
            return v * scale, w * scale
    return command
