"""Velocity, acceleration and jerk limits of one axis, as diff_drive_controller applies them.

NaN means unlimited (Jazzy's convention). Accelerating away from zero uses
``max_acceleration`` (``max_acceleration_reverse`` when moving backwards);
slowing towards zero uses ``max_deceleration`` (``max_deceleration_reverse``),
each falling back to the forward value, and the deceleration limits fall back to
the legacy ``min_acceleration`` (a negative number) and then to
``max_acceleration``. Jerk limits bound the change of acceleration per second.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

NAN = math.nan


def _first(*values: float) -> float:
    """The first finite value, NaN when none is."""
    return next((v for v in values if math.isfinite(v)), NAN)


def _clamp(value: float, low: float, high: float) -> float:
    if math.isfinite(low):
        value = max(value, low)
    if math.isfinite(high):
        value = min(value, high)
    return value


@dataclass(frozen=True)
class AxisLimits:
    max_velocity: float = NAN
    min_velocity: float = NAN
    max_acceleration: float = NAN
    max_deceleration: float = NAN
    max_acceleration_reverse: float = NAN
    max_deceleration_reverse: float = NAN
    min_acceleration: float = NAN  # legacy: a negative bound on acceleration
    max_jerk: float = NAN
    min_jerk: float = NAN

    def problems(self, axis: str) -> list[tuple[str, float, str]]:
        """What is inconsistent, as (parameter, value, rule) (empty when valid)."""
        out = []
        for name in ("max_acceleration", "max_deceleration", "max_acceleration_reverse",
                     "max_deceleration_reverse", "max_jerk"):
            value = getattr(self, name)
            if not math.isnan(value) and not value > 0:
                out.append((f"{axis}.{name}", value, "must be positive (or NaN for unlimited)"))
        for name in ("min_acceleration", "min_jerk"):
            value = getattr(self, name)
            if not math.isnan(value) and not value < 0:
                out.append((f"{axis}.{name}", value, "must be negative (or NaN for unlimited)"))
        for name in ("max_velocity", "min_velocity"):
            if math.isinf(getattr(self, name)):
                out.append((f"{axis}.{name}", getattr(self, name), "must be finite (or NaN for unlimited)"))
        both = math.isfinite(self.max_velocity) and math.isfinite(self.min_velocity)
        if both and self.min_velocity > self.max_velocity:
            out.append((f"{axis}.min_velocity", self.min_velocity, f"must not exceed max_velocity {self.max_velocity}"))
        return out

    def acceleration_bounds(self, previous: float, target: float) -> tuple[float, float]:
        """(lowest, highest) allowed acceleration going from ``previous`` towards ``target``."""
        decel = _first(self.max_deceleration, -self.min_acceleration, self.max_acceleration)
        accel = self.max_acceleration
        accel_rev = _first(self.max_acceleration_reverse, accel)
        decel_rev = _first(self.max_deceleration_reverse, decel)
        if previous > 0 or (previous == 0 and target >= 0):
            # moving forward: speeding up is +, slowing down is -
            return -decel, accel
        return -accel_rev, decel_rev


@dataclass
class SpeedLimiter:
    """Stateful limiter of one axis: ``limit(target, dt)`` returns the allowed command."""

    limits: AxisLimits
    previous: float = 0.0
    previous_acceleration: float = 0.0

    def reset(self) -> None:
        self.previous = self.previous_acceleration = 0.0

    def limit(self, target: float, dt: float) -> float:
        """The command closest to ``target`` that respects every limit; updates the state."""
        lim = self.limits
        goal = _clamp(target, lim.min_velocity, lim.max_velocity)
        value = goal
        if dt > 0:
            low, high = lim.acceleration_bounds(self.previous, goal)
            acceleration = _clamp((goal - self.previous) / dt, low, high)
            min_jerk = _first(lim.min_jerk, -lim.max_jerk)
            acceleration = _clamp(acceleration, self.previous_acceleration + min_jerk * dt,
                                  self.previous_acceleration + lim.max_jerk * dt)
            value = self.previous + acceleration * dt
            if (goal - self.previous) * (goal - value) < 0:  # never overshoot the goal
                value = goal
            self.previous_acceleration = (value - self.previous) / dt
        value = _clamp(value, lim.min_velocity, lim.max_velocity)
        self.previous = value
        return value
