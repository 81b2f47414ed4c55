"""Wheel slip as the wheel encoders report it, so that odometry drifts like a real robot's.

Physics stays exact; what changes is what ``/joint_states`` says. Each driven
wheel reports its true rotation since the last reading times ``1 + s``, where the
slip fraction ``s`` of every wheel is its own Ornstein–Uhlenbeck process: zero
mean, standard deviation ``slip_stddev``, correlation time ``correlation_s``
(slip comes and goes with the floor and the load, it is not white noise). A
difference between the two wheels' ``s`` turns into a heading error, which is
what makes dead reckoning drift. The reported velocity is scaled the same way.

No ROS here; the generator is passed in, so runs are reproducible.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Beyond this a wheel would now and then seem to turn backwards (1 + s < 0 at 5 sigma).
MAX_SLIP_STDDEV = 0.2


@dataclass(frozen=True)
class SlipModel:
    """``slip_stddev``: standard deviation of the slip fraction (0.02 = 2 % of wheel travel);
    ``correlation_s``: how long (sim s) a slip fraction persists."""

    slip_stddev: float = 0.0
    correlation_s: float = 2.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.slip_stddev) and 0.0 <= self.slip_stddev <= MAX_SLIP_STDDEV):
            raise ValueError(f"wheel slip standard deviation must be in [0, {MAX_SLIP_STDDEV}], not {self.slip_stddev}")
        if not (math.isfinite(self.correlation_s) and self.correlation_s > 0.0):
            raise ValueError(f"wheel slip correlation time must be a positive number of seconds, "
                             f"not {self.correlation_s}")


class WheelSlip:
    """Turns true wheel positions and velocities into reported ones; ``wheels`` masks the slipping joints."""

    def __init__(self, model: SlipModel, wheels: np.ndarray, rng: np.random.Generator) -> None:
        self.model = model
        self.wheels = np.asarray(wheels, dtype=bool)
        self.rng = rng
        self.slip = np.zeros(len(self.wheels))
        self._true: np.ndarray | None = None
        self._reported: np.ndarray | None = None
        self._time_s = 0.0

    @property
    def enabled(self) -> bool:
        return self.model.slip_stddev > 0.0

    def reset(self) -> None:
        """Reported positions follow the true ones again from the next reading (after a reset)."""
        self._true = self._reported = None
        self.slip[:] = 0.0

    def apply(self, time_s: float, positions: np.ndarray, velocities: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Reported (positions, velocities) for true ones read at ``time_s``."""
        if not self.enabled:
            return positions, velocities
        if self._true is None or self._reported is None:
            self._true, self._reported, self._time_s = positions.copy(), positions.copy(), time_s
            return positions, velocities
        self._advance_slip(max(0.0, time_s - self._time_s))
        scale = np.where(self.wheels, 1.0 + self.slip, 1.0)
        self._reported = self._reported + (positions - self._true) * scale
        self._true, self._time_s = positions.copy(), time_s
        return self._reported.copy(), velocities * scale

    def _advance_slip(self, dt_s: float) -> None:
        """One exact Ornstein–Uhlenbeck step of length ``dt_s``."""
        decay = math.exp(-dt_s / self.model.correlation_s)
        spread = self.model.slip_stddev * math.sqrt(1.0 - decay * decay)
        self.slip = self.slip * decay + spread * self.rng.standard_normal(len(self.slip))
