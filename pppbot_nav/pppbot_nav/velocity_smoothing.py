"""Velocity smoothing as Nav2's ``velocity_smoother`` does it, without ROS.

Each period (``1 / frequency_hz`` s) the last command is limited three ways, per axis
(x, y, yaw: ``(vx m/s, vy m/s, wz rad/s)``):

* **velocity**: clamped to ``[min_velocity, max_velocity]``;
* **acceleration**: the change from the current velocity is at most ``max_accel / f`` while the
  speed grows in the same direction and at most ``-max_decel / f`` while it shrinks or changes
  sign. With ``scale_velocities`` every axis is first scaled by one factor, that of the axis
  furthest over its limit, so the commanded direction (a diff drive's curvature) is kept; an
  axis still over its own limit after that is clamped;
* **deadband**: an output axis below ``deadband`` in magnitude is sent as zero.

The current velocity is the last output (open loop) or the measured one (closed loop: the
odometry averaged over a short window, :class:`OdomAverage`). A command older than
``timeout_s`` is replaced by zero, which the robot decelerates to within the limits; once the
output is zero nothing more is sent until a new command (:class:`VelocitySmoothing`).
"""
from __future__ import annotations

import enum
import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pppbot_nav.errors import VelocitySmootherError

#: (vx m/s, vy m/s, wz rad/s).
Velocity3 = tuple[float, float, float]
ZERO: Velocity3 = (0.0, 0.0, 0.0)


class Feedback(enum.Enum):
    """Where the current velocity comes from: the last output, or odometry."""
    OPEN_LOOP = "OPEN_LOOP"
    CLOSED_LOOP = "CLOSED_LOOP"


def feedback_of(value: str) -> Feedback:
    """``value`` as a :class:`Feedback`.

    Raises:
        VelocitySmootherError: not one of OPEN_LOOP, CLOSED_LOOP (parameter ``feedback``).
    """
    try:
        return Feedback(value)
    except ValueError:
        allowed = ", ".join(f.value for f in Feedback)
        raise VelocitySmootherError(f"feedback '{value}' is not one of {allowed}", "feedback") from None


def vector3(name: str, value: Sequence[float]) -> Velocity3:
    """``value`` as three finite floats.

    Raises:
        VelocitySmootherError: not a sequence of three finite numbers (parameter ``name``).
    """
    try:
        values = [float(v) for v in value]
    except (TypeError, ValueError):
        raise VelocitySmootherError(f"{name} must be three numbers (x, y, theta), not {value!r}", name) from None
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise VelocitySmootherError(f"{name} must be three finite numbers (x, y, theta), not {list(value)!r}", name)
    return values[0], values[1], values[2]


@dataclass(frozen=True)
class SmootherLimits:
    """The limits of one smoothing period; vectors are (x, y, theta)."""
    frequency_hz: float
    max_velocity: Velocity3
    min_velocity: Velocity3
    max_accel: Velocity3
    max_decel: Velocity3
    deadband: Velocity3 = ZERO
    scale_velocities: bool = False

    def validate(self) -> None:
        """Raises:
            VelocitySmootherError: naming the parameter (Nav2's: ``max_accel``, ``max_decel``, ...).
        """
        if not (math.isfinite(self.frequency_hz) and self.frequency_hz > 0):
            raise VelocitySmootherError(f"smoothing_frequency must be a positive number of Hz, not "
                                        f"{self.frequency_hz}", "smoothing_frequency")
        checks = (("max_velocity", self.max_velocity, 1, "must not be negative"),
                  ("min_velocity", self.min_velocity, -1, "must not be positive"),
                  ("max_accel", self.max_accel, 1, "must not be negative (it speeds the robot up)"),
                  ("max_decel", self.max_decel, -1, "must not be positive (it slows the robot down)"),
                  ("deadband_velocity", self.deadband, 1, "must not be negative"))
        for name, vector, sign, rule in checks:
            vector3(name, vector)
            if any(v * sign < 0 for v in vector):
                raise VelocitySmootherError(f"{name} {list(vector)}: each axis {rule}", name)
        if any(lo > hi for lo, hi in zip(self.min_velocity, self.max_velocity, strict=True)):
            raise VelocitySmootherError(f"min_velocity {list(self.min_velocity)} is above max_velocity "
                                        f"{list(self.max_velocity)} on an axis", "min_velocity")


def _change_bounds(current: np.ndarray, target: np.ndarray, limits: SmootherLimits) -> tuple[np.ndarray, np.ndarray]:
    """Per axis, the smallest and largest change allowed this period (a speed growing in the same
    direction is limited by max_accel, anything else by max_decel)."""
    accelerating = (np.abs(target) >= np.abs(current)) & (current * target >= 0.0)
    step = np.where(accelerating, np.asarray(limits.max_accel), -np.asarray(limits.max_decel)) / limits.frequency_hz
    return -step, step


