"""Differential-drive kinematics and wheel odometry.

Body twist (v m/s forward, w rad/s counter-clockwise) and wheel speeds (rad/s)::

    left  = (v - w·s/2) / r_left        v = (r_right·right + r_left·left) / 2
    right = (v + w·s/2) / r_right       w = (r_right·right - r_left·left) / s

with ``s`` the wheel separation. Odometry integrates each step's travelled
distance ``d`` and heading change ``dθ`` either exactly along the arc
(``x += d/dθ·(sin(θ+dθ) - sin θ)``, ``y -= d/dθ·(cos(θ+dθ) - cos θ)``), or with
the second-order Runge-Kutta (mid-heading) form ``x += d·cos(θ + dθ/2)``, which
is what ros2_controllers uses for small ``dθ``. Yaw is kept in (−π, π].
"""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass

from pppbot_common.se2 import wrap_angle

__all__ = ["ARC_EPSILON", "DiffDriveGeometry", "Integration", "Odometry", "integrate", "wrap_angle"]

#: Below this heading change (rad) the exact arc formula loses precision: use Runge-Kutta.
ARC_EPSILON = 1e-6


@dataclass(frozen=True)
class DiffDriveGeometry:
    wheel_separation: float
    wheel_radius: float
    wheel_separation_multiplier: float = 1.0
    left_wheel_radius_multiplier: float = 1.0
    right_wheel_radius_multiplier: float = 1.0

    @property
    def separation(self) -> float:
        return self.wheel_separation * self.wheel_separation_multiplier

    @property
    def left_radius(self) -> float:
        return self.wheel_radius * self.left_wheel_radius_multiplier

    @property
    def right_radius(self) -> float:
        return self.wheel_radius * self.right_wheel_radius_multiplier

    def wheel_speeds(self, v: float, w: float) -> tuple[float, float]:
        """(left, right) wheel speeds in rad/s for a body twist."""
        half = w * self.separation / 2.0
        return (v - half) / self.left_radius, (v + half) / self.right_radius

    def body_twist(self, left: float, right: float) -> tuple[float, float]:
        """(v, w) of the body for wheel speeds in rad/s (or the wheels' angle changes → distances)."""
        left_m, right_m = left * self.left_radius, right * self.right_radius
        return (right_m + left_m) / 2.0, (right_m - left_m) / self.separation


class Integration(enum.Enum):
    EXACT = "exact"
    RUNGE_KUTTA = "runge_kutta"


def integrate(x: float, y: float, yaw: float, distance: float, dyaw: float,
              method: Integration = Integration.EXACT) -> tuple[float, float, float]:
    """Pose after moving ``distance`` (m) while turning ``dyaw`` (rad)."""
    if method is Integration.RUNGE_KUTTA or abs(dyaw) < ARC_EPSILON:
        mid = yaw + dyaw / 2.0
        return x + distance * math.cos(mid), y + distance * math.sin(mid), wrap_angle(yaw + dyaw)
    radius = distance / dyaw
    new_yaw = yaw + dyaw
    return (x + radius * (math.sin(new_yaw) - math.sin(yaw)),
            y - radius * (math.cos(new_yaw) - math.cos(yaw)),
            wrap_angle(new_yaw))


@dataclass
class Odometry:
    """Wheel odometry: pose (x, y, yaw) in the odom frame and the body twist (v, w)."""

    geometry: DiffDriveGeometry
    method: Integration = Integration.EXACT
    x: float = 0.0
    y: float = 0.0
    yaw: float = 0.0
    v: float = 0.0
    w: float = 0.0
    _left: float | None = None
    _right: float | None = None

    def reset(self, x: float = 0.0, y: float = 0.0, yaw: float = 0.0) -> None:
        self.x, self.y, self.yaw, self.v, self.w = x, y, wrap_angle(yaw), 0.0, 0.0
        self._left = self._right = None

    def carry_over(self, other: Odometry) -> None:
        """Continue from ``other``'s pose, twist and last wheel angles (a new geometry, same robot)."""
        self.x, self.y, self.yaw, self.v, self.w = other.x, other.y, other.yaw, other.v, other.w
        self._left, self._right = other._left, other._right

    def update_from_positions(self, left: float, right: float, dt: float) -> None:
        """Integrate wheel angles (rad, cumulative); the first call only records them."""
        if self._left is None or self._right is None:
            self._left, self._right = left, right
            return
        distance, dyaw = self.geometry.body_twist(left - self._left, right - self._right)
        self._left, self._right = left, right
        self._step(distance, dyaw, dt)

    def update_from_velocities(self, left: float, right: float, dt: float) -> None:
        """Integrate wheel speeds (rad/s) over ``dt`` seconds."""
        v, w = self.geometry.body_twist(left, right)
        self._step(v * dt, w * dt, dt)

    def update_open_loop(self, v: float, w: float, dt: float) -> None:
        """Integrate the commanded twist (no wheel feedback)."""
        self._step(v * dt, w * dt, dt)

    def _step(self, distance: float, dyaw: float, dt: float) -> None:
        self.x, self.y, self.yaw = integrate(self.x, self.y, self.yaw, distance, dyaw, self.method)
        if dt > 0:
            self.v, self.w = distance / dt, dyaw / dt
