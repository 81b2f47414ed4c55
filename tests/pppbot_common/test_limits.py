"""Speed limiter: velocity clamp, acceleration, separate deceleration, reverse, jerk, NaN = unlimited."""
from __future__ import annotations

import math

import pytest

from pppbot_common.limits import AxisLimits, SpeedLimiter

NAN = math.nan


def run(limiter: SpeedLimiter, target: float, steps: int, dt: float = 0.01) -> list[float]:
    return [limiter.limit(target, dt) for _ in range(steps)]


def test_nan_means_unlimited():
    limiter = SpeedLimiter(AxisLimits())
    assert limiter.limit(123.0, 0.01) == 123.0
    assert limiter.limit(-5.0, 0.01) == -5.0


def test_velocity_clamp():
    limiter = SpeedLimiter(AxisLimits(max_velocity=2.0, min_velocity=-1.0))
    assert limiter.limit(5.0, 0.0) == 2.0
    assert limiter.limit(-5.0, 0.0) == -1.0


def test_acceleration_ramp_reaches_target_without_overshoot():
    limiter = SpeedLimiter(AxisLimits(max_acceleration=1.0))
    values = run(limiter, 0.5, 100)
    assert values[0] == pytest.approx(0.01)
    assert values[49] == pytest.approx(0.5)
    assert max(values) == pytest.approx(0.5)


def test_separate_deceleration_limit():
    limiter = SpeedLimiter(AxisLimits(max_acceleration=1.0, max_deceleration=-4.0))  # Jazzy's sign
    run(limiter, 1.0, 200)
    down = run(limiter, 0.0, 30)
    assert down[0] == pytest.approx(1.0 - 0.04)
    assert down[-1] == 0.0  # 1 m/s at 4 m/s² takes 0.25 s


def test_legacy_min_acceleration_is_the_deceleration():
    limiter = SpeedLimiter(AxisLimits(max_acceleration=1.0, min_acceleration=-2.0))
    run(limiter, 1.0, 200)
    assert limiter.limit(0.0, 0.01) == pytest.approx(0.98)


def test_reverse_limits_apply_when_moving_backwards():
    limiter = SpeedLimiter(AxisLimits(max_acceleration=1.0, max_acceleration_reverse=-0.5))
    assert limiter.limit(-1.0, 0.1) == pytest.approx(-0.05)
    limiter.reset()
    assert limiter.limit(1.0, 0.1) == pytest.approx(0.1)


def test_reverse_deceleration_mirrors_the_forward_one_when_unset():
    limiter = SpeedLimiter(AxisLimits(max_acceleration=1.0, max_deceleration=-4.0))
    run(limiter, -1.0, 200)
    assert limiter.limit(0.0, 0.01) == pytest.approx(-1.0 + 0.04)


def test_jazzy_signed_limits_are_valid():
    limits = AxisLimits(max_velocity=2.0, min_velocity=-2.0, max_acceleration=1.0, max_deceleration=-2.0,
                        max_acceleration_reverse=-1.0, max_deceleration_reverse=2.0, max_jerk=5.0, min_jerk=-5.0)
    assert limits.problems("linear.x") == []


def test_jerk_limits_the_change_of_acceleration():
    limiter = SpeedLimiter(AxisLimits(max_acceleration=10.0, max_jerk=10.0))
    values = run(limiter, 1.0, 3, dt=0.1)
    # acceleration grows by at most 1 m/s² per 0.1 s: 1, 2, 3 → speeds 0.1, 0.3, 0.6
    assert values == pytest.approx([0.1, 0.3, 0.6])


@pytest.mark.parametrize("limits, parameter", [
    (AxisLimits(max_acceleration=-1.0), "linear.x.max_acceleration"),
    (AxisLimits(min_acceleration=1.0), "linear.x.min_acceleration"),
    (AxisLimits(max_deceleration=1.0), "linear.x.max_deceleration"),  # Humble-style positive: refused, as Jazzy
    (AxisLimits(max_acceleration_reverse=1.0), "linear.x.max_acceleration_reverse"),
    (AxisLimits(max_deceleration_reverse=-1.0), "linear.x.max_deceleration_reverse"),
    (AxisLimits(min_jerk=1.0), "linear.x.min_jerk"),
    (AxisLimits(max_velocity=1.0, min_velocity=2.0), "linear.x.min_velocity"),
    (AxisLimits(max_velocity=math.inf), "linear.x.max_velocity"),
])
def test_inconsistent_limits_are_named(limits, parameter):
    (problem,) = limits.problems("linear.x")
    assert problem[0] == parameter
