"""teleop_twist_keyboard's key map and speed rules."""
from __future__ import annotations

import pytest

from pppbot_control.teleop import TeleopState, Twist


@pytest.mark.parametrize("key, twist", [
    ("i", Twist(0.5, 0, 0, 0)), (",", Twist(-0.5, 0, 0, 0)), ("j", Twist(0, 0, 0, 1.0)),
    ("l", Twist(0, 0, 0, -1.0)), ("u", Twist(0.5, 0, 0, 1.0)), ("o", Twist(0.5, 0, 0, -1.0)),
    ("m", Twist(-0.5, 0, 0, -1.0)), (".", Twist(-0.5, 0, 0, 1.0)), ("J", Twist(0, 0.5, 0, 0)),
    ("t", Twist(0, 0, 0.5, 0)), ("k", Twist()), ("?", Twist()),
])
def test_move_keys(key, twist):
    state = TeleopState()
    state.press("i")
    state.press(key)
    assert state.twist() == twist


def test_speed_keys_scale_and_report():
    state = TeleopState()
    assert state.press("q") is True
    assert (state.speed, state.turn) == pytest.approx((0.55, 1.1))
    state.press("x")
    state.press("e")
    assert (state.speed, state.turn) == pytest.approx((0.495, 1.21))
    state.press("i")
    assert state.twist().linear_x == pytest.approx(0.495)
    assert state.speeds_line() == "currently:\tspeed 0.495\tturn 1.21 "
