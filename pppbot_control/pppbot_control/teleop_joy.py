"""teleop_twist_joy's mapping from a joystick's axes and buttons to a twist, without ROS.

As ``teleop_twist_joy`` (ros2/teleop_twist_joy) does it, for each Joy message:

* the turbo button (``enable_turbo_button`` >= 0, pressed) drives with the turbo scales, whether
  or not the enable button is held;
* else the enable button pressed, or ``require_enable_button`` false, drives with the normal scales;
* else one zero twist goes out, the first time (the robot stops when the button is released;
  later messages without it send nothing, so other sources of commands are not overridden).

Each twist field is ``axes[axis] * scale``; an axis of -1, or one the message does not have, gives
0. ``inverted_reverse`` turns the yaw around while driving backwards (as a car steers in reverse).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from enum import Enum

#: Twist fields driven by axes: linear (``axis_linear.<name>``) and angular (``axis_angular.<name>``).
LINEAR_FIELDS = ("x", "y", "z")
ANGULAR_FIELDS = ("yaw", "pitch", "roll")


class Speed(Enum):
    NORMAL = "normal"
    TURBO = "turbo"


@dataclass(frozen=True)
class TwistCommand:
    """A velocity command (m/s, rad/s); angular x/y/z are roll, pitch and yaw rates."""

    linear_x: float = 0.0
    linear_y: float = 0.0
    linear_z: float = 0.0
    angular_x: float = 0.0
    angular_y: float = 0.0
    angular_z: float = 0.0


def _linear(**values: float) -> dict[str, float]:
    return {name: values.get(name, 0.0) for name in LINEAR_FIELDS}


def _angular(**values: float) -> dict[str, float]:
    return {name: values.get(name, 0.0) for name in ANGULAR_FIELDS}


@dataclass(frozen=True)
class TeleopJoyConfig:
    """teleop_twist_joy's parameters (its defaults): axis indices by twist field (-1 = unused),
    scales by twist field for normal and turbo speed, the buttons (-1 = none)."""

    axis_linear: Mapping[str, int] = field(default_factory=lambda: {"x": 5, "y": -1, "z": -1})
    scale_linear: Mapping[str, float] = field(default_factory=lambda: _linear(x=0.5))
    scale_linear_turbo: Mapping[str, float] = field(default_factory=lambda: _linear(x=1.0))
    axis_angular: Mapping[str, int] = field(default_factory=lambda: {"yaw": 2, "pitch": -1, "roll": -1})
    scale_angular: Mapping[str, float] = field(default_factory=lambda: _angular(yaw=0.5))
    scale_angular_turbo: Mapping[str, float] = field(default_factory=lambda: _angular(yaw=1.0))
    enable_button: int = 5
    enable_turbo_button: int = -1
    require_enable_button: bool = True
    inverted_reverse: bool = False


def _pressed(buttons: Sequence[int], index: int) -> bool:
    return 0 <= index < len(buttons) and bool(buttons[index])


def _axis(axes: Sequence[float], index: int, scale: float) -> float:
    if not 0 <= index < len(axes):
        return 0.0
    return float(axes[index]) * scale


class TeleopTwistJoy:
    """Joy messages in, twists out (see the module's docstring); ``config`` may be replaced between
    messages (runtime parameter updates)."""

    def __init__(self, config: TeleopJoyConfig) -> None:
        self.config = config
        self._sent_stop = False

    def speed(self, buttons: Sequence[int]) -> Speed | None:
        """Which scales the buttons select; None: not enabled."""
        c = self.config
        if c.enable_turbo_button >= 0 and _pressed(buttons, c.enable_turbo_button):
            return Speed.TURBO
        if not c.require_enable_button or _pressed(buttons, c.enable_button):
            return Speed.NORMAL
        return None

    def on_joy(self, axes: Sequence[float], buttons: Sequence[int]) -> TwistCommand | None:
        """The twist to publish for one Joy message's ``axes`` and ``buttons``, if any."""
        speed = self.speed(buttons)
        if speed is None:
            if self._sent_stop:
                return None
            self._sent_stop = True
            return TwistCommand()
        self._sent_stop = False
        return self.twist(axes, speed)

    def twist(self, axes: Sequence[float], speed: Speed) -> TwistCommand:
        c = self.config
        turbo = speed is Speed.TURBO
        linear = c.scale_linear_turbo if turbo else c.scale_linear
        angular = c.scale_angular_turbo if turbo else c.scale_angular

        def lin(name: str) -> float:
            return _axis(axes, c.axis_linear.get(name, -1), linear.get(name, 0.0))

        def ang(name: str) -> float:
            return _axis(axes, c.axis_angular.get(name, -1), angular.get(name, 0.0))

        x, yaw = lin("x"), ang("yaw")
        if c.inverted_reverse and x < 0.0:
            yaw = -yaw
        return TwistCommand(x, lin("y"), lin("z"), ang("roll"), ang("pitch"), yaw)
