"""``pppbot topic list|info|echo|hz``: inspect topics with ``ros2 topic``'s flags and output.

There is no ROS 2 daemon here, so each call starts a hidden node and waits for
DDS discovery: ``--spin-time`` bounds that wait.
"""
from __future__ import annotations

import argparse
import itertools
import math
import statistics
import sys
import time
from collections import deque
from collections.abc import Callable, Iterator
from typing import Any

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from pppbot_common.errors import PppbotError, TimeoutExpired
from pppbot_common.ros.messages import get_field, get_interface, message_to_yaml
from pppbot_common.ros.nodes import unspun_node
from pppbot_common.ros.qos import qos_matching_publishers
from pppbot_common.ros.wait import wait_for_topic

#: Discovery is over once the graph has not changed for this long ...
_SETTLE_S = 1.5
#: ... and no sooner than this.
_MIN_DISCOVERY_S = 3.5


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="topic_verb", required=True, metavar="<list|info|echo|hz>")

    p = sub.add_parser("list", help="topics in the graph")
    p.add_argument("-t", "--show-types", action="store_true", help="also print each topic's type")
    p.add_argument("-c", "--count-topics", action="store_true", help="print only the number of topics")
    p.add_argument("--include-hidden-topics", action="store_true", help="also list hidden topics")
    _spin_time(p, 5.0)

    p = sub.add_parser("info", help="a topic's type and its publishers and subscribers")
    p.add_argument("topic_name")
    p.add_argument("-v", "--verbose", action="store_true", help="each endpoint's node and QoS")
    _spin_time(p, 5.0)

    p = sub.add_parser("echo", help="print messages as YAML")
    p.add_argument("topic_name")
    p.add_argument("message_type", nargs="?", help="e.g. geometry_msgs/msg/Twist (found from the graph if omitted)")
    p.add_argument("--once", action="store_true", help="print the first message and exit")
    p.add_argument("--field", help="print only this dotted field, e.g. header.stamp")
    p.add_argument("--no-arr", action="store_true", help="do not print array contents")
    p.add_argument("--no-str", action="store_true", help="do not print string contents")
    p.add_argument("--flow-style", action="store_true", help="YAML flow style")
    _qos_arguments(p)
    _spin_time(p, 5.0)

    p = sub.add_parser("hz", help="print the publishing rate")
    p.add_argument("topic_name")
    p.add_argument("-w", "--window", type=_positive_int, default=10000,
                   help="how many recent messages the statistics cover (default 10000)")
    _qos_arguments(p)
    _spin_time(p, 5.0)


