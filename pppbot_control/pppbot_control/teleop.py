"""teleop_twist_keyboard's keys and speed rules, without a terminal or ROS.

::

    Moving around:        u    i    o          (shift: strafe, for holonomic bases)
                          j    k    l
                          m    ,    .
    t : up (+z)   b : down (-z)   anything else : stop
    q/z : max speeds +/-10 %   w/x : linear only   e/c : angular only
"""
from __future__ import annotations

from dataclasses import dataclass

#: key → (x, y, z, yaw) direction
MOVE_BINDINGS: dict[str, tuple[int, int, int, int]] = {
    "i": (1, 0, 0, 0), "o": (1, 0, 0, -1), "j": (0, 0, 0, 1), "l": (0, 0, 0, -1),
    "u": (1, 0, 0, 1), ",": (-1, 0, 0, 0), ".": (-1, 0, 0, 1), "m": (-1, 0, 0, -1),
    "O": (1, -1, 0, 0), "I": (1, 0, 0, 0), "J": (0, 1, 0, 0), "L": (0, -1, 0, 0),
    "U": (1, 1, 0, 0), "<": (-1, 0, 0, 0), ">": (-1, -1, 0, 0), "M": (-1, 1, 0, 0),
    "t": (0, 0, 1, 0), "b": (0, 0, -1, 0),
}
#: key → (linear factor, angular factor)
SPEED_BINDINGS: dict[str, tuple[float, float]] = {
    "q": (1.1, 1.1), "z": (0.9, 0.9), "w": (1.1, 1.0), "x": (0.9, 1.0), "e": (1.0, 1.1), "c": (1.0, 0.9),
}

HELP = """
This node takes keypresses from the keyboard and publishes them
as Twist/TwistStamped messages. It works best with a US keyboard layout.
---------------------------
Moving around:
   u    i    o
   j    k    l
   m    ,    .

For Holonomic mode (strafing), hold down the shift key:
---------------------------
   U    I    O
   J    K    L
   M    <    >

t : up (+z)
b : down (-z)

anything else : stop

q/z : increase/decrease max speeds by 10%
w/x : increase/decrease only linear speed by 10%
e/c : increase/decrease only angular speed by 10%

CTRL-C to quit
"""


@dataclass(frozen=True)
class Twist:
    linear_x: float = 0.0
    linear_y: float = 0.0
    linear_z: float = 0.0
    angular_z: float = 0.0

    @property
    def is_zero(self) -> bool:
        return self == Twist()


@dataclass
class TeleopState:
    """Speeds and the current direction; ``press(key)`` applies one key."""

    speed: float = 0.5
    turn: float = 1.0
    x: int = 0
    y: int = 0
    z: int = 0
    th: int = 0

    def press(self, key: str) -> bool:
        """Apply a key; True when the speeds changed (the caller prints them)."""
        if key in MOVE_BINDINGS:
            self.x, self.y, self.z, self.th = MOVE_BINDINGS[key]
            return False
        if key in SPEED_BINDINGS:
            linear, angular = SPEED_BINDINGS[key]
            self.speed *= linear
            self.turn *= angular
            return True
        self.stop()
        return False

    def stop(self) -> None:
        self.x = self.y = self.z = self.th = 0

    def twist(self) -> Twist:
        return Twist(self.x * self.speed, self.y * self.speed, self.z * self.speed, self.th * self.turn)

    def speeds_line(self) -> str:
        return f"currently:\tspeed {self.speed:.5g}\tturn {self.turn:.5g} "
