"""The planar transform buffer: chains, interpolation, static edges, errors."""
from __future__ import annotations

import math

import numpy as np
import pytest

from pppbot_common.se2 import se2_compose, se2_inverse
from pppbot_common.transforms import TransformBuffer, TransformError, compose, inverse


def close(a: tuple[float, float, float], b: tuple[float, float, float], tol: float = 1e-9) -> bool:
    return all(abs(x - y) < tol for x, y in zip(a, b, strict=True))


def test_compose_and_inverse_cancel():
    a, b = (1.0, 2.0, 0.7), (-0.3, 0.5, -2.9)
    assert close(compose(inverse(a), compose(a, b)), b)
    assert close(compose(a, inverse(a)), (0.0, 0.0, 0.0))


def test_compose_and_inverse_on_floats_agree_with_the_array_forms():
    """The buffer's float compose and inverse are se2's, yaw wrapped into (−π, π] alike."""
    rng = np.random.default_rng(7)
    poses = np.column_stack([rng.uniform(-50, 50, (500, 2)), rng.uniform(-4 * math.pi, 4 * math.pi, 500)])
    poses[:4, 2] = [math.pi, -math.pi, 0.0, 3 * math.pi]
    for a, b in zip(poses, poses[::-1], strict=True):
        a_, b_ = tuple(a.tolist()), tuple(b.tolist())
        assert compose(a_, b_) == pytest.approx(tuple(se2_compose(a, b).tolist()), abs=1e-9)
        assert inverse(a_) == pytest.approx(tuple(se2_inverse(a).tolist()), abs=1e-9)
        assert -math.pi < compose(a_, b_)[2] <= math.pi and -math.pi < inverse(a_)[2] <= math.pi


def test_chain_map_odom_base_link_with_a_static_sensor():
    tf = TransformBuffer()
    tf.set_transform("map", "odom", 1.0, (1.0, 0.0, math.pi / 2))
    tf.set_transform("odom", "base_link", 1.0, (2.0, 0.0, 0.0))
    tf.set_transform("base_link", "lidar_frame", 0.0, (0.05, 0.0, 0.0), static=True)
    assert close(tf.lookup("map", "base_link", 1.0), (1.0, 2.0, math.pi / 2))
    assert close(tf.lookup("map", "lidar_frame", 1.0), (1.0, 2.05, math.pi / 2))
    # The inverse direction, and between siblings through the common parent.
    assert close(tf.lookup("base_link", "map", 1.0), inverse((1.0, 2.0, math.pi / 2)))
    assert close(tf.lookup("lidar_frame", "base_link", 1.0), (-0.05, 0.0, 0.0))


def test_interpolates_position_and_yaw_the_short_way():
    tf = TransformBuffer()
    tf.set_transform("odom", "base_link", 1.0, (0.0, 0.0, 3.0))
    tf.set_transform("odom", "base_link", 2.0, (1.0, 2.0, -3.0))
    x, y, yaw = tf.lookup("odom", "base_link", 1.5)
    assert (x, y) == pytest.approx((0.5, 1.0))
    assert abs(abs(yaw) - math.pi) < 1e-9  # through ±π, not through 0
    assert tf.latest_time("odom", "base_link") == 2.0


def test_out_of_order_stamps_are_sorted_and_old_ones_expire():
    tf = TransformBuffer(cache_s=1.0)
    for t in (0.0, 0.5, 0.25, 1.0, 2.0):
        tf.set_transform("odom", "base_link", t, (t, 0.0, 0.0))
    assert tf.lookup("odom", "base_link", 1.5)[0] == pytest.approx(1.5)
    with pytest.raises(TransformError, match="before the oldest"):
        tf.lookup("odom", "base_link", 0.5)


def test_errors_name_the_frames_and_times():
    tf = TransformBuffer()
    tf.set_transform("odom", "base_link", 1.0, (0.0, 0.0, 0.0))
    with pytest.raises(TransformError, match="after the newest.*1.000"):
        tf.lookup("odom", "base_link", 3.0)
    with pytest.raises(TransformError, match="no transform from 'base_link' to 'map'.*odom"):
        tf.lookup("map", "base_link", 1.0)
    with pytest.raises(ValueError, match="its own parent"):
        tf.set_transform("a", "a", 0.0, (0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="non-finite"):
        tf.set_transform("odom", "base_link", 2.0, (math.nan, 0.0, 0.0))
