"""Velocity, acceleration and jerk limits of one axis, as diff_drive_controller applies them.

NaN means unlimited. The signs are Jazzy's (ros2_controllers 4.x): each limit is
the bound on the signed rate of change, so

* ``max_acceleration`` ≥ 0 bounds speeding up forwards (dv/dt > 0 at v ≥ 0);
* ``max_deceleration`` ≤ 0 bounds slowing down forwards (dv/dt < 0 at v > 0);
* ``max_acceleration_reverse`` ≤ 0 bounds speeding up backwards (dv/dt < 0 at v ≤ 0);
* ``max_deceleration_reverse`` ≥ 0 bounds slowing down backwards (dv/dt > 0 at v < 0).

A limit left NaN falls back to its mirror: ``max_deceleration`` to the legacy
``min_acceleration`` (Humble's, negative) and then to ``-max_acceleration``;
``max_acceleration_reverse`` to ``-max_acceleration``; ``max_deceleration_reverse``
to ``-max_deceleration``. A limit with the wrong sign is refused, naming it, as
Jazzy's parameter validation refuses it (a Humble-style positive ``max_deceleration``
is not silently read as a magnitude). Jerk limits (``max_jerk`` ≥ 0, ``min_jerk`` ≤ 0)
bound the change of acceleration per second.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

NAN = math.nan
#: Limits that bound an increase of the signed speed (or of the acceleration): > 0.
POSITIVE = ("max_acceleration", "max_deceleration_reverse", "max_jerk")
#: Limits that bound a decrease: < 0 (Jazzy's signs; ``min_acceleration`` is Humble's).
NEGATIVE = ("max_deceleration", "max_acceleration_reverse", "min_acceleration", "min_jerk")


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
        for name in POSITIVE:
            value = getattr(self, name)
            if not math.isnan(value) and not value > 0:
                out.append((f"{axis}.{name}", value, "must be positive (or NaN for unlimited)"))
        for name in NEGATIVE:
            value = getattr(self, name)
            if not math.isnan(value) and not value < 0:
                out.append((f"{axis}.{name}", value, "must be negative, as in Jazzy: it bounds a decrease of the "
                                                     "signed speed (or NaN for unlimited)"))
        for name in ("max_velocity", "min_velocity"):
            if math.isinf(getattr(self, name)):
                out.append((f"{axis}.{name}", getattr(self, name), "must be finite (or NaN for unlimited)"))
        both = math.isfinite(self.max_velocity) and math.isfinite(self.min_velocity)
        if both and self.min_velocity > self.max_velocity:
            out.append((f"{axis}.min_velocity", self.min_velocity, f"must not exceed max_velocity {self.max_velocity}"))
        return out

    def acceleration_bounds(self, previous: float, target: float) -> tuple[float, float]:
        """(lowest, highest) allowed acceleration going from ``previous`` towards ``target``."""
        decel = _first(self.max_deceleration, self.min_acceleration, -self.max_acceleration)  # ≤ 0
        accel = self.max_acceleration  # ≥ 0
        accel_rev = _first(self.max_acceleration_reverse, -accel)  # ≤ 0
        decel_rev = _first(self.max_deceleration_reverse, -decel)  # ≥ 0
        if previous > 0 or (previous == 0 and target >= 0):
            return decel, accel  # moving forward: slowing down is -, speeding up is +
        return accel_rev, decel_rev  # moving backward: speeding up is -, slowing down is +


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
