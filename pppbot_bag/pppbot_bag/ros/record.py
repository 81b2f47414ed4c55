"""The recorder of ``pppbot bag record`` (like rosbag2's ``rosbag2_recorder`` node).

Subscriptions are raw (serialized CDR is written as received, never deserialized)
with QoS compatible with every publisher: reliable and transient local only when all
publishers offer them, so latched topics (``/tf_static``, ``/map``,
``/robot_description``) arrive with their stored messages. Topics are looked for every
polling interval, so ``-a`` picks up topics that appear later.

Callbacks only queue; one writer thread writes and closes a chunk every second, so a
killed recorder loses at most about a second (``pppbot bag reindex`` recovers the rest).
SIGINT, SIGTERM and SIGHUP stop the subscriptions, write what is queued, finish the
files and ``metadata.yaml``, and print the count of each topic.
"""
from __future__ import annotations

import errno
import functools
import os
import queue
import re
import signal
import sys
import threading
import time
from pathlib import Path
from typing import Any

import rclpy
from rclpy.clock import Clock, ClockType
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions

from pppbot_bag.cli import RecordOptions
from pppbot_bag.definitions import type_definition
from pppbot_bag.errors import BagError
from pppbot_bag.metadata import BagMetadata
from pppbot_bag.recover import salvage, salvaged
from pppbot_bag.ros.qos import qos_to_bag, type_hash_string
from pppbot_bag.writer import BagWriter
from pppbot_common.errors import MessageTypeError
from pppbot_common.ros.messages import get_interface
from pppbot_common.ros.qos import subscription_qos

#: Subscription history: deep enough that a busy moment never overwrites unread messages.
QUEUE_DEPTH = 1000
_STOP = object()


