"""teleop_twist_joy's mapping (enable and turbo buttons, scales, the one stop on release, axes a
message lacks, inverted reverse, the deadzone's effect), its parameters, and the two nodes over DDS:
joy_node reading a pty that stands in for /dev/input/js0, teleop_twist_joy_node turning its Joy
into cmd_vel, in one process and as the executables with ppp_bot's config/joystick.yaml."""
from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import pytest

from pppbot_common.errors import ParameterError
from pppbot_common.ros.wait import wait_until
from pppbot_control.joystick import EventKind, JoySettings, Joystick, JsEvent
from pppbot_control.teleop_joy import TeleopJoyConfig, TeleopTwistJoy, TwistCommand

REPO = Path(__file__).resolve().parents[2]
PPPBOT = str(REPO / "pppbot")
JOYSTICK_YAML = REPO / "config" / "joystick.yaml"

#: ppp_bot's config/joystick.yaml: stick axis 1 forward, axis 0 turns; hold button 6 (7: turbo).
PPP_BOT = TeleopJoyConfig(axis_linear={"x": 1}, scale_linear={"x": 0.5}, scale_linear_turbo={"x": 1.0},
                          axis_angular={"yaw": 0}, scale_angular={"yaw": 0.5}, scale_angular_turbo={"yaw": 1.0},
                          enable_button=6, enable_turbo_button=7, require_enable_button=True)
ENABLE, TURBO = 6, 7
STICK = [0.2, 0.8]  # axis 0: a little left; axis 1: mostly forward


def buttons(*pressed: int, count: int = 11) -> list[int]:
    return [1 if i in pressed else 0 for i in range(count)]


def drive(teleop: TeleopTwistJoy, axes: Sequence[float], held: Sequence[int]) -> TwistCommand | None:
    return teleop.on_joy(axes, buttons(*held))


# ----------------------------------------------------------------------------- the mapping
def test_the_enable_button_drives_at_the_normal_scales():
    assert drive(TeleopTwistJoy(PPP_BOT), STICK, [ENABLE]) == TwistCommand(linear_x=0.4, angular_z=0.1)


def test_the_turbo_button_drives_at_the_turbo_scales_with_or_without_the_enable_button():
    teleop = TeleopTwistJoy(PPP_BOT)
    assert drive(teleop, STICK, [ENABLE, TURBO]) == TwistCommand(linear_x=0.8, angular_z=0.2)
    assert drive(teleop, STICK, [TURBO]) == TwistCommand(linear_x=0.8, angular_z=0.2)  # as upstream


def test_without_the_enable_button_one_zero_goes_out_and_then_nothing():
    teleop = TeleopTwistJoy(PPP_BOT)
    assert drive(teleop, STICK, [ENABLE]) == TwistCommand(linear_x=0.4, angular_z=0.1)
    assert drive(teleop, STICK, []) == TwistCommand()  # released: stop the robot, once
    assert drive(teleop, STICK, []) is None
    assert drive(teleop, STICK, [3]) is None  # another button enables nothing
    assert drive(teleop, STICK, [ENABLE]) == TwistCommand(linear_x=0.4, angular_z=0.1)
    assert drive(teleop, STICK, []) == TwistCommand()  # and once again after the next release


def test_the_first_message_without_the_enable_button_sends_the_one_zero():
    teleop = TeleopTwistJoy(PPP_BOT)
    assert drive(teleop, STICK, []) == TwistCommand()
    assert drive(teleop, STICK, []) is None


def test_without_require_enable_button_the_stick_always_drives():
    teleop = TeleopTwistJoy(TeleopJoyConfig(**{**PPP_BOT.__dict__, "require_enable_button": False}))
    assert drive(teleop, STICK, []) == TwistCommand(linear_x=0.4, angular_z=0.1)
    assert drive(teleop, [0.0, 0.0], []) == TwistCommand()  # a centred stick: a zero twist, every time
    assert drive(teleop, [0.0, 0.0], []) == TwistCommand()
    assert drive(teleop, STICK, [TURBO]) == TwistCommand(linear_x=0.8, angular_z=0.2)


