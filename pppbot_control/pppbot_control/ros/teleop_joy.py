"""``teleop_node``: teleop_twist_joy for pppbot (node ``teleop_twist_joy_node``).

Subscribes sensor_msgs/Joy on ``joy``; publishes on ``cmd_vel`` a geometry_msgs/Twist, or a
TwistStamped (stamped with the node's clock, frame ``frame``) with ``publish_stamped_twist``.
Parameters as teleop_twist_joy's, with its defaults: ``axis_linear.{x,y,z}``,
``scale_linear.{x,y,z}``, ``scale_linear_turbo.{x,y,z}``, ``axis_angular.{yaw,pitch,roll}``,
``scale_angular.*``, ``scale_angular_turbo.*``, ``enable_button``, ``enable_turbo_button``,
``require_enable_button``, ``inverted_reverse``; all may be changed at run time. The mapping is
:mod:`pppbot_control.teleop_joy`.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import Any

from geometry_msgs.msg import Twist, TwistStamped
from sensor_msgs.msg import Joy

from pppbot_common.params import ParameterError, check_finite_range, param
from pppbot_common.ros.params import declare_parameters, on_valid_update
from pppbot_control.teleop_joy import ANGULAR_FIELDS, LINEAR_FIELDS, TeleopJoyConfig, TeleopTwistJoy, TwistCommand
from pppbot_lockstep.ros.node import StepNode
from pppbot_lockstep.ros.runner import guarded, run_node

AXIS = "joystick axis for {}; -1 = unused"
SCALE = "{} per unit of axis at {} speed"


@dataclass(frozen=True)
class TeleopTwistJoyParameters:
    require_enable_button: bool = param(True, "drive only while enable_button (or the turbo button) is held")
    enable_button: int = param(5, "joystick button that enables normal-speed driving; -1 = none")
    enable_turbo_button: int = param(-1, "joystick button that enables turbo-speed driving; -1 = none")
    inverted_reverse: bool = param(False, "turn the yaw around while driving backwards")
    publish_stamped_twist: bool = param(False, "publish TwistStamped instead of Twist")
    frame: str = param("teleop_twist_joy", "frame_id of TwistStamped messages")
    axis_linear_x: int = param(5, AXIS.format("linear.x"), "axis_linear.x")
    axis_linear_y: int = param(-1, AXIS.format("linear.y"), "axis_linear.y")
    axis_linear_z: int = param(-1, AXIS.format("linear.z"), "axis_linear.z")
    scale_linear_x: float = param(0.5, SCALE.format("m/s", "normal"), "scale_linear.x")
    scale_linear_y: float = param(0.0, SCALE.format("m/s", "normal"), "scale_linear.y")
    scale_linear_z: float = param(0.0, SCALE.format("m/s", "normal"), "scale_linear.z")
    scale_linear_turbo_x: float = param(1.0, SCALE.format("m/s", "turbo"), "scale_linear_turbo.x")
    scale_linear_turbo_y: float = param(0.0, SCALE.format("m/s", "turbo"), "scale_linear_turbo.y")
    scale_linear_turbo_z: float = param(0.0, SCALE.format("m/s", "turbo"), "scale_linear_turbo.z")
    axis_angular_yaw: int = param(2, AXIS.format("angular.z (yaw)"), "axis_angular.yaw")
    axis_angular_pitch: int = param(-1, AXIS.format("angular.y (pitch)"), "axis_angular.pitch")
    axis_angular_roll: int = param(-1, AXIS.format("angular.x (roll)"), "axis_angular.roll")
    scale_angular_yaw: float = param(0.5, SCALE.format("rad/s", "normal"), "scale_angular.yaw")
    scale_angular_pitch: float = param(0.0, SCALE.format("rad/s", "normal"), "scale_angular.pitch")
    scale_angular_roll: float = param(0.0, SCALE.format("rad/s", "normal"), "scale_angular.roll")
    scale_angular_turbo_yaw: float = param(1.0, SCALE.format("rad/s", "turbo"), "scale_angular_turbo.yaw")
    scale_angular_turbo_pitch: float = param(0.0, SCALE.format("rad/s", "turbo"), "scale_angular_turbo.pitch")
    scale_angular_turbo_roll: float = param(0.0, SCALE.format("rad/s", "turbo"), "scale_angular_turbo.roll")

    def _group(self, prefix: str, names: tuple[str, ...]) -> dict[str, Any]:
        return {name: getattr(self, f"{prefix}_{name}") for name in names}

    def validate(self) -> None:
        for prefix, names in (("axis_linear", LINEAR_FIELDS), ("axis_angular", ANGULAR_FIELDS)):
            for name, index in self._group(prefix, names).items():
                if index < -1:
                    raise ParameterError(f"{prefix}.{name}", index, "must be an axis index (>= 0) or -1 (unused)")
        for prefix, names in (("scale_linear", LINEAR_FIELDS), ("scale_linear_turbo", LINEAR_FIELDS),
                              ("scale_angular", ANGULAR_FIELDS), ("scale_angular_turbo", ANGULAR_FIELDS)):
            for name, scale in self._group(prefix, names).items():
                check_finite_range(f"{prefix}.{name}", scale)
        for name in ("enable_button", "enable_turbo_button"):
            if getattr(self, name) < -1:
                raise ParameterError(name, getattr(self, name), "must be a button index (>= 0) or -1 (none)")

    def config(self) -> TeleopJoyConfig:
        return TeleopJoyConfig(
            axis_linear=self._group("axis_linear", LINEAR_FIELDS),
            scale_linear=self._group("scale_linear", LINEAR_FIELDS),
            scale_linear_turbo=self._group("scale_linear_turbo", LINEAR_FIELDS),
            axis_angular=self._group("axis_angular", ANGULAR_FIELDS),
            scale_angular=self._group("scale_angular", ANGULAR_FIELDS),
            scale_angular_turbo=self._group("scale_angular_turbo", ANGULAR_FIELDS),
            enable_button=self.enable_button, enable_turbo_button=self.enable_turbo_button,
            require_enable_button=self.require_enable_button, inverted_reverse=self.inverted_reverse)


class TeleopTwistJoyNode(StepNode):
    def __init__(self, **kwargs: object) -> None:
        super().__init__("teleop_twist_joy_node", **kwargs)  # type: ignore[arg-type]
        self.params = declare_parameters(self, TeleopTwistJoyParameters)
        self.teleop = TeleopTwistJoy(self.params.config())
        self.pub = self._publisher(self.params.publish_stamped_twist)
        self.create_subscription(Joy, "joy", guarded(self, self.on_joy, "Joy"), 10)
        on_valid_update(self, lambda: self.params, self._apply)
        self._describe()

    def _publisher(self, stamped: bool) -> Any:
        return self.create_publisher(TwistStamped if stamped else Twist, "cmd_vel", 10)

    def _apply(self, params: TeleopTwistJoyParameters) -> None:
        if params.publish_stamped_twist != self.params.publish_stamped_twist:
            self.destroy_publisher(self.pub)
            self.pub = self._publisher(params.publish_stamped_twist)
        self.params = params
        self.teleop.config = params.config()

    def _describe(self) -> None:
        p, log = self.params, self.get_logger()
        if p.require_enable_button:
            log.info(f"Teleop enable button {p.enable_button}.")
        if p.enable_turbo_button >= 0:
            log.info(f"Turbo on button {p.enable_turbo_button}.")
        config = p.config()
        groups = (("Linear", config.axis_linear, config.scale_linear, config.scale_linear_turbo),
                  ("Angular", config.axis_angular, config.scale_angular, config.scale_angular_turbo))
        for kind, axes, normal, turbo in groups:
            for name, index in axes.items():
                if index >= 0:
                    turbo_text = f" (turbo {turbo[name]:g})" if p.enable_turbo_button >= 0 else ""
                    log.info(f"{kind} axis {name} on {index} at scale {normal[name]:g}{turbo_text}.")

    def on_joy(self, msg: Joy) -> None:
        twist = self.teleop.on_joy(msg.axes, msg.buttons)
        if twist is not None:
            self.publish(twist)

    def publish(self, twist: TwistCommand) -> None:
        msg: Any = TwistStamped() if self.params.publish_stamped_twist else Twist()
        body = msg.twist if self.params.publish_stamped_twist else msg
        if self.params.publish_stamped_twist:
            msg.header.stamp = self.get_clock().now().to_msg()
            msg.header.frame_id = self.params.frame
        body.linear.x, body.linear.y, body.linear.z = twist.linear_x, twist.linear_y, twist.linear_z
        body.angular.x, body.angular.y, body.angular.z = twist.angular_x, twist.angular_y, twist.angular_z
        self.pub.publish(msg)


def main(args: list[str] | None = None) -> int:
    return run_node(TeleopTwistJoyNode, "teleop_twist_joy_node", args, fatal=(ParameterError,))


if __name__ == "__main__":
    sys.exit(main())
