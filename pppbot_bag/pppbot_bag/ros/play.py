"""The player of ``pppbot bag play`` (like rosbag2's ``rosbag2_player``).

Messages are published as recorded (serialized bytes, no round trip) at their
recorded reception times scaled by ``--rate``, on publishers with the QoS the topic
was recorded with (``playback_qos``). ``--clock`` publishes /clock with the bag's time.
In a terminal: space pauses and resumes, ``s`` or the right arrow publishes the
next message while paused, up/down arrows change the rate by 10 %.
"""
from __future__ import annotations

import os
import select
import signal
import sys
import termios
import threading
import time
import tty
from dataclasses import dataclass
from typing import Any

import rclpy
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock

from pppbot_bag.cli import PlayOptions
from pppbot_bag.errors import BagError
from pppbot_bag.reader import bag_messages, open_bag
from pppbot_bag.ros.qos import playback_qos
from pppbot_common.errors import MessageTypeError
from pppbot_common.ros.messages import get_interface


@dataclass
class PlaybackClock:
    """Bag time ↔ wall time, with pause and rate changes (times in ns)."""

    bag_start_ns: int
    rate: float
    paused: bool = False

    def __post_init__(self) -> None:
        self._anchor_wall = time.monotonic_ns()
        self._anchor_bag = self.bag_start_ns

    def now(self) -> int:
        """The bag time that corresponds to now."""
        if self.paused:
            return self._anchor_bag
        return self._anchor_bag + int((time.monotonic_ns() - self._anchor_wall) * self.rate)

    def _reanchor(self) -> None:
        self._anchor_bag, self._anchor_wall = self.now(), time.monotonic_ns()

    def set_paused(self, paused: bool) -> None:
        self._reanchor()
        self.paused = paused

    def set_rate(self, rate: float) -> None:
        self._reanchor()
        self.rate = rate

    def jump(self, bag_ns: int) -> None:
        self._anchor_bag, self._anchor_wall = bag_ns, time.monotonic_ns()

    def wall_seconds_until(self, bag_ns: int) -> float:
        return max(0.0, (bag_ns - self.now()) / self.rate / 1e9)


