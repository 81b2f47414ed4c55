"""``foxglove_bridge``: ROS topics for Foxglove and Lichtblick, as foxglove_bridge serves them.

A WebSocket server (the Foxglove SDK's, subprotocol ``foxglove.sdk.v1``) on ``address:port``
(127.0.0.1:8765 by default). Every ROS topic matching ``topic_whitelist`` is advertised as a
channel with its ``ros2msg`` schema (the type's full definition, as rosbag2 stores it) and
``cdr`` encoding; while a client subscribes, the bridge subscribes to the topic and forwards
each message's bytes untouched. Clients may publish (``ClientPublish``) on the topics matching
``client_topic_whitelist`` — by default ``/goal_pose``, ``/initialpose`` and
``/cmd_vel_teleop``: their CDR bytes are published on ROS as they came.

ROS subscriptions and publishers are made on the node's executor (a 10 Hz wall-clock timer
applies what the server's thread asked for), and topics are looked for every
``discovery_period`` seconds.
"""
from __future__ import annotations

import queue
import re
import sys
from dataclasses import dataclass
from typing import Any

import foxglove
from foxglove.websocket import Capability, ChannelView, Client, ClientChannel, ServerListener
from rclpy.clock import Clock, ClockType

from pppbot_bag.definitions import type_definition
from pppbot_common.errors import MessageTypeError
from pppbot_common.params import ParameterError, check_finite_range, param
from pppbot_common.ros.messages import get_interface
from pppbot_common.ros.params import declare_parameters
from pppbot_common.ros.qos import qos_matching_publishers
from pppbot_lockstep.ros.node import StepNode
from pppbot_lockstep.ros.runner import Warnings, run_node
from pppbot_viz.errors import VizError

#: what clients may publish by default: RViz's tools and the keyboard teleop's input
CLIENT_TOPICS = ["/goal_pose", "/initialpose", "/cmd_vel_teleop"]


@dataclass(frozen=True)
class BridgeParameters:
    port: int = param(8765, "the WebSocket port (foxglove_bridge's default)")
    address: str = param("127.0.0.1", "the address to listen on (0.0.0.0: every interface; think twice)")
    topic_whitelist: list[str] = param([".*"], "regular expressions of the topics offered to clients")
    client_topic_whitelist: list[str] = param([re.escape(t) for t in CLIENT_TOPICS],
                                              "regular expressions of the topics clients may publish on")
    discovery_period: float = param(1.0, "how often new topics are looked for (s of wall time)")
    max_qos_depth: int = param(25, "the queue depth of the bridge's subscriptions, at most")

    def validate(self) -> None:
        if not 0 <= self.port <= 65535:
            raise ParameterError("port", self.port, "must be a port number 0-65535 (0: a free one)")
        for name in ("topic_whitelist", "client_topic_whitelist"):
            for pattern in getattr(self, name):
                try:
                    re.compile(pattern)
                except re.error as exc:
                    raise ParameterError(name, pattern, f"is not a regular expression: {exc}") from exc
        check_finite_range("discovery_period", self.discovery_period, 0.05)
        if self.max_qos_depth < 1:
            raise ParameterError("max_qos_depth", self.max_qos_depth, "must be at least 1")


@dataclass
class _Topic:
    type_name: str
    channel: Any
    subscribers: int = 0
    subscription: Any = None


