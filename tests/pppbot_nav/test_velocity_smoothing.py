"""Velocity smoothing without ROS: velocity, acceleration and deadband limits, direction-keeping
scaling, closed-loop feedback and the command timeout."""
from __future__ import annotations

import dataclasses
import math

import pytest

from pppbot_nav.errors import VelocitySmootherError
from pppbot_nav.velocity_smoothing import (
    Feedback,
    OdomAverage,
    SmootherLimits,
    VelocitySmoothing,
    deadbanded,
    feedback_of,
    limited,
)

#: Nav2's defaults at 20 Hz: 0.125 m/s and 0.16 rad/s per period speeding up, the same slowing down.
LIMITS = SmootherLimits(20.0, (0.5, 0.0, 2.0), (-0.5, 0.0, -2.0), (2.5, 0.0, 3.2), (-2.5, 0.0, -3.2))


def with_(**changes: object) -> SmootherLimits:
    return dataclasses.replace(LIMITS, **changes)  # type: ignore[arg-type]


def test_acceleration_is_limited_per_period_until_the_command_is_reached():
    smoothing = VelocitySmoothing(LIMITS, timeout_s=1.0)
    smoothing.command((0.4, 0.0, 0.0), now_s=0.0)
    outputs = [smoothing.tick(0.05 * k) for k in range(1, 6)]
    assert [o[0] for o in outputs if o] == pytest.approx([0.125, 0.25, 0.375, 0.4, 0.4])


def test_commands_are_clamped_to_the_velocity_limits():
    v = (0.5, 0.0, 2.0)
    assert limited(v, (3.0, 1.0, -9.0), LIMITS) == pytest.approx((0.5, 0.0, 2.0 - 3.2 / 20))
    assert limited((0.0, 0.0, 0.0), (-3.0, 0.0, 0.0), LIMITS) == pytest.approx((-0.125, 0.0, 0.0))


def test_slowing_down_and_reversing_use_the_deceleration_limit():
    limits = with_(max_accel=(1.0, 0.0, 1.0), max_decel=(-4.0, 0.0, -4.0))
    assert limited((0.4, 0.0, 0.0), (0.0, 0.0, 0.0), limits)[0] == pytest.approx(0.2)  # 4 m/s² / 20
    assert limited((0.1, 0.0, 0.0), (-0.5, 0.0, 0.0), limits)[0] == pytest.approx(-0.1)  # through zero: decel
    assert limited((0.1, 0.0, 0.0), (0.5, 0.0, 0.0), limits)[0] == pytest.approx(0.15)  # speeding up: accel


def test_scale_velocities_keeps_the_commanded_curvature():
    target = (0.5, 0.0, 1.0)  # a 0.5 m radius: x reaches its limit in four periods, yaw in seven
    plain = limited((0.0, 0.0, 0.0), target, LIMITS)
    scaled = limited((0.0, 0.0, 0.0), target, with_(scale_velocities=True))
    assert plain == pytest.approx((0.125, 0.0, 0.16))  # each axis at its own limit: curvature lost
    assert plain[2] / plain[0] != pytest.approx(2.0)
    assert scaled == pytest.approx((0.08, 0.0, 0.16))  # both at yaw's factor (0.16 of 1.0)
    assert scaled[2] / scaled[0] == pytest.approx(target[2] / target[0])


def test_scale_velocities_ignores_an_axis_that_may_not_change():
    # y may not move at all (limits of 0): it must not stop x and yaw along with it.
    out = limited((0.0, 0.05, 0.0), (0.3, 0.0, 0.0), with_(scale_velocities=True))
    assert out[0] == pytest.approx(0.125) and out[1] == pytest.approx(0.05)