def test_every_twist_field_has_its_axis_and_scale():
    config = TeleopJoyConfig(axis_linear={"x": 0, "y": 1, "z": 2}, scale_linear={"x": 1.0, "y": 2.0, "z": 3.0},
                             axis_angular={"yaw": 3, "pitch": 4, "roll": 5},
                             scale_angular={"yaw": 4.0, "pitch": 5.0, "roll": 6.0},
                             enable_button=0)
    assert TeleopTwistJoy(config).on_joy([0.5] * 6, [1]) == TwistCommand(0.5, 1.0, 1.5, 3.0, 2.5, 2.0)


def test_an_axis_or_button_the_message_lacks_counts_as_zero():
    config = TeleopJoyConfig(axis_linear={"x": 1, "y": -1, "z": 9}, scale_linear={"x": 0.5, "y": 1.0, "z": 1.0},
                             axis_angular={"yaw": 0}, scale_angular={"yaw": 0.5}, enable_button=6)
    teleop = TeleopTwistJoy(config)
    assert teleop.on_joy([0.2, 0.8], [0, 0, 0, 0, 0, 0, 1]) == TwistCommand(linear_x=0.4, angular_z=0.1)
    assert teleop.on_joy([0.2], [0, 0, 0, 0, 0, 0, 1]) == TwistCommand(angular_z=0.1)  # no axis 1
    assert teleop.on_joy([0.2, 0.8], [1]) == TwistCommand()  # no button 6: not enabled


def test_inverted_reverse_turns_the_yaw_around_when_driving_backwards():
    teleop = TeleopTwistJoy(TeleopJoyConfig(**{**PPP_BOT.__dict__, "inverted_reverse": True}))
    assert drive(teleop, [0.2, 0.8], [ENABLE]) == TwistCommand(linear_x=0.4, angular_z=0.1)
    assert drive(teleop, [0.2, -0.8], [ENABLE]) == TwistCommand(linear_x=-0.4, angular_z=-0.1)
    assert drive(TeleopTwistJoy(PPP_BOT), [0.2, -0.8], [ENABLE]) == TwistCommand(linear_x=-0.4, angular_z=0.1)


def test_a_stick_inside_joys_deadzone_does_not_move_the_robot():
    """Raw readings through joy's core into teleop: a stick resting a little off centre gives a
    zero twist, full forward gives the whole scale."""
    joystick = Joystick(JoySettings(deadzone=0.05, coalesce_interval_s=0.0), axes=8, buttons=11)
    teleop = TeleopTwistJoy(PPP_BOT)
    joystick.on_event(JsEvent(0, 1, EventKind.BUTTON, ENABLE), 0.0)
    for raw_turn, raw_forward, expected in [(900, -1500, TwistCommand()),
                                            (0, -32767, TwistCommand(linear_x=0.5)),
                                            (32767, 0, TwistCommand(angular_z=-0.5))]:
        joystick.on_event(JsEvent(0, raw_turn, EventKind.AXIS, 0), 1.0)
        joystick.on_event(JsEvent(0, raw_forward, EventKind.AXIS, 1), 1.0)
        state = joystick.state
        assert teleop.on_joy(state.axes, state.buttons) == pytest.approx(expected)


# ----------------------------------------------------------------------------- parameters
def test_parameters_map_to_the_config_by_their_ros_names():
    from pppbot_common.params import from_values
    from pppbot_control.ros.teleop_joy import TeleopTwistJoyParameters

    params = from_values(TeleopTwistJoyParameters, {"axis_linear.x": 1, "scale_linear.x": 0.5, "axis_angular.yaw": 0,
                                                    "scale_angular_turbo.yaw": 1, "enable_button": 6})
    config = params.config()
    assert config.axis_linear == {"x": 1, "y": -1, "z": -1}
    assert config.axis_angular == {"yaw": 0, "pitch": -1, "roll": -1}
    assert config.scale_angular_turbo == {"yaw": 1.0, "pitch": 0.0, "roll": 0.0}
    assert (config.enable_button, config.enable_turbo_button, config.require_enable_button) == (6, -1, True)
    assert TeleopTwistJoyParameters().config() == TeleopJoyConfig()  # teleop_twist_joy's defaults


