"""Wait for graph conditions and messages with a timeout (never a fixed sleep)."""
from __future__ import annotations

import time
from typing import Any, Callable, TypeVar

import rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile

from pppbot_common.errors import TimeoutExpired

T = TypeVar("T")

_POLL_S = 0.05


def wait_until(condition: Callable[[], T | None], timeout_s: float, what: str,
               node: Node | None = None) -> T:
    """Return the first truthy ``condition()``, spinning ``node`` between tries.

    Raises:
        TimeoutExpired: not true within ``timeout_s``; the message says ``what``.
    """
    deadline = time.monotonic() + timeout_s
    while True:
        value = condition()
        if value:
            return value
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            raise TimeoutExpired(f"timed out after {timeout_s:.1f} s waiting for {what}")
        if node is not None:
            rclpy.spin_once(node, timeout_sec=min(_POLL_S, remaining))
        else:
            time.sleep(min(_POLL_S, remaining))


def topic_types(node: Node, topic: str) -> list[str]:
    """The types currently advertised on ``topic`` (empty when unknown)."""
    for name, types in node.get_topic_names_and_types():
        if name == topic:
            return list(types)
    return []


def wait_for_topic(node: Node, topic: str, timeout_s: float = 10.0) -> str:
    """Wait until ``topic`` has a publisher; return its type name.

    Raises:
        TimeoutExpired: no publisher appeared in time.
    """
    def published() -> str | None:
        if node.count_publishers(topic) == 0:
            return None
        types = topic_types(node, topic)
        return types[0] if types else None

    return wait_until(published, timeout_s, f"a publisher on '{topic}'")


def wait_for_messages(node: Node, msg_type: Any, topic: str, count: int = 1,
                      timeout_s: float = 10.0, qos: QoSProfile | int = 10,
                      predicate: Callable[[Any], bool] | None = None) -> list[Any]:
    """Subscribe to ``topic`` and return the first ``count`` messages (that pass ``predicate``).

    Raises:
        TimeoutExpired: fewer than ``count`` arrived in time.
    """
    received: list[Any] = []

    def on_message(msg: Any) -> None:
        if predicate is None or predicate(msg):
            received.append(msg)

    subscription = node.create_subscription(msg_type, topic, on_message, qos)
    try:
        wait_until(lambda: len(received) >= count, timeout_s,
                   f"{count} message(s) on '{topic}'", node=node)
    except TimeoutExpired as exc:
        raise TimeoutExpired(f"{exc} (received {len(received)})") from None
    finally:
        node.destroy_subscription(subscription)
    return received[:count]
