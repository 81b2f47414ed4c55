"""The velocity smoother node over DDS: quiet until active, then a ramp within the acceleration
limit, a stop once commands end, and bad parameters refused at configure by name."""
from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import pytest
from geometry_msgs.msg import Twist
from lifecycle_msgs.msg import Transition
from rclpy.lifecycle import TransitionCallbackReturn
from rclpy.node import Node
from rclpy.parameter import Parameter

from pppbot_common.ros.wait import change_state, wait_until
from pppbot_nav.ros.velocity_smoother import VelocitySmoother

pytestmark = pytest.mark.ros


@pytest.fixture
def spin(spin_in_background: Callable[..., Any]) -> Callable[[Node], None]:
    """``spin(node)``: spin ``node`` in an executor thread until the test ends (then destroy it)."""
    return spin_in_background


def forward(x: float) -> Twist:
    msg = Twist()
    msg.linear.x = x
    return msg


def listen(ros_node: Node, smoother: VelocitySmoother) -> tuple[list[Twist], Any]:
    """The smoothed outputs as received, and a command publisher, both matched with the node."""
    received: list[Twist] = []
    ros_node.create_subscription(Twist, "cmd_vel_smoothed", received.append, 100)
    commands = ros_node.create_publisher(Twist, "cmd_vel", 10)
    wait_until(lambda: commands.get_subscription_count() > 0 and smoother.output.get_subscription_count() > 0,
               10, "the smoother's topics matched", node=ros_node)
    return received, commands


def test_nothing_is_published_until_active_then_the_output_ramps(ros_node, spin):
    smoother = VelocitySmoother(parameter_overrides=[Parameter("velocity_timeout", value=60.0)])
    spin(smoother)
    assert change_state(ros_node, "velocity_smoother", Transition.TRANSITION_CONFIGURE)
    received, commands = listen(ros_node, smoother)
    commands.publish(forward(0.4))
    wait_until(lambda: smoother.ignored_inactive == 1, 10, "the command reaching the inactive node", node=ros_node)
    assert change_state(ros_node, "velocity_smoother", Transition.TRANSITION_ACTIVATE)
    commands.publish(forward(0.4))
    wait_until(lambda: len(received) >= 5, 10, "five smoothed commands", node=ros_node)
    # The first message is the ramp's first step: nothing was published while inactive (DDS keeps
    # one writer's order), and each period adds at most max_accel / smoothing_frequency.
    assert [m.linear.x for m in received[:5]] == pytest.approx([0.125, 0.25, 0.375, 0.4, 0.4])


def test_when_commands_end_the_robot_is_slowed_to_zero_and_left_alone(ros_node, spin):
    smoother = VelocitySmoother(parameter_overrides=[Parameter("velocity_timeout", value=0.5)])
    spin(smoother)
    assert change_state(ros_node, "velocity_smoother", Transition.TRANSITION_CONFIGURE)
    assert change_state(ros_node, "velocity_smoother", Transition.TRANSITION_ACTIVATE)
    received, commands = listen(ros_node, smoother)
    commands.publish(forward(0.3))
    smoothing = smoother.smoothing
    assert smoothing is not None
    wait_until(lambda: received and received[-1].linear.x == 0.0 and smoothing.idle, 20,
               "the smoother stopping", node=ros_node)
    xs = [m.linear.x for m in received]
    assert max(xs) > 0.0 and 0.0 not in xs[:-1]  # one zero, at the end
    assert all(abs(b - a) <= 0.125 + 1e-9 for a, b in zip([0.0, *xs], xs, strict=False))


def test_a_non_finite_command_is_dropped_and_the_node_goes_on():
    import rclpy

    rclpy.init()
    try:
        smoother = VelocitySmoother()
        assert smoother.trigger_configure() == TransitionCallbackReturn.SUCCESS
        assert smoother.trigger_activate() == TransitionCallbackReturn.SUCCESS
        assert smoother.smoothing is not None
        smoother._on_command(forward(math.nan))
        assert smoother.smoothing.idle  # not taken
        smoother._on_command(forward(0.2))
        assert not smoother.smoothing.idle
        smoother.destroy_node()
    finally:
        rclpy.shutdown()


def test_commands_at_one_instant_give_one_output_the_newest_at_the_next_period():
    """A wall-clock publisher in lockstep can send several commands within one sim instant: each
    replaces the last (one output per instant, as downstream depth-1 subscriptions count on)."""
    import rclpy

    rclpy.init()
    try:
        smoother = VelocitySmoother(parameter_overrides=[Parameter("use_sim_time", value=True)])
        assert smoother.trigger_configure() == TransitionCallbackReturn.SUCCESS
        assert smoother.trigger_activate() == TransitionCallbackReturn.SUCCESS
        sent: list[Any] = []
        smoother.output.publish = sent.append
        for x in (0.1, 0.3, 0.2):  # the sim clock stands still (no /clock)
            smoother._on_command(forward(x))
        assert len(sent) == 1
        command = smoother.smoothing._command if smoother.smoothing is not None else None
        assert command is not None and command[0] == pytest.approx(0.2)  # the newest
        smoother.destroy_node()
    finally:
        rclpy.shutdown()


@pytest.mark.parametrize("name, value", [
    ("max_decel", [2.5, 0.0, -3.2]), ("max_accel", [2.5, -1.0, 3.2]), ("max_velocity", [0.5, 2.0]),
    ("feedback", "CLOSED"), ("smoothing_frequency", 0.0), ("deadband_velocity", [0.0, 0.0, math.inf]),
])
def test_bad_parameters_fail_configure_naming_them(name: str, value: Any):
    import rclpy

    rclpy.init()
    try:
        smoother = VelocitySmoother(parameter_overrides=[Parameter(name, value=value)])
        assert smoother.trigger_configure() == TransitionCallbackReturn.FAILURE
        assert f"'{name}'" in smoother.configure_failure and smoother.state == "unconfigured"
        smoother.destroy_node()
    finally:
        rclpy.shutdown()


def test_live_limits_apply_to_the_running_smoother_and_the_rest_waits_for_configure():
    import rclpy

    rclpy.init()
    try:
        smoother = VelocitySmoother()
        assert smoother.trigger_configure() == TransitionCallbackReturn.SUCCESS
        assert smoother.trigger_activate() == TransitionCallbackReturn.SUCCESS
        smoothing = smoother.smoothing
        assert smoothing is not None
        smoother._on_command(forward(0.4))
        assert smoother.set_parameters([Parameter("max_velocity", value=[0.2, 0.0, 1.0])])[0].successful
        assert smoother.smoothing is smoothing and smoothing.limits.max_velocity[0] == pytest.approx(0.2)
        assert not smoothing.idle  # the command given before the set is still there
        refused = smoother.set_parameters([Parameter("smoothing_frequency", value=10.0)])[0]
        assert not refused.successful and "read at configure" in refused.reason
        assert smoother.trigger_deactivate() == TransitionCallbackReturn.SUCCESS
        assert smoother.trigger_cleanup() == TransitionCallbackReturn.SUCCESS
        assert smoother.set_parameters([Parameter("smoothing_frequency", value=10.0)])[0].successful
        assert smoother.trigger_configure() == TransitionCallbackReturn.SUCCESS
        assert smoother.smoothing is not None and smoother.smoothing.limits.frequency_hz == pytest.approx(10.0)
        smoother.destroy_node()
    finally:
        rclpy.shutdown()