def limited(current: Velocity3, command: Velocity3, limits: SmootherLimits) -> Velocity3:
    """The next output from ``current`` towards ``command``: velocity and acceleration limits
    applied, before the deadband (which :func:`deadbanded` applies)."""
    now = np.asarray(current, dtype=float)
    target = np.clip(np.asarray(command, dtype=float), limits.min_velocity, limits.max_velocity)
    change = target - now
    low, high = _change_bounds(now, target, limits)
    if limits.scale_velocities:
        # The axis furthest over its bound sets one factor for all: the direction is kept. An
        # axis that may not change at all (a bound of zero) would stop every axis: it is left to
        # its own clamp, as Nav2 does.
        factor = np.ones(3)
        np.divide(high, change, out=factor, where=change > high)
        np.divide(low, change, out=factor, where=change < low)
        change = change * float(factor[factor > 0.0].min(initial=1.0))
    out = now + np.clip(change, low, high)
    return float(out[0]), float(out[1]), float(out[2])


def deadbanded(velocity: Velocity3, deadband: Velocity3) -> Velocity3:
    """Axes smaller in magnitude than their deadband set to zero."""
    x, y, w = (0.0 if abs(v) < d else v for v, d in zip(velocity, deadband, strict=True))
    return x, y, w


def is_finite(velocity: Sequence[float]) -> bool:
    return all(math.isfinite(v) for v in velocity)


class OdomAverage:
    """The measured velocity: the mean of the odometry twists of the last ``window_s`` seconds
    (Nav2's odom smoother); zero before the first."""

    def __init__(self, window_s: float) -> None:
        if not (math.isfinite(window_s) and window_s > 0):
            raise VelocitySmootherError(f"odom_duration must be a positive number of seconds, not {window_s}",
                                        "odom_duration")
        self.window_s = window_s
        self._samples: deque[tuple[float, Velocity3]] = deque()

    def add(self, stamp_s: float, velocity: Velocity3) -> None:
        """Keep a twist (a non-finite one is refused: :class:`VelocitySmootherError`)."""
        if not (math.isfinite(stamp_s) and is_finite(velocity)):
            raise VelocitySmootherError(f"odometry twist {velocity} at {stamp_s} s is not finite")
        self._samples.append((stamp_s, velocity))
        newest = max(s for s, _ in self._samples)
        while self._samples and self._samples[0][0] < newest - self.window_s:
            self._samples.popleft()

    def velocity(self) -> Velocity3:
        if not self._samples:
            return ZERO
        mean = np.mean([v for _, v in self._samples], axis=0)
        return float(mean[0]), float(mean[1]), float(mean[2])


class VelocitySmoothing:
    """The smoother's state between periods: the last command and when it came, the last output.

    Call :meth:`command` for each command and :meth:`tick` each period; times are seconds on
    the caller's clock.
    """

    def __init__(self, limits: SmootherLimits, timeout_s: float) -> None:
        limits.validate()
        if not (math.isfinite(timeout_s) and timeout_s > 0):
            raise VelocitySmootherError(f"velocity_timeout must be a positive number of seconds, not {timeout_s}",
                                        "velocity_timeout")
        self.limits = limits
        self.timeout_s = timeout_s
        self._command: Velocity3 | None = None
        self._command_s = -math.inf
        self._last: Velocity3 = ZERO  # the last output before the deadband
        self._stopped = True

    @property
    def idle(self) -> bool:
        """Nothing to send until a new command (none yet, or stopped after a timeout)."""
        return self._command is None or self._stopped

    def command(self, velocity: Velocity3, now_s: float) -> None:
        """Take a command.

        Raises:
            VelocitySmootherError: a NaN or infinite component (the command is not taken).
        """
        if not is_finite(velocity):
            raise VelocitySmootherError(f"command {velocity} has a component that is not finite")
        self._command, self._command_s = velocity, now_s
        self._stopped = False

    def tick(self, now_s: float, measured: Velocity3 | None = None) -> Velocity3 | None:
        """The output for this period, or None when there is nothing to send. ``measured``: the
        current velocity in closed loop (None: open loop, the last output)."""
        if self._command is None:
            return None
        if now_s - self._command_s > self.timeout_s:
            if self._stopped or self._last == ZERO:
                self._stopped = True
                return None
            self._command = ZERO  # stale: decelerate to a stop
        current = self._last if measured is None else measured
        self._last = limited(current, self._command, self.limits)
        return deadbanded(self._last, self.limits.deadband)

    def reset(self) -> None:
        """Forget the command and the last output."""
        self._command, self._command_s, self._last, self._stopped = None, -math.inf, ZERO, True