@pytest.mark.parametrize(("name", "value", "message"), [
    ("axis_linear.x", -2, "'axis_linear.x' = -2: must be an axis index"),
    ("axis_angular.roll", -5, "'axis_angular.roll' = -5"),
    ("scale_angular.yaw", math.nan, "'scale_angular.yaw' = nan: must be a finite number"),
    ("enable_button", -3, "'enable_button' = -3: must be a button index"),
])
def test_bad_parameters_are_refused_by_name(name: str, value: float, message: str):
    from pppbot_common.params import from_values
    from pppbot_control.ros.teleop_joy import TeleopTwistJoyParameters

    with pytest.raises(ParameterError, match=message):
        from_values(TeleopTwistJoyParameters, {name: value})


# ----------------------------------------------------------------------------- over DDS
@pytest.mark.ros
def test_joystick_to_cmd_vel_through_both_nodes(ros_node, spin_in_background, pty_joystick):
    from geometry_msgs.msg import Twist
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import Joy

    from pppbot_control.ros.joy_node import JoyNode
    from pppbot_control.ros.teleop_joy import TeleopTwistJoyNode

    pad = pty_joystick()
    overrides = {"axis_linear.x": 1, "scale_linear.x": 0.5, "scale_linear_turbo.x": 1.0, "axis_angular.yaw": 0,
                 "scale_angular.yaw": 0.5, "scale_angular_turbo.yaw": 1.0, "enable_button": 6,
                 "enable_turbo_button": 7, "require_enable_button": True}
    teleop = TeleopTwistJoyNode(parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()])
    twists: list[Twist] = []
    ros_node.create_subscription(Twist, "cmd_vel", twists.append, 100)
    joys: list[Joy] = []
    ros_node.create_subscription(Joy, "joy", joys.append, 100)
    spin_in_background(teleop)
    wait_until(lambda: teleop.pub.get_subscription_count() > 0, 10, "cmd_vel matched", node=ros_node)
    joy = JoyNode(parameter_overrides=[Parameter("dev", value=str(pad.path)), Parameter("autorepeat_rate", value=20.0)])
    spin_in_background(joy)
    wait_until(lambda: joy.pub.get_subscription_count() >= 2, 10, "joy matched by teleop and the test", node=ros_node)

    pad.init(axes=[0] * 8, buttons=[0] * 11)
    wait_until(lambda: twists, 10, "the zero for a joystick at rest", node=ros_node)
    assert len(twists) == 1 and twists[0] == Twist()  # one zero, not one per autorepeat
    pad.button(ENABLE, True)
    pad.axis(1, -32767)  # full forward
    pad.axis(0, 16384)  # half right
    wait_until(lambda: twists[-1].linear.x == 0.5 and twists[-1].angular.z < 0, 10, "forward and right",
               node=ros_node)
    assert twists[-1].angular.z == pytest.approx(-0.5 * (16384 - 1638.35) / (32767 - 1638.35), rel=1e-6)
    pad.button(TURBO, True)
    wait_until(lambda: twists[-1].linear.x == 1.0, 10, "turbo", node=ros_node)
    pad.button(TURBO, False)
    pad.button(ENABLE, False)
    wait_until(lambda: twists[-1] == Twist(), 10, "the stop on release", node=ros_node)
    stops, seen = len(twists), len(joys)
    # joy repeats its state at 20 Hz; teleop sends nothing more for a released button.
    wait_until(lambda: len(joys) >= seen + 5, 10, "five more Joy messages", node=ros_node)
    assert len(twists) == stops