class Player:
    def __init__(self, node: Node, options: PlayOptions) -> None:
        self.node = node
        self.options = options
        self.stop = threading.Event()
        self.step = threading.Event()
        self.clock: PlaybackClock | None = None
        self.publishers: dict[str, Any] = {}
        self.published = 0
        self.clock_pub = node.create_publisher(Clock, "/clock", 10) if options.clock_hz else None

    def _make_publishers(self, reader: Any) -> list[Any]:
        log = self.node.get_logger()
        by_topic: dict[str, list[Any]] = {}
        for conn in reader.connections:
            if self.options.selection.matches(conn.topic):
                by_topic.setdefault(conn.topic, []).append(conn)
        chosen = []
        for topic, conns in by_topic.items():
            try:
                msg_class = get_interface(conns[0].msgtype)
            except MessageTypeError as exc:
                log.warning(f"not playing '{topic}': {exc}")
                continue
            offered = [q for c in conns for q in getattr(c.ext, "offered_qos_profiles", [])]
            self.publishers[topic] = self.node.create_publisher(
                msg_class, self.options.remap(topic), playback_qos(offered))
            chosen += conns
        return chosen

    def run(self) -> int:
        with open_bag(self.options.bag) as reader:
            connections = self._make_publishers(reader)
            if not connections:
                raise BagError(f"no topic of '{self.options.bag}' is selected for playback")
            if self.options.delay_s:
                self.stop.wait(self.options.delay_s)
            if reader.message_count == 0:
                raise BagError(f"bag '{self.options.bag}' has no messages")
            first = reader.start_time + int(self.options.start_offset_s * 1e9)
            if first > reader.end_time:
                raise BagError(f"--start-offset {self.options.start_offset_s:g} s is past the end of the bag "
                               f"({(reader.end_time - reader.start_time) / 1e9:.3f} s long)")
            self.clock = PlaybackClock(first, self.options.rate, paused=self.options.start_paused)
            if self.options.start_paused:
                self.node.get_logger().info("paused: press space to play (or s to step)")
            clock_thread = threading.Thread(target=self._publish_clock, daemon=True)
            clock_thread.start()
            while not self.stop.is_set():
                self.clock.jump(first)
                before = self.published
                for conn, stamp, data in bag_messages(reader, connections, start=first):
                    if not self._wait_until(stamp):
                        break
                    self.publishers[conn.topic].publish(data)
                    self.published += 1
                if not self.options.loop or self.published == before:
                    break
        self.stop.set()
        return 0

    def wait_for_all_acked(self) -> None:
        """Give reliable subscribers the time to acknowledge the last messages (destroying
        the publishers at once can lose them); warn when they did not."""
        timeout_ms = self.options.wait_for_all_acked_ms
        if timeout_ms < 0:
            return
        deadline = time.monotonic() + timeout_ms / 1000.0
        for topic, pub in self.publishers.items():
            left_s = max(0.0, deadline - time.monotonic()) if timeout_ms else -1.0
            if not pub.wait_for_all_acked(Duration(nanoseconds=int(left_s * 1e9))):
                self.node.get_logger().warning(
                    f"'{topic}': not every message was acknowledged within {timeout_ms} ms")
                return

    def _wait_until(self, stamp: int) -> bool:
        """Sleep until ``stamp`` is due (or a step is asked for while paused); False to stop."""
        assert self.clock is not None
        while not self.stop.is_set():
            if self.clock.paused:
                if self.step.is_set():
                    self.step.clear()
                    self.clock.jump(stamp)
                    return True
                self.stop.wait(0.02)
                continue
            wait = self.clock.wall_seconds_until(stamp)
            if wait <= 0:
                return True
            self.stop.wait(min(wait, 0.05))
        return False

    def _publish_clock(self) -> None:
        if self.clock_pub is None or self.clock is None:
            return
        period = 1.0 / self.options.clock_hz
        while not self.stop.wait(period):
            msg = Clock()
            ns = self.clock.now()
            msg.clock.sec, msg.clock.nanosec = divmod(ns, 1_000_000_000)
            self.clock_pub.publish(msg)

    # -- keyboard ------------------------------------------------------------------------

    def key(self, key: str) -> None:
        clock = self.clock
        if clock is None:
            return
        log = self.node.get_logger()
        if key == " ":
            clock.set_paused(not clock.paused)
            log.info("paused" if clock.paused else "playing")
        elif key in ("s", "\x1b[C") and clock.paused:
            self.step.set()
        elif key in ("\x1b[A", "\x1b[B"):
            clock.set_rate(clock.rate * (1.1 if key == "\x1b[A" else 1 / 1.1))
            log.info(f"rate {clock.rate:.3g}")


def _read_keys(player: Player) -> None:
    fd = sys.stdin.fileno()
    saved = termios.tcgetattr(fd)
    try:
        tty.setcbreak(fd)
        while not player.stop.is_set():
            ready, _, _ = select.select([fd], [], [], 0.1)
            if ready:
                data = os.read(fd, 8).decode(errors="replace")
                player.key(data if data.startswith("\x1b") else data[:1])
    finally:
        termios.tcsetattr(fd, termios.TCSADRAIN, saved)


def main(options: PlayOptions) -> int:
    if options.start_paused and not (options.keyboard_controls and sys.stdin.isatty()):
        print("pppbot bag play: --start-paused needs the keyboard controls in a terminal to resume "
              "(the pause/resume services of rosbag2's player are not provided)", file=sys.stderr)
        return 1
    rclpy.init(args=[], signal_handler_options=SignalHandlerOptions.NO)
    node = Node(options.node_name)
    player = Player(node, options)
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, lambda *_: player.stop.set())
    keys = None
    if options.keyboard_controls and sys.stdin.isatty():
        keys = threading.Thread(target=_read_keys, args=(player,), daemon=True)
        keys.start()
    try:
        player.run()
    except BagError as exc:
        print(f"pppbot bag play: {exc}", file=sys.stderr)
        return 1
    finally:
        player.stop.set()
        if keys is not None:
            keys.join()
        player.wait_for_all_acked()
        node.destroy_node()
        rclpy.try_shutdown()
    print(f"[bag play] published {player.published} messages", flush=True)
    return 0
