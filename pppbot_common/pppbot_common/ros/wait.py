"""Wait for graph conditions, messages, futures and the node's clock, with timeouts (never a fixed
sleep, never a busy loop)."""
from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any, TypeVar

import rclpy
from rclpy.clock import JumpThreshold, ROSClock
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.task import Future

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


def send_goal(client: Any, goal: Any, node: Node | None, timeout_s: float = 10.0, attempts: int = 3,
              feedback_callback: Callable[[Any], None] | None = None) -> Any:
    """Send an action goal and return its goal handle once the server answered (accepted or not),
    spinning ``node`` meanwhile (None: another thread spins it). An answer not there within
    ``timeout_s`` / ``attempts`` is taken for lost and the goal sent again
    (:func:`pppbot_common.ros.retry.send_goal`).

    Raises:
        TimeoutExpired: no answer to any attempt (:class:`~pppbot_common.ros.retry.Unanswered`).
    """
    from pppbot_common.ros import retry

    return retry.send_goal(client, goal, retry.Retry(timeout_s / attempts, attempts), retry.node_wait(node),
                           node=node, feedback_callback=feedback_callback)


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


#: Any forward step of the clock wakes a sleeper (with sim time: every /clock message).
_EVERY_STEP = JumpThreshold(min_forward=Duration(nanoseconds=1), min_backward=None, on_clock_change=True)


def sleep_until_clock(node: Node, t_s: float, timeout_s: float) -> bool:
    """Block this thread until the node's clock (sim time under ``use_sim_time``) reads ``t_s`` seconds,
    for at most ``timeout_s`` wall seconds; True when the time was reached.

    Woken by the clock's own updates (a jump callback on every /clock message), not by polling;
    without sim time it sleeps the difference. Call it from a thread other than the one spinning
    the node.
    """
    clock = node.get_clock()
    target_ns = int(t_s * 1e9)
    remaining_ns = target_ns - clock.now().nanoseconds
    if remaining_ns <= 0:
        return True
    if not (isinstance(clock, ROSClock) and clock.ros_time_is_active):
        time.sleep(min(remaining_ns * 1e-9, timeout_s))
        return clock.now().nanoseconds >= target_ns
    reached = threading.Event()

    def on_jump(_: Any) -> None:
        if clock.now().nanoseconds >= target_ns:
            reached.set()

    with clock.create_jump_callback(_EVERY_STEP, post_callback=on_jump):
        if clock.now().nanoseconds < target_ns:
            reached.wait(timeout_s)
    return clock.now().nanoseconds >= target_ns


def call(node: Node, srv_type: Any, name: str, request: Any, timeout_s: float = 20.0, attempts: int = 3) -> Any:
    """The answer of service ``name`` to ``request``, as ``ros2 service call`` gives it, spinning
    ``node``: waits up to ``timeout_s`` for the service, then sends the request again when its answer
    is lost (:func:`pppbot_common.ros.retry.call_service`), so only for a request that may be sent
    twice (a query, setting a value).

    Raises:
        TimeoutExpired: no service, or no answer to any attempt within ``timeout_s``.
    """
    from pppbot_common.ros import retry

    client = node.create_client(srv_type, name)
    try:
        if not client.wait_for_service(timeout_sec=timeout_s):
            raise TimeoutExpired(f"no service {name} within {timeout_s:g} s")
        return retry.call_service(client, request, retry.Retry(timeout_s / attempts, attempts),
                                  retry.node_wait(node), node=node)
    finally:
        node.destroy_client(client)


def wait_for_future(future: Future, timeout_s: float, check: Callable[[], None] | None = None,
                    check_every_s: float = 0.05) -> bool:
    """Block this thread until ``future`` is done (another thread spins its node), at most
    ``timeout_s`` wall seconds; ``check`` runs every ``check_every_s`` and may raise to stop
    waiting. True when the future is done."""
    done = threading.Event()
    future.add_done_callback(lambda _: done.set())
    deadline = time.monotonic() + timeout_s
    while not done.is_set():
        if check is not None:
            check()
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            break
        done.wait(min(check_every_s, remaining))
    return future.done()


def change_state(node: Node, target: str, transition: int, label: str = "", timeout_s: float = 30.0) -> bool:
    """Ask lifecycle node ``target`` for ``transition`` (a ``lifecycle_msgs/msg/Transition`` id, or
    its ``label``) on its ``change_state`` service, as a lifecycle manager or ``ros2 lifecycle set``
    does, spinning ``node``; whether it succeeded. A request is sent again only when it was lost
    (:class:`pppbot_common.ros.retry.LifecycleCalls`).

    Raises:
        TimeoutExpired: no service or no answer within ``timeout_s``.
    """
    from pppbot_common.ros.retry import LifecycleCalls, Retry, node_wait

    calls = LifecycleCalls(node, target, Retry(timeout_s / 3, attempts=3), node_wait(node))
    try:
        for client in (calls.get_client, calls.change_client):
            if not client.wait_for_service(timeout_sec=timeout_s):
                raise TimeoutExpired(f"no {client.srv_name} service within {timeout_s:g} s")
        before_id = calls.state()[0]
        done = calls.change_state(transition, before_id, label)
        return done if done is not None else calls.state()[0] != before_id
    finally:
        calls.destroy()