class FoxgloveBridge(StepNode):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__("foxglove_bridge", **kwargs)
        self.params = p = declare_parameters(self, BridgeParameters)
        p.validate()
        self.offered = [re.compile(x) for x in p.topic_whitelist]
        self.publishable = [re.compile(x) for x in p.client_topic_whitelist]
        self.warn = Warnings(self)
        self.topics: dict[str, _Topic] = {}
        self.client_publishers: dict[tuple[int, int], Any] = {}
        # What the server's thread asks of the executor's thread: (kind, value).
        self.requests: queue.SimpleQueue[tuple[str, Any]] = queue.SimpleQueue()
        try:
            self.server = foxglove.start_server(
                name="pppbot", host=p.address, port=p.port, server_listener=_Listener(self.requests),
                capabilities=[Capability.ClientPublish], supported_encodings=["cdr"])
        except Exception as exc:  # the SDK raises its own error types for a taken port
            raise VizError(f"can't serve Foxglove clients on {p.address}:{p.port}: {exc}") from exc
        self.get_logger().info(f"Foxglove bridge: ws://{p.address}:{self.server.port} (foxglove.sdk.v1)")
        wall = Clock(clock_type=ClockType.STEADY_TIME)
        self._discover()
        self.create_timer(p.discovery_period, self._discover, clock=wall)
        self.create_timer(0.1, self._apply_requests, clock=wall)

    # ------------------------------------------------------------ ROS → clients
    def _discover(self) -> None:
        present = dict(self.get_topic_names_and_types())
        for topic, types in present.items():
            if topic in self.topics or not any(x.fullmatch(topic) for x in self.offered):
                continue
            try:
                definition = type_definition(types[0])
            except MessageTypeError as exc:
                self.warn(topic, f"not offering {topic}: {exc}")
                continue
            if not definition.encoding:
                self.warn(topic, f"not offering {topic}: no definition of {types[0]} is installed")
                continue
            schema = foxglove.Schema(name=definition.name, encoding=definition.encoding,
                                     data=definition.text.encode())
            channel = foxglove.Channel(topic, schema=schema, message_encoding="cdr")
            self.topics[topic] = _Topic(types[0], channel)
        for topic in [t for t in self.topics if t not in present]:
            gone = self.topics.pop(topic)
            if gone.subscription is not None:
                self.destroy_subscription(gone.subscription)
            gone.channel.close()

    def _apply_requests(self) -> None:
        while True:
            try:
                kind, value = self.requests.get_nowait()
            except queue.Empty:
                return
            try:
                self._apply(kind, value)
            except Exception as exc:  # one client's odd request must not end the bridge
                self.warn(kind, f"a client's {kind} failed: {type(exc).__name__}: {exc}")

    def _apply(self, kind: str, value: Any) -> None:
        if kind == "subscribe":
            self._subscribe(value)
        elif kind == "unsubscribe":
            self._unsubscribe(value)
        elif kind == "advertise":
            self._advertise(*value)
        elif kind == "unadvertise":
            publisher = self.client_publishers.pop(value, None)
            if publisher is not None:
                self.destroy_publisher(publisher)
        elif kind == "message":
            self._client_message(*value)

    def _subscribe(self, topic: str) -> None:
        entry = self.topics.get(topic)
        if entry is None:
            return
        entry.subscribers += 1
        if entry.subscription is None:
            qos = qos_matching_publishers(self, topic, depth=self.params.max_qos_depth)
            channel = entry.channel
            clock = self.get_clock()
            entry.subscription = self.create_subscription(
                get_interface(entry.type_name), topic,
                lambda data: channel.log(data, log_time=clock.now().nanoseconds), qos, raw=True)

    def _unsubscribe(self, topic: str) -> None:
        entry = self.topics.get(topic)
        if entry is None or entry.subscribers == 0:
            return
        entry.subscribers -= 1
        if entry.subscribers == 0 and entry.subscription is not None:
            self.destroy_subscription(entry.subscription)
            entry.subscription = None

    # ------------------------------------------------------------ clients → ROS
    def _advertise(self, client_id: int, channel: ClientChannel) -> None:
        if not any(x.fullmatch(channel.topic) for x in self.publishable):
            self.warn(channel.topic, f"a client may not publish on {channel.topic} "
                                     f"(client_topic_whitelist: {self.params.client_topic_whitelist})")
            return
        if channel.encoding != "cdr":
            self.warn(channel.topic, f"a client advertised {channel.topic} in '{channel.encoding}'; only cdr "
                                     "is published")
            return
        try:
            msg_type = get_interface(channel.schema_name)
        except MessageTypeError as exc:
            self.warn(channel.topic, f"a client advertised {channel.topic} as {channel.schema_name}: {exc}")
            return
        self.client_publishers[(client_id, channel.id)] = self.create_publisher(msg_type, channel.topic, 10)
        self.get_logger().info(f"a client publishes on {channel.topic} ({channel.schema_name})")

    def _client_message(self, key: tuple[int, int], data: bytes) -> None:
        publisher = self.client_publishers.get(key)
        if publisher is not None:
            publisher.publish(data)

    def destroy_node(self) -> None:
        self.server.stop()
        super().destroy_node()


class _Listener(ServerListener):
    """The server's callbacks (its thread): handed to the executor through ``requests``."""

    def __init__(self, requests: queue.SimpleQueue[tuple[str, Any]]) -> None:
        self.requests = requests

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        self.requests.put(("subscribe", channel.topic))

    def on_unsubscribe(self, client: Client, channel: ChannelView) -> None:
        self.requests.put(("unsubscribe", channel.topic))

    def on_client_advertise(self, client: Client, channel: ClientChannel) -> None:
        self.requests.put(("advertise", (client.id, channel)))

    def on_client_unadvertise(self, client: Client, client_channel_id: int) -> None:
        self.requests.put(("unadvertise", (client.id, client_channel_id)))

    def on_message_data(self, client: Client, client_channel_id: int, data: bytes) -> None:
        self.requests.put(("message", ((client.id, client_channel_id), bytes(data))))


def main(args: list[str] | None = None) -> int:
    return run_node(FoxgloveBridge, "foxglove_bridge", args)


if __name__ == "__main__":
    sys.exit(main())