@pytest.mark.ros
def test_publish_stamped_twist_stamps_with_the_frame(ros_node, spin_in_background):
    from geometry_msgs.msg import TwistStamped
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import Joy

    from pppbot_control.ros.teleop_joy import TeleopTwistJoyNode

    teleop = TeleopTwistJoyNode(parameter_overrides=[Parameter("publish_stamped_twist", value=True),
                                                     Parameter("frame", value="base_link"),
                                                     Parameter("require_enable_button", value=False)])
    twists: list[TwistStamped] = []
    ros_node.create_subscription(TwistStamped, "cmd_vel", twists.append, 10)
    joy_pub = ros_node.create_publisher(Joy, "joy", 10)
    spin_in_background(teleop)
    wait_until(lambda: teleop.pub.get_subscription_count() > 0 and joy_pub.get_subscription_count() > 0, 10,
               "both topics matched", node=ros_node)
    joy_pub.publish(Joy(axes=[0.0, 0.0, 0.5, 0.0, 0.0, 1.0], buttons=[0] * 6))  # defaults: x on axis 5, yaw on 2
    wait_until(lambda: twists, 10, "a TwistStamped", node=ros_node)
    msg = twists[0]
    assert (msg.header.frame_id, msg.twist.linear.x, msg.twist.angular.z) == ("base_link", 0.5, 0.25)
    assert msg.header.stamp.sec > 0


@pytest.mark.ros
def test_the_executables_with_ppp_bots_joystick_yaml(ros_node, spawn, pty_joystick):
    """``joy_node`` and ``teleop_node`` as users start them (teleop named ``teleop_node``, as
    ppp_bot's launch file names it, so that the file's section applies)."""
    from geometry_msgs.msg import Twist

    pad = pty_joystick()
    twists: list[Twist] = []
    ros_node.create_subscription(Twist, "cmd_vel", twists.append, 100)
    teleop = spawn([PPPBOT, "run", "pppbot_control", "teleop_node", "--ros-args", "--params-file", str(JOYSTICK_YAML),
                    "-r", "__node:=teleop_node"], name="teleop_node")
    joy = spawn([PPPBOT, "run", "pppbot_control", "joy_node", "--ros-args", "--params-file", str(JOYSTICK_YAML),
                 "-p", f"dev:={pad.path}"], name="joy_node")
    joy.wait_for_output(r"opened joystick \(no name\) at /dev/pts/", 60)
    teleop.wait_for_output(r"Teleop enable button 6\.", 60)
    wait_until(lambda: ros_node.count_publishers("/cmd_vel") and ros_node.count_subscribers("/joy"), 30,
               "teleop_node in the graph", node=ros_node)
    pad.init(axes=[0] * 8, buttons=[0] * 11)
    pad.button(ENABLE, True)
    pad.axis(1, -32767)
    wait_until(lambda: twists and twists[-1].linear.x == 0.5, 30, "forward at scale_linear.x", node=ros_node)
    assert joy.running() and teleop.running()


@pytest.mark.ros
def test_parameters_change_at_run_time_and_bad_ones_are_refused(ros_node):
    from geometry_msgs.msg import Twist, TwistStamped
    from rclpy.parameter import Parameter

    from pppbot_control.ros.teleop_joy import TeleopTwistJoyNode

    teleop = TeleopTwistJoyNode()
    try:
        assert teleop.set_parameters([Parameter("scale_linear.x", value=2.0)])[0].successful
        assert teleop.teleop.config.scale_linear["x"] == 2.0
        refused = teleop.set_parameters([Parameter("axis_angular.yaw", value=-2)])[0]
        assert not refused.successful and "'axis_angular.yaw' = -2" in refused.reason
        assert teleop.teleop.config.axis_angular["yaw"] == 2
        assert teleop.pub.msg_type is Twist
        assert teleop.set_parameters([Parameter("publish_stamped_twist", value=True)])[0].successful
        assert teleop.pub.msg_type is TwistStamped
    finally:
        teleop.destroy_node()
