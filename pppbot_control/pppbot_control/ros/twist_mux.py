"""``twist_mux``: twist_mux's configuration and behaviour, plus a stop when the winner goes quiet.

Parameters as twist_mux's YAML: ``topics.<name>.{topic, timeout, priority}`` and
``locks.<name>.{topic, timeout, priority}`` (std_msgs/Bool), ``use_stamped``
(inputs and output TwistStamped instead of Twist). Output on ``cmd_vel_out``.
"""
from __future__ import annotations

import sys
from collections.abc import Callable
from typing import Any

from geometry_msgs.msg import Twist, TwistStamped
from rclpy.node import Node
from std_msgs.msg import Bool

from pppbot_common.params import ParameterError
from pppbot_common.ros.params import refuse_sets
from pppbot_control.mux import MuxConfigError, TwistMux, parse_config
from pppbot_lockstep.ros.node import StepNode
from pppbot_lockstep.ros.runner import guarded, run_node

#: How often input timeouts are checked. In lockstep the check fires at the first sync time
#: after its deadline (a scan's, 10 Hz by default, or another participant's timer) without
#: making one: a timeout is noticed at most a scan period late, and adds no steps of its own.
CHECK_RATE_HZ = 20.0


def grouped(node: Node, prefix: str) -> dict[str, dict[str, Any]]:
    """``prefix.<name>.<field>`` parameters as {name: {field: value}}."""
    out: dict[str, dict[str, Any]] = {}
    for name, parameter in node.get_parameters_by_prefix(prefix).items():
        entry, _, field = name.partition(".")
        if field:
            out.setdefault(entry, {})[field] = getattr(parameter, "value", parameter)
    return out


class TwistMuxNode(StepNode):
    def __init__(self, **kwargs: Any) -> None:
        # Its inputs are whatever ``topics.*`` the file names, so every override is declared; undeclared
        # names stay refused (rclpy's get_parameter_types fails unanswered on them when they are allowed).
        super().__init__("twist_mux", automatically_declare_parameters_from_overrides=True, **kwargs)
        refuse_sets(self, "twist_mux reads its inputs and locks once, at start-up (as twist_mux's); restart it")
        use_stamped = self.get_parameter("use_stamped").value if self.has_parameter("use_stamped") else False
        if not isinstance(use_stamped, bool):
            raise ParameterError("use_stamped", use_stamped, "must be true or false")
        self.stamped = use_stamped
        topics, lock_entries = grouped(self, "topics"), grouped(self, "locks")
        try:
            inputs, locks = parse_config(topics, lock_entries)
        except MuxConfigError as exc:
            raise ParameterError("topics" if "locks." not in str(exc) else "locks",
                                 topics if "locks." not in str(exc) else lock_entries, str(exc)) from exc
        self.mux = TwistMux(inputs, locks)
        self.msg_type = TwistStamped if self.stamped else Twist
        self.output = self.create_publisher(self.msg_type, "cmd_vel_out", 10)
        self.port.require_match(self, self.output)
        for spec in inputs:  # inputs and locks may have no publisher (no teleop): none is waited for
            self.create_subscription(self.msg_type, spec.topic, self._input_callback(spec.name), 10,
                                     data_path=True, needs_publisher=False)
        for lock in locks:
            self.create_subscription(Bool, lock.topic, self._lock_callback(lock.name), 10, data_path=True,
                                     needs_publisher=False)
        self.step_timer(1.0 / CHECK_RATE_HZ, self.check, wakes=False)
        summary = ", ".join(f"{s.name} ({s.topic}, priority {s.priority}, {s.timeout_s:g} s)" for s in inputs)
        locked = f"; locks: {', '.join(lock.name for lock in locks)}" if locks else ""
        self.get_logger().info(f"inputs: {summary}{locked}")

    def _input_callback(self, name: str) -> Callable[[Any], None]:
        return guarded(self, lambda msg: self.on_input(name, msg), f"'{name}' input")

    def _lock_callback(self, name: str) -> Callable[[Bool], None]:
        return guarded(self, lambda msg: self.on_lock(name, msg), f"'{name}' lock")

    def _now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def on_input(self, name: str, msg: Any) -> None:
        out = self.mux.on_input(name, msg, self._now_s())
        if out is not None:
            self.output.publish(out)

    def on_lock(self, name: str, msg: Bool) -> None:
        self.mux.on_lock(name, bool(msg.data), self._now_s())
        self.check()

    def check(self) -> None:
        if self.mux.check_timeouts(self._now_s()):
            zero = self.msg_type()
            if self.stamped:
                zero.header.stamp = self.get_clock().now().to_msg()
            self.output.publish(zero)


def main(args: list[str] | None = None) -> int:
    return run_node(TwistMuxNode, "twist_mux", args, fatal=(ParameterError,))


if __name__ == "__main__":
    sys.exit(main())
