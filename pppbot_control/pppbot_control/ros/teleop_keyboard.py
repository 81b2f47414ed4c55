"""``teleop_keyboard``: teleop_twist_keyboard for pppbot (``./pppbot teleop``).

Same keys, help and speed rules as teleop_twist_keyboard; publishes on
``cmd_vel_teleop`` (twist_mux's ``teleop`` input). Parameters: ``speed``,
``turn``, ``stamped``, ``frame_id``, and ``repeat_rate`` (Hz: re-send the current
twist while a key is held) with ``key_timeout`` (s: stop when no key came for
that long), so holding a key drives smoothly and releasing it stops.
The terminal is restored on every way out.
"""
from __future__ import annotations

import os
import select
import signal
import sys
import termios
import time
import tty
from dataclasses import dataclass
from types import FrameType
from typing import Any

from geometry_msgs.msg import Twist, TwistStamped
from rclpy.duration import Duration
from rclpy.node import Node

from pppbot_common.params import ParameterError, check_finite_range, param
from pppbot_common.ros.params import declare_parameters
from pppbot_control.teleop import HELP, TeleopState
from pppbot_control.teleop import Twist as CoreTwist
from pppbot_lockstep.ros.runner import run_node

STATUS_LINES_PER_HELP = 14
SUBSCRIBER_WAIT_S = 5.0
#: How long the stop on the way out may wait for its subscribers to acknowledge it (s).
STOP_DELIVERY_S = 1.0


@dataclass(frozen=True)
class TeleopParameters:
    speed: float = param(0.5, "initial linear speed (m/s)")
    turn: float = param(1.0, "initial angular speed (rad/s)")
    stamped: bool = param(False, "publish TwistStamped instead of Twist")
    frame_id: str = param("", "frame_id of TwistStamped messages")
    repeat_rate: float = param(10.0, "re-send the current twist at this rate (Hz); 0 = only on key presses")
    key_timeout: float = param(0.6, "stop after this long without a key (s); 0 = never")

    def validate(self) -> None:
        check_finite_range("speed", self.speed, 0.0, 100.0)
        check_finite_range("turn", self.turn, 0.0, 100.0)
        check_finite_range("repeat_rate", self.repeat_rate, 0.0, 1000.0)
        check_finite_range("key_timeout", self.key_timeout, 0.0, 3600.0)


class Teleop(Node):
    def __init__(self) -> None:
        super().__init__("teleop_keyboard")
        self.params = declare_parameters(self, TeleopParameters)
        self.state = TeleopState(speed=self.params.speed, turn=self.params.turn)
        msg_type = TwistStamped if self.params.stamped else Twist
        self.pub = self.create_publisher(msg_type, "cmd_vel_teleop", 10)

    def publish(self, twist: CoreTwist) -> None:
        msg: Any = TwistStamped() if self.params.stamped else Twist()
        body = msg.twist if self.params.stamped else msg
        if self.params.stamped:
            msg.header.stamp = self.get_clock().now().to_msg()
            msg.header.frame_id = self.params.frame_id
        body.linear.x, body.linear.y, body.linear.z = twist.linear_x, twist.linear_y, twist.linear_z
        body.angular.z = twist.angular_z
        self.pub.publish(msg)


def _raise_interrupt(signum: int, frame: FrameType | None) -> None:
    raise KeyboardInterrupt


def run(node: Teleop, fd: int) -> None:
    """Read keys from the terminal ``fd`` (in cbreak mode) and publish until Ctrl-C.

    Every key publishes the resulting twist (as upstream). While moving, the twist
    is re-sent at ``repeat_rate`` and the robot stops (one zero twist) when no key
    came for ``key_timeout``. Zeros are not repeated, so twist_mux hands control
    back to navigation once teleop has been quiet for its timeout.
    """
    p = node.params
    print(HELP)
    print(node.state.speeds_line(), flush=True)
    status_lines = 0
    repeat_s = 1.0 / p.repeat_rate if p.repeat_rate > 0 else 0.0
    last_key_s = last_sent_s = time.monotonic()
    while True:
        moving = not node.state.twist().is_zero
        deadlines = []
        if moving and repeat_s:
            deadlines.append(last_sent_s + repeat_s)
        if moving and p.key_timeout:
            deadlines.append(last_key_s + p.key_timeout)
        timeout = max(0.0, min(deadlines) - time.monotonic()) if deadlines else None
        ready, _, _ = select.select([fd], [], [], timeout)
        now = time.monotonic()
        if ready:
            data = os.read(fd, 32)
            if not data:
                return  # the terminal went away
            for key in data.decode(errors="ignore"):
                if key == "\x03":
                    raise KeyboardInterrupt
                if node.state.press(key):
                    print(node.state.speeds_line(), flush=True)
                    status_lines += 1
                    if status_lines % STATUS_LINES_PER_HELP == 0:
                        print(HELP)
            node.publish(node.state.twist())
            last_key_s = last_sent_s = now
        elif moving and p.key_timeout and now - last_key_s >= p.key_timeout:
            node.state.stop()
            node.publish(node.state.twist())
            last_sent_s = now
        elif moving and repeat_s and now - last_sent_s >= repeat_s:
            node.publish(node.state.twist())
            last_sent_s = now


def terminal_session(node: Teleop) -> None:
    """Drive from this terminal until Ctrl-C (or SIGTERM/SIGHUP), then put everything back."""
    # Keys pressed before twist_mux has matched our publisher would be lost.
    deadline = time.monotonic() + SUBSCRIBER_WAIT_S
    while node.pub.get_subscription_count() == 0 and time.monotonic() < deadline:
        time.sleep(0.05)
    if node.pub.get_subscription_count() == 0:
        print(f"(nobody subscribes to {node.pub.topic_name} yet: is twist_mux running?)", flush=True)
    fd = sys.stdin.fileno()
    saved = termios.tcgetattr(fd)
    previous = {s: signal.signal(s, _raise_interrupt) for s in (signal.SIGTERM, signal.SIGHUP)}
    try:
        tty.setcbreak(fd)
        run(node, fd)
    except KeyboardInterrupt:
        pass
    finally:
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # cleanup must not be cut short
        termios.tcsetattr(fd, termios.TCSADRAIN, saved)
        for s, handler in previous.items():
            signal.signal(s, handler)
        node.publish(CoreTwist())  # stop the robot on the way out
        # ... and see it delivered: the node is destroyed next, which can drop a message
        # its subscribers have not acknowledged yet (a CI run saw the stop lost).
        node.pub.wait_for_all_acked(Duration(seconds=STOP_DELIVERY_S))


def main(args: list[str] | None = None) -> int:
    if not sys.stdin.isatty():
        print("teleop_keyboard reads keys from a terminal, and its standard input is not one.\n"
              "Run it in a terminal of its own: ./pppbot teleop", file=sys.stderr)
        return 1
    # Ctrl-C is ours: rclpy must not shut the context down before the last stop twist.
    return run_node(Teleop, "teleop_keyboard", args, spin=terminal_session, fatal=(ParameterError,),
                    signal_handlers=False)


if __name__ == "__main__":
    sys.exit(main())