def _positive_int(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, not {text}")
    return value


def _spin_time(parser: argparse.ArgumentParser, default_s: float) -> None:
    parser.add_argument("--spin-time", type=float, default=default_s, metavar="SECONDS",
                        help=f"how long to wait for discovery (default {default_s})")


def _qos_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--qos-depth", type=_positive_int, default=10)
    parser.add_argument("--qos-reliability", choices=["reliable", "best_effort"],
                        help="default: what the publishers offer")
    parser.add_argument("--qos-durability", choices=["volatile", "transient_local"],
                        help="default: what the publishers offer")


def _subscription_qos(node: Node, args: argparse.Namespace) -> QoSProfile:
    qos = qos_matching_publishers(node, args.topic_name, depth=args.qos_depth)
    if args.qos_reliability:
        qos.reliability = ReliabilityPolicy[args.qos_reliability.upper()]
    if args.qos_durability:
        qos.durability = DurabilityPolicy[args.qos_durability.upper()]
    return qos


def _settled_topics(node: Node, spin_time_s: float) -> list[tuple[str, list[str]]]:
    """Topic names and types once discovery has stopped adding any (bounded by spin_time_s)."""
    start = time.monotonic()
    last = node.get_topic_names_and_types()
    changed_at = start
    while time.monotonic() - start < spin_time_s:
        rclpy.spin_once(node, timeout_sec=0.05)
        now = node.get_topic_names_and_types()
        if now != last:
            last, changed_at = now, time.monotonic()
        elif time.monotonic() - changed_at >= _SETTLE_S and time.monotonic() - start >= _MIN_DISCOVERY_S:
            break
    return [(name, list(types)) for name, types in last]


def _is_hidden(topic: str) -> bool:
    return any(part.startswith("_") for part in topic.split("/"))


def cmd_list(node: Node, args: argparse.Namespace) -> int:
    topics = [(n, t) for n, t in _settled_topics(node, args.spin_time)
              if args.include_hidden_topics or not _is_hidden(n)]
    if args.count_topics:
        print(len(topics))
        return 0
    for name, types in topics:
        print(f"{name} [{', '.join(types)}]" if args.show_types else name)
    return 0


def _endpoint_lines(infos: list[Any], verbose: bool) -> Iterator[str]:
    for info in infos:
        yield f"Node name: {info.node_name}"
        yield f"Node namespace: {info.node_namespace}"
        yield f"Topic type: {info.topic_type}"
        if verbose:
            q = info.qos_profile
            yield "QoS profile:"
            yield f"  Reliability: {q.reliability.name}"
            yield f"  History (Depth): {q.history.name} ({q.depth})"
            yield f"  Durability: {q.durability.name}"
        yield ""


def cmd_info(node: Node, args: argparse.Namespace) -> int:
    topics = dict(_settled_topics(node, args.spin_time))
    if args.topic_name not in topics:
        print(f"Unknown topic '{args.topic_name}'", file=sys.stderr)
        return 1
    pubs = node.get_publishers_info_by_topic(args.topic_name)
    subs = node.get_subscriptions_info_by_topic(args.topic_name)
    subs = [s for s in subs if s.node_name != node.get_name()]
    print(f"Type: {', '.join(topics[args.topic_name])}")
    print(f"Publisher count: {len(pubs)}")
    if args.verbose:
        print("", *_endpoint_lines(pubs, True), sep="\n", end="")
    print(f"Subscription count: {len(subs)}")
    if args.verbose:
        print("", *_endpoint_lines(subs, True), sep="\n", end="")
    return 0


def _resolve_type(node: Node, args: argparse.Namespace) -> Any:
    given = getattr(args, "message_type", None)
    if given:
        return get_interface(given)
    try:
        type_name = wait_for_topic(node, args.topic_name, timeout_s=args.spin_time)
    except TimeoutExpired:
        raise PppbotError(
            f"topic '{args.topic_name}' has no publisher yet, so its type is unknown; "
            f"give it: pppbot topic {args.topic_verb} {args.topic_name} <package/msg/Type>"
        ) from None
    return get_interface(type_name)


def cmd_echo(node: Node, args: argparse.Namespace) -> int:
    msg_type = _resolve_type(node, args)
    truncate_arrays = 0 if args.no_arr else None
    truncate_strings = 0 if args.no_str else None
    done = False

    def on_message(msg: Any) -> None:
        nonlocal done
        if done:
            return
        value = get_field(msg, args.field) if args.field else msg
        if hasattr(value, "get_fields_and_field_types"):
            text = message_to_yaml(value, args.flow_style, truncate_arrays, truncate_strings)
        else:
            text = f"{value}\n"
        sys.stdout.write(text + "---\n")
        sys.stdout.flush()
        done = args.once

    node.create_subscription(msg_type, args.topic_name, on_message, _subscription_qos(node, args))
    while not done:
        rclpy.spin_once(node, timeout_sec=0.1)
    return 0


def rate_statistics(stamps: list[float]) -> tuple[float, float, float, float] | None:
    """``(rate_hz, min_s, max_s, std_s)`` of arrival times, or None below two stamps."""
    if len(stamps) < 2:
        return None
    gaps = [b - a for a, b in itertools.pairwise(stamps)]
    mean = statistics.fmean(gaps)
    rate = math.inf if mean == 0 else 1.0 / mean
    return rate, min(gaps), max(gaps), statistics.pstdev(gaps)


def cmd_hz(node: Node, args: argparse.Namespace, clock: Callable[[], float] = time.monotonic) -> int:
    msg_type = _resolve_type(node, args)
    stamps: deque[float] = deque(maxlen=args.window + 1)
    count = 0

    def on_message(_serialized: bytes) -> None:
        nonlocal count
        count += 1
        stamps.append(clock())

    node.create_subscription(msg_type, args.topic_name, on_message,
                             _subscription_qos(node, args), raw=True)
    printed_at_count = 0
    next_print = clock() + 1.0
    while True:
        rclpy.spin_once(node, timeout_sec=0.05)
        if clock() < next_print:
            continue
        next_print += 1.0
        if count == printed_at_count:
            print("no new messages" if count else f"waiting for messages on '{args.topic_name}'",
                  flush=True)
            continue
        stats = rate_statistics(list(stamps))
        if stats is None:
            continue
        printed_at_count = count
        rate, low, high, std = stats
        print(f"average rate: {rate:.3f}\n\tmin: {low:.3f}s max: {high:.3f}s "
              f"std dev: {std:.5f}s window: {len(stamps)}", flush=True)


COMMANDS: dict[str, Callable[[Node, argparse.Namespace], int]] = {
    "list": cmd_list, "info": cmd_info, "echo": cmd_echo, "hz": cmd_hz,
}


def main(args: argparse.Namespace) -> int:
    rclpy.init(args=[])
    node = unspun_node(f"_pppbot_topic_{args.topic_verb}", enable_rosout=False)
    try:
        return COMMANDS[args.topic_verb](node, args)
    except PppbotError as exc:
        print(f"pppbot topic {args.topic_verb}: {exc}", file=sys.stderr)
        return 1
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
