"""Planar pose helpers: angles in (−π, π], yaw ↔ quaternion (x, y, z, w), and SE(2) on arrays.

Poses are (x, y, yaw) in m, m, rad. ``a ∘ b`` (:func:`se2_compose`) is the pose ``b``,
given in frame ``a``, expressed in ``a``'s parent; yaw is kept in (−π, π]. The array
functions broadcast like numpy over (..., 3) poses.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

PoseLike = Sequence[float] | np.ndarray


def finite_pose(value: object, what: str, error: Callable[[str], Exception] = ValueError) -> np.ndarray:
    """``value`` as a float (3,) array (x, y, yaw), the one check every pose input gets.

    Raises:
        ``error(message)`` (the caller's package error; ValueError by default), the message
        naming ``what`` and the value given, when it is not three finite numbers.
    """
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        array = np.empty(0)
    if array.shape != (3,) or not np.isfinite(array).all():
        raise error(f"{what} must be three finite numbers (x, y, yaw), not {value!r}")
    return array


def wrap_angle(angle: float) -> float:
    """``angle`` in (−π, π]."""
    wrapped = math.fmod(angle + math.pi, 2.0 * math.pi)
    if wrapped <= 0.0:
        wrapped += 2.0 * math.pi
    return wrapped - math.pi


def yaw_from_quaternion(x: float, y: float, z: float, w: float) -> float:
    """Rotation about z (rad) of a quaternion (the yaw of its roll-pitch-yaw)."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def quaternion_from_yaw(yaw: float) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a rotation by ``yaw`` rad about z."""
    return 0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0)



def wrap_angles(angle_rad: np.ndarray | float) -> np.ndarray:
    """Angles (rad) wrapped into (−π, π], element-wise."""
    return math.pi - np.mod(math.pi - np.asarray(angle_rad, dtype=float), 2.0 * math.pi)


def se2_compose(a: PoseLike, b: PoseLike) -> np.ndarray:
    """``a ∘ b`` for (..., 3) arrays of (x, y, yaw), broadcasting like numpy."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = a[..., 0] + c * b[..., 0] - s * b[..., 1]
    y = a[..., 1] + s * b[..., 0] + c * b[..., 1]
    return np.stack([x, y, wrap_angles(a[..., 2] + b[..., 2])], axis=-1)


def se2_inverse(a: PoseLike) -> np.ndarray:
    """``a⁻¹`` for a (..., 3) array of (x, y, yaw): ``a ∘ a⁻¹`` is the identity."""
    a = np.asarray(a, dtype=float)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = -c * a[..., 0] - s * a[..., 1]
    y = s * a[..., 0] - c * a[..., 1]
    return np.stack([x, y, wrap_angles(-a[..., 2])], axis=-1)


def se2_relative(a: PoseLike, b: PoseLike) -> np.ndarray:
    """``a⁻¹ ∘ b``: the pose ``b`` seen from ``a`` (both in the same frame)."""
    return se2_compose(se2_inverse(a), b)


def se2_apply(pose: PoseLike, points_xy: np.ndarray) -> np.ndarray:
    """Points (..., 2), given in the frame ``pose``, expressed in ``pose``'s parent (m)."""
    pose = np.asarray(pose, dtype=float)
    points_xy = np.asarray(points_xy, dtype=float)
    c, s = np.cos(pose[..., 2]), np.sin(pose[..., 2])
    x = pose[..., 0] + c * points_xy[..., 0] - s * points_xy[..., 1]
    y = pose[..., 1] + s * points_xy[..., 0] + c * points_xy[..., 1]
    return np.stack([x, y], axis=-1)
