"""Differential-drive kinematics and odometry on hand-worked cases."""
from __future__ import annotations

import math

import pytest

from pppbot_common.kinematics import DiffDriveGeometry, Integration, Odometry, integrate, wrap_angle

PPP = DiffDriveGeometry(wheel_separation=0.35, wheel_radius=0.05)


def test_wheel_speeds_and_back():
    assert PPP.wheel_speeds(0.5, 0.0) == pytest.approx((10.0, 10.0))
    assert PPP.wheel_speeds(0.0, 1.0) == pytest.approx((-3.5, 3.5))  # 0.175 m / 0.05 m
    assert PPP.body_twist(*PPP.wheel_speeds(0.3, -0.7)) == pytest.approx((0.3, -0.7))


def test_multipliers_correct_geometry():
    g = DiffDriveGeometry(0.35, 0.05, wheel_separation_multiplier=2.0, left_wheel_radius_multiplier=0.5)
    left, right = g.wheel_speeds(0.0, 1.0)
    assert (left, right) == pytest.approx((-0.35 / 0.025, 0.35 / 0.05))


@pytest.mark.parametrize("angle, wrapped", [
    (0.0, 0.0), (math.pi, math.pi), (-math.pi, math.pi), (3 * math.pi, math.pi), (2 * math.pi + 0.1, 0.1),
    (-0.1, -0.1), (-3 * math.pi / 2, math.pi / 2),
])
def test_wrap_angle_is_in_minus_pi_to_pi(angle, wrapped):
    assert wrap_angle(angle) == pytest.approx(wrapped)


def test_straight_line():
    odom = Odometry(PPP)
    odom.update_from_positions(0.0, 0.0, 0.0)
    for k in range(1, 101):  # 100 steps of 0.01 s at 10 rad/s → 0.5 m/s
        odom.update_from_positions(0.1 * k, 0.1 * k, 0.01)
    assert (odom.x, odom.y, odom.yaw) == pytest.approx((0.5, 0.0, 0.0))
    assert (odom.v, odom.w) == pytest.approx((0.5, 0.0))


def test_pure_rotation():
    odom = Odometry(PPP)
    odom.update_from_positions(0.0, 0.0, 0.0)
    odom.update_from_positions(-3.5, 3.5, 1.0)  # 1 rad in one step
    assert (odom.x, odom.y) == pytest.approx((0.0, 0.0))
    assert odom.yaw == pytest.approx(1.0)


def test_arc_exact_versus_runge_kutta():
    """A quarter circle of radius 1 m in one step: exact lands on it, RK2 is off by ~1 %."""
    exact = integrate(0.0, 0.0, 0.0, math.pi / 2, math.pi / 2, Integration.EXACT)
    assert exact == pytest.approx((1.0, 1.0, math.pi / 2))
    rk = integrate(0.0, 0.0, 0.0, math.pi / 2, math.pi / 2, Integration.RUNGE_KUTTA)
    assert rk[0] == pytest.approx(math.pi / 2 * math.cos(math.pi / 4))
    assert abs(rk[0] - 1.0) > 0.1  # why the exact form exists


@pytest.mark.parametrize("method", list(Integration))
def test_full_circle_closes_on_itself(method):
    odom = Odometry(PPP, method=method)
    v, w, steps = 0.4, 0.8, 1000
    dt = 2 * math.pi / w / steps  # exactly one turn
    for _ in range(steps):
        odom.update_from_velocities(*PPP.wheel_speeds(v, w), dt)
    assert math.hypot(odom.x, odom.y) < 1e-9
    assert abs(wrap_angle(odom.yaw)) < 1e-9


def test_open_loop_and_reset():
    odom = Odometry(PPP)
    odom.update_open_loop(1.0, 0.0, 2.0)
    assert odom.x == pytest.approx(2.0)
    odom.reset(1.0, 2.0, 4.0)
    assert (odom.x, odom.y, odom.yaw) == pytest.approx((1.0, 2.0, 4.0 - 2 * math.pi))
