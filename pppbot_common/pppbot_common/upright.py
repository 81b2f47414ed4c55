"""Whether a ground robot is upright: its base's roll and pitch, and its height over the ground.

A robot that rolls or pitches past ``max_tilt_rad`` has tipped over, and a base below
``min_height_m`` has sunk into the ground (the physics gave way); either way its lidar sweeps
the floor or the sky and nothing it does counts. The simulator reports it (log and
``/diagnostics``), an evaluation fails on it, and the navigator ends a goal with it. 0.5 rad
(29°) is far past what ppp_bot meets driving on the flat (under 0.05 rad) and short of where a
box-shaped robot falls over on its own.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

#: roll or pitch beyond this (rad) is tipped over
MAX_TILT_RAD = 0.5
#: the base's origin below this height (m, world z) is under the ground
MIN_HEIGHT_M = -0.02
#: the /diagnostics status of a robot's posture is named "<robot>: upright"
UPRIGHT_STATUS = ": upright"


def roll_pitch(x: float, y: float, z: float, w: float) -> tuple[float, float]:
    """Roll and pitch (rad, fixed-axis xyz as in URDF/SDF) of a quaternion (need not be normalized)."""
    norm = math.sqrt(x * x + y * y + z * z + w * w) or 1.0
    x, y, z, w = x / norm, y / norm, z / norm, w / norm
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
    return roll, pitch


@dataclass(frozen=True)
class Posture:
    """The base's attitude and height at one time, and whether that is upright."""

    stamp_s: float
    roll_rad: float
    pitch_rad: float
    height_m: float
    upright: bool
    reason: str  # empty when upright

    def describe(self) -> str:
        state = "upright" if self.upright else self.reason
        return (f"{state} (roll {self.roll_rad:.2f} rad, pitch {self.pitch_rad:.2f} rad, z {self.height_m:.3f} m, "
                f"t = {self.stamp_s:.2f} s)")


def posture(stamp_s: float, height_m: float, orientation_xyzw: tuple[float, float, float, float],
            max_tilt_rad: float = MAX_TILT_RAD, min_height_m: float = MIN_HEIGHT_M) -> Posture:
    """The posture of a base at ``height_m`` (world z, m) with this orientation."""
    roll, pitch = roll_pitch(*orientation_xyzw)
    reason = ""
    if abs(roll) > max_tilt_rad or abs(pitch) > max_tilt_rad:
        reason = f"tipped over (beyond {max_tilt_rad:g} rad)"
    elif height_m < min_height_m:
        reason = f"base below the ground (z under {min_height_m:g} m)"
    return Posture(stamp_s, roll, pitch, height_m, not reason, reason)


class UprightWatch:
    """Follows a robot's posture; :meth:`update` returns the posture when it changed between
    upright and not (None otherwise), so each tip is reported once."""

    def __init__(self, max_tilt_rad: float = MAX_TILT_RAD, min_height_m: float = MIN_HEIGHT_M) -> None:
        self.max_tilt_rad = max_tilt_rad
        self.min_height_m = min_height_m
        self.last: Posture | None = None
        self.first_tip: Posture | None = None

    def update(self, stamp_s: float, height_m: float,
               orientation_xyzw: tuple[float, float, float, float]) -> Posture | None:
        now = posture(stamp_s, height_m, orientation_xyzw, self.max_tilt_rad, self.min_height_m)
        changed = self.last is None and not now.upright or self.last is not None and self.last.upright != now.upright
        self.last = now
        if not now.upright and self.first_tip is None:
            self.first_tip = now
        return now if changed else None

    @property
    def upright(self) -> bool:
        return self.last is None or self.last.upright
