"""twist_mux arbitration: priority, timeouts, locks, and one zero when the winner goes quiet."""
from __future__ import annotations

import pytest

from pppbot_control.mux import MuxConfigError, TwistMux, parse_config

TOPICS = {
    "navigation": {"topic": "cmd_vel", "timeout": 0.5, "priority": 10},
    "teleop": {"topic": "cmd_vel_teleop", "timeout": 0.5, "priority": 100},
}


def make(locks=None) -> TwistMux:
    inputs, lock_specs = parse_config(TOPICS, locks or {})
    return TwistMux(inputs, lock_specs)


def test_only_input_passes_through():
    mux = make()
    assert mux.on_input("navigation", "nav1", 0.0) == "nav1"


def test_teleop_overrides_navigation_and_expires():
    mux = make()
    mux.on_input("navigation", "nav", 0.0)
    assert mux.on_input("teleop", "tele", 0.1) == "tele"
    assert mux.on_input("navigation", "nav", 0.2) is None  # teleop still fresh
    assert mux.check_timeouts(0.55) is False  # navigation active: it takes over, no zero
    assert mux.on_input("navigation", "nav", 0.7) == "nav"


def test_one_zero_when_the_winner_goes_quiet():
    mux = make()
    mux.on_input("teleop", "tele", 0.0)
    assert mux.check_timeouts(0.4) is False
    assert mux.check_timeouts(0.6) is True
    assert mux.check_timeouts(0.7) is False  # only once


def test_locks_block_lower_priorities():
    mux = make({"pause": {"topic": "pause_navigation", "timeout": 0.0, "priority": 50}})
    mux.on_lock("pause", True, 0.0)
    assert mux.on_input("navigation", "nav", 0.1) is None
    assert mux.on_input("teleop", "tele", 0.2) == "tele"
    mux.on_lock("pause", False, 0.3)
    assert mux.on_input("navigation", "nav", 0.8) == "nav"


def test_a_silent_watchdog_lock_locks():
    mux = make({"watchdog": {"topic": "heartbeat", "timeout": 1.0, "priority": 200}})
    assert mux.on_input("teleop", "tele", 0.0) is None  # never heard from: locked
    mux.on_lock("watchdog", False, 0.1)
    assert mux.on_input("teleop", "tele", 0.2) == "tele"
    assert mux.check_timeouts(1.2) is True  # heartbeat gone: lock engages, stop once


@pytest.mark.parametrize("topics, message", [
    ({"a": {"topic": "x", "timeout": 0.5}}, "topics.a: missing priority"),
    ({"a": {"topic": "x", "timeout": -1, "priority": 1}}, "topics.a.timeout = -1"),
    ({"a": {"topic": "x", "timeout": 1, "priority": 300}},
     r"topics.a.priority = 300: must be an integer in \[0, 255\]"),
    ({"a": {"topic": "x", "timeout": 1, "priority": 1}, "b": {"topic": "x", "timeout": 1, "priority": 2}},
     "'b' and 'a' both use topic 'x'"),
    ({}, "no input topics configured"),
])
def test_bad_config_is_named(topics, message):
    with pytest.raises(MuxConfigError, match=message):
        parse_config(topics, {})


def test_zero_timeout_never_expires():
    inputs, _ = parse_config({"joystick": {"topic": "joy_vel", "timeout": 0, "priority": 50}}, {})
    mux = TwistMux(inputs)
    assert mux.on_input("joystick", "joy", 0.0) == "joy"
    assert mux.check_timeouts(1000.0) is False
    assert mux.winner(1000.0) == "joystick"