def test_deadband_zeroes_small_axes_only():
    assert deadbanded((0.04, 0.0, -0.3), (0.05, 0.0, 0.1)) == (0.0, 0.0, -0.3)
    smoothing = VelocitySmoothing(with_(deadband=(0.2, 0.0, 0.0)), timeout_s=1.0)
    smoothing.command((0.5, 0.0, 0.0), 0.0)
    assert smoothing.tick(0.05) == (0.0, 0.0, 0.0)  # 0.125 is inside the deadband
    assert smoothing.tick(0.10) == pytest.approx((0.25, 0.0, 0.0))  # but the ramp went on underneath


def test_a_stale_command_decelerates_to_zero_then_nothing_is_sent():
    smoothing = VelocitySmoothing(LIMITS, timeout_s=1.0)
    smoothing.command((0.3, 0.0, 0.0), 0.0)
    t = 0.0
    while t < 0.9:
        t += 0.05
        smoothing.tick(t)
    assert smoothing.tick(1.05) == pytest.approx((0.175, 0.0, 0.0))  # the timeout passed: decelerating
    assert smoothing.tick(1.10) == pytest.approx((0.05, 0.0, 0.0))
    assert smoothing.tick(1.15) == (0.0, 0.0, 0.0)  # the zero is sent once ...
    assert smoothing.tick(1.20) is None and smoothing.idle  # ... then nothing
    smoothing.command((0.1, 0.0, 0.0), 1.25)
    assert not smoothing.idle and smoothing.tick(1.30) == pytest.approx((0.1, 0.0, 0.0))


def test_nothing_is_sent_before_the_first_command():
    smoothing = VelocitySmoothing(LIMITS, timeout_s=1.0)
    assert smoothing.tick(0.05) is None and smoothing.idle


def test_a_non_finite_command_is_refused_and_the_previous_one_kept():
    smoothing = VelocitySmoothing(LIMITS, timeout_s=1.0)
    smoothing.command((0.2, 0.0, 0.0), 0.0)
    with pytest.raises(VelocitySmootherError, match="not finite"):
        smoothing.command((math.nan, 0.0, 0.0), 0.01)
    assert smoothing.tick(0.05) == pytest.approx((0.125, 0.0, 0.0))


def test_closed_loop_starts_from_the_measured_velocity():
    smoothing = VelocitySmoothing(LIMITS, timeout_s=1.0)
    smoothing.command((0.5, 0.0, 0.0), 0.0)
    assert smoothing.tick(0.05, measured=(0.3, 0.0, 0.0)) == pytest.approx((0.425, 0.0, 0.0))


def test_odometry_is_averaged_over_its_window():
    odom = OdomAverage(0.1)
    assert odom.velocity() == (0.0, 0.0, 0.0)
    for stamp_s, vx in ((0.0, 1.0), (0.05, 0.2), (0.1, 0.4), (0.15, 0.6)):
        odom.add(stamp_s, (vx, 0.0, 0.0))
    assert odom.velocity()[0] == pytest.approx(0.4)  # 0.2, 0.4 and 0.6: the first is too old


@pytest.mark.parametrize("changes, parameter", [
    ({"max_decel": (2.5, 0.0, -3.2)}, "max_decel"),
    ({"max_accel": (-2.5, 0.0, 3.2)}, "max_accel"),
    ({"max_velocity": (0.5, 0.0)}, "max_velocity"),
    ({"min_velocity": (0.1, 0.0, -2.0)}, "min_velocity"),
    ({"deadband": (0.0, -0.1, 0.0)}, "deadband_velocity"),
    ({"frequency_hz": 0.0}, "smoothing_frequency"),
])
def test_bad_limits_are_refused_naming_the_parameter(changes, parameter):
    with pytest.raises(VelocitySmootherError, match=parameter) as caught:
        with_(**changes).validate()
    assert caught.value.parameter == parameter


def test_feedback_names_its_choices():
    assert feedback_of("CLOSED_LOOP") is Feedback.CLOSED_LOOP
    with pytest.raises(VelocitySmootherError, match="OPEN_LOOP, CLOSED_LOOP"):
        feedback_of("closed")