class Recorder(Node):
    def __init__(self, options: RecordOptions, writer: BagWriter) -> None:
        super().__init__(options.node_name, parameter_overrides=[
            Parameter("use_sim_time", value=options.use_sim_time)])
        self.options = options
        self.writer = writer
        self.queue: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self.subscribed: dict[str, Any] = {}
        self.skipped: set[str] = set()
        self.error: BaseException | None = None
        self._started = time.monotonic()
        self._warned_no_clock = False
        self._writer_thread = threading.Thread(target=self._write_loop, name="bag-writer", daemon=True)
        self._writer_thread.start()
        # Discovery runs on wall time: with --use-sim-time it must run before /clock exists.
        self._poll = self.create_timer(options.polling_interval_s, self._discover,
                                       clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.get_logger().info(f"recording to '{options.output}'")
        self._discover()

    # -- discovery -----------------------------------------------------------------------

    def _discover(self) -> None:
        if not self.options.discovery and time.monotonic() - self._started > 1.0:
            self._poll.cancel()  # --no-discovery: only what showed up at start
            return
        if self.options.use_sim_time and self.get_clock().now().nanoseconds == 0:
            if time.monotonic() - self._started > 5.0 and not self._warned_no_clock:
                self._warned_no_clock = True
                self.get_logger().warning("--use-sim-time: no /clock yet; recording starts when it comes")
            return  # no /clock yet: messages would be stamped 0
        for name, types in self.get_topic_names_and_types():
            if name in self.subscribed or name in self.skipped or not self.options.selection.matches(name):
                continue
            publishers = self.get_publishers_info_by_topic(name)
            if not publishers and not self.options.include_unpublished_topics:
                continue
            self._subscribe(name, types, publishers)

    def _subscribe(self, name: str, types: list[str], publishers: list[Any]) -> None:
        log = self.get_logger()
        if len(types) > 1:
            log.warning(f"topic '{name}' has several types {types}; recording '{types[0]}'")
        type_name = types[0]
        try:
            msg_class = get_interface(type_name)
        except MessageTypeError as exc:
            log.warning(f"not recording '{name}': {exc}")
            self.skipped.add(name)
            return
        definition = type_definition(type_name)
        if not definition.encoding:
            log.warning(f"no message definition installed for '{type_name}' ({name}); "
                        "the bag plays, but tools that decode from the bag can't decode it")
        hashes = {type_hash_string(p.topic_type_hash) for p in publishers} - {""}
        self.writer_call(self.writer.add_topic, name, definition, [qos_to_bag(p.qos_profile) for p in publishers],
                         definition.type_hash or next(iter(hashes), ""))
        qos = subscription_qos(publishers, QUEUE_DEPTH)
        self.subscribed[name] = self.create_subscription(
            msg_class, name, functools.partial(self._received, name), qos, raw=True)
        log.info(f"subscribed to '{name}' ({type_name})")

    # -- messages ------------------------------------------------------------------------

    def _received(self, topic: str, data: bytes, info: Any) -> None:
        recv_ns = self.get_clock().now().nanoseconds
        info = info if isinstance(info, dict) else {}
        self.queue.put((topic, data, recv_ns, info.get("source_timestamp", recv_ns),
                        info.get("publication_sequence_number") or 0))

    def writer_call(self, fn: Any, *args: Any) -> None:
        """Run ``fn`` on the writer thread, in order with the queued messages."""
        self.queue.put((fn, args))

    def _write_loop(self) -> None:
        period = self.options.flush_period_s
        next_flush = time.monotonic() + period
        while True:
            try:
                item = self.queue.get(timeout=max(0.0, next_flush - time.monotonic()))
            except queue.Empty:
                item = None
            try:
                if item is _STOP:
                    return
                if item is not None:
                    if len(item) == 2:
                        item[0](*item[1])
                    else:
                        self.writer.write(item[0], item[1], item[2], item[3], item[4])
                if time.monotonic() >= next_flush:
                    self.writer.flush()
                    next_flush = time.monotonic() + period
            except Exception as exc:  # disk full, closed file: stop recording, report at the end
                self.error = exc
                return

    def finish(self) -> BagMetadata:
        """Take what DDS has already received, stop the subscriptions, write everything
        queued, close the bag."""
        executor = SingleThreadedExecutor(context=self.context)
        executor.add_node(self)
        deadline = time.monotonic() + 2.0
        while time.monotonic() < deadline and self._take_pending(executor):
            pass
        executor.remove_node(self)
        for sub in self.subscribed.values():
            self.destroy_subscription(sub)
        self.queue.put(_STOP)
        self._writer_thread.join()
        return self.writer.close()

    def _take_pending(self, executor: SingleThreadedExecutor) -> bool:
        """One callback of what is already received; False when there is none."""
        before = self.queue.qsize()
        executor.spin_once(timeout_sec=0.0)
        return self.queue.qsize() != before


def _summary(metadata: BagMetadata, output: str) -> str:
    lines = [f"[bag record] {metadata.message_count} messages in {len(metadata.files)} file(s) "
             f"written to '{output}'"]
    width = max((len(t.name) for t in metadata.topics), default=0)
    lines += [f"  {t.name:<{width}}  {t.message_count}" for t in metadata.topics]
    return "\n".join(lines)


def main(options: RecordOptions) -> int:
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", options.node_name):
        print(f"pppbot bag record: --node-name '{options.node_name}' is not a valid node name "
              "(letters, digits and underscores, not starting with a digit)", file=sys.stderr)
        return 1
    try:
        continuing = None
        if options.resume and options.output.exists():
            if options.output.is_dir() and not any(options.output.glob("*.mcap*")):
                continuing = BagMetadata()  # killed before its first file: a bag begun, nothing in it
            else:
                continuing, report = salvaged(options.output)
                print(f"[bag record] recording on into '{options.output}' ({report})", flush=True)
        writer = BagWriter(options.output, options.writer, ros_distro=os.environ.get("ROS_DISTRO", "jazzy"),
                           continuing=continuing)
    except (OSError, BagError) as exc:
        print(f"pppbot bag record: {exc}", file=sys.stderr)
        return 1
    rclpy.init(args=[], signal_handler_options=SignalHandlerOptions.NO)
    stop = threading.Event()

    def on_signal(signum: int, frame: Any) -> None:
        stop.set()

    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, on_signal)
    recorder = Recorder(options, writer)
    try:
        while not stop.is_set() and recorder.error is None:
            rclpy.spin_once(recorder, timeout_sec=0.05)
    except ExternalShutdownException:
        pass
    finally:
        try:
            metadata = recorder.finish()
        except (OSError, BagError) as exc:
            recorder.error = recorder.error or exc
            metadata = writer.metadata
        recorder.destroy_node()
        rclpy.try_shutdown()
    if recorder.error is not None:
        return _salvage(options.output, recorder.error)
    print(_summary(metadata, str(options.output)), flush=True)
    return 0


def _salvage(bag: Path, error: BaseException) -> int:
    """Say once why recording stopped, and leave the bag readable with what reached the disk."""
    why = str(error)
    if isinstance(error, OSError):
        full = error.errno in (errno.ENOSPC, errno.EFBIG, errno.EDQUOT)
        why = f"{error.strerror}" + (": the disk is full, or a file-size limit (ulimit -f) was reached" if full else "")
    try:
        kept = salvage(bag)
    except (OSError, BagError) as exc:
        print(f"pppbot bag record: writing '{bag}' failed, recording stopped: {why}; the bag could not be finished "
              f"either ({exc}): run `pppbot bag reindex {bag}` once there is room", file=sys.stderr, flush=True)
        return 1
    print(f"pppbot bag record: writing '{bag}' failed, recording stopped: {why}; the bag is readable, with what "
          f"reached the disk ({kept.splitlines()[0].split(': ', 1)[1]})", file=sys.stderr, flush=True)
    return 1
