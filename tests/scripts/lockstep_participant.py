"""A small lockstep participant for the tests: ``lockstep_participant.py <role> [args]``.

* ``ticker``: a 20 Hz step timer publishes the tick's sim time (nanoseconds) on ``/ls_test/tick``;
  ``--sleep-every N --sleep-s S`` sleeps S wall seconds in every N-th tick (a slow node);
  ``--hang-at T`` sleeps forever in the first tick at or after sim time T (a hung node).
* ``relay``: forwards every ``/ls_test/tick`` at once on ``/ls_test/relayed`` with the sim
  time it was handled at (the chain's second hop).

Runs through pppbot's node runner, so ``--ros-args -p lockstep:=true -p lockstep_name:=...``
makes it a participant like pppbot's own nodes.
"""
from __future__ import annotations

import argparse
import sys
import time
from typing import Any

from std_msgs.msg import Int64MultiArray

from pppbot_lockstep.ros.node import StepNode
from pppbot_lockstep.ros.runner import run_nodes


class Ticker(StepNode):
    def __init__(self, sleep_every: int, sleep_s: float, hang_at_s: float, **kwargs: Any) -> None:
        super().__init__("ls_ticker", **kwargs)
        self.pub = self.create_publisher(Int64MultiArray, "/ls_test/tick", 100)
        self.count = 0
        self.sleep_every, self.sleep_s, self.hang_at_s = sleep_every, sleep_s, hang_at_s
        self.step_timer(0.05, self.tick)

    def tick(self) -> None:
        now = self.get_clock().now().nanoseconds
        self.count += 1
        if self.hang_at_s and now * 1e-9 >= self.hang_at_s:
            print(f"hanging at {now}", flush=True)
            time.sleep(3600)
        if self.sleep_every and self.count % self.sleep_every == 0:
            time.sleep(self.sleep_s)
        self.pub.publish(Int64MultiArray(data=[self.count, now]))


class Relay(StepNode):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__("ls_relay", **kwargs)
        self.pub = self.create_publisher(Int64MultiArray, "/ls_test/relayed", 100)
        self.port.require_match(self, self.pub)
        self.create_subscription(Int64MultiArray, "/ls_test/tick", self.on_tick, 100, data_path=True)

    def on_tick(self, msg: Int64MultiArray) -> None:
        now = self.get_clock().now().nanoseconds
        self.pub.publish(Int64MultiArray(data=[*msg.data, now]))


def main() -> int:
    argv = sys.argv[1:]
    ros = argv.index("--ros-args") if "--ros-args" in argv else len(argv)
    parser = argparse.ArgumentParser()
    parser.add_argument("role", choices=("ticker", "relay"))
    parser.add_argument("--sleep-every", type=int, default=0)
    parser.add_argument("--sleep-s", type=float, default=0.0)
    parser.add_argument("--hang-at", type=float, default=0.0)
    args = parser.parse_args(argv[:ros])
    if args.role == "ticker":
        return run_nodes([lambda port: Ticker(args.sleep_every, args.sleep_s, args.hang_at, port=port)], "ls_ticker",
                         argv[ros:])
    return run_nodes([Relay], "ls_relay", argv[ros:])


if __name__ == "__main__":
    sys.exit(main())
