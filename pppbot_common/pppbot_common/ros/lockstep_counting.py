"""Counting for lockstep: what this process sends (per topic, and whether anything at all) and
what its data-path subscriptions receive.

:func:`install_counting` wraps rclpy's send methods once per process, so any node composed
into the process counts: a participant's answer says whether it sent anything (another
round is then needed) and how many messages it published per topic; each step carries the
totals, and a :class:`Receiver` tells whether its subscriptions have them all
(:class:`pppbot_common.lockstep.Deliveries`). Used by :mod:`pppbot_common.ros.lockstep`
(a participant) and by the simulator's coordinator.
"""
from __future__ import annotations

import functools
import inspect
import itertools
from typing import Any, Callable, ClassVar

import rclpy.action.client
import rclpy.action.server
import rclpy.client
import rclpy.publisher
import rclpy.service
import rclpy.task

from pppbot_common.lockstep import Counted, Deliveries

# --------------------------------------------------------------------------- counting
class _Counters:
    """Process-wide counts of what was sent and of executor tasks created (both only grow)."""

    def __init__(self) -> None:
        self._sends = itertools.count()
        self._tasks = itertools.count()
        self.sends = 0
        self.tasks = 0
        #: Messages published per topic (the totals steps carry; see :class:`Publications`).
        self.published: dict[str, int] = {}
        self.installed = False

    def sent(self) -> None:
        self.sends = next(self._sends) + 1

    def published_on(self, topic: str) -> None:
        self.published[topic] = self.published.get(topic, 0) + 1

    def task(self) -> None:
        self.tasks = next(self._tasks) + 1


COUNTERS = _Counters()
_ORIGINAL_PUBLISH = rclpy.publisher.Publisher.publish

#: rclpy's methods that put a message on the wire (rclpy 7.1, pinned): (class, method name).
SEND_METHODS: tuple[tuple[type, str], ...] = (
    (rclpy.publisher.Publisher, "publish"),
    (rclpy.client.Client, "call_async"),
    (rclpy.service.Service, "send_response"),
    (rclpy.action.client.ActionClient, "send_goal_async"),
    (rclpy.action.client.ActionClient, "_cancel_goal_async"),
    (rclpy.action.client.ActionClient, "_get_result_async"),
    (rclpy.action.server.ActionServer, "_execute_goal_request"),
    (rclpy.action.server.ActionServer, "_execute_cancel_request"),
    (rclpy.action.server.ActionServer, "_execute_get_result_request"),
    (rclpy.action.server.ActionServer, "_send_result_response"),
    (rclpy.action.server.ServerGoalHandle, "publish_feedback"),
    (rclpy.action.server.ServerGoalHandle, "_update_state"),
)


def install_counting() -> None:
    """Count every send and every executor task of this process (once; idempotent)."""
    if COUNTERS.installed:
        return
    for cls, name in SEND_METHODS:
        setattr(cls, name, _counting_publish(getattr(cls, name)) if name == "publish" else _counting(getattr(cls, name)))
    task_init = rclpy.task.Task.__init__

    @functools.wraps(task_init)
    def counting_init(self: Any, *args: Any, **kwargs: Any) -> None:
        COUNTERS.task()
        task_init(self, *args, **kwargs)

    rclpy.task.Task.__init__ = counting_init  # type: ignore[method-assign]
    COUNTERS.installed = True


def _counting(method: Callable[..., Any]) -> Callable[..., Any]:
    if inspect.iscoroutinefunction(method):
        @functools.wraps(method)
        async def counted_async(self: Any, *args: Any, **kwargs: Any) -> Any:
            COUNTERS.sent()
            return await method(self, *args, **kwargs)
        return counted_async

    @functools.wraps(method)
    def counted(self: Any, *args: Any, **kwargs: Any) -> Any:
        COUNTERS.sent()
        return method(self, *args, **kwargs)
    return counted


def _counting_publish(method: Callable[..., Any]) -> Callable[..., Any]:
    @functools.wraps(method)
    def counted(self: Any, msg: Any) -> Any:
        COUNTERS.sent()
        COUNTERS.published_on(_topic_of(self))
        return method(self, msg)
    return counted


def _topic_of(publisher: Any) -> str:
    """The publisher's topic, cached on it (rclpy asks rcl each time)."""
    try:
        return str(publisher._pppbot_topic)
    except AttributeError:
        publisher._pppbot_topic = publisher.topic_name
        return str(publisher._pppbot_topic)


def publish_aside(publisher: Any, msg: Any) -> None:
    """Publish a message nobody in lockstep reacts to at this time (a wheel's transform, for
    RViz): counted for delivery, but it asks for no further round."""
    COUNTERS.published_on(_topic_of(publisher))
    _ORIGINAL_PUBLISH(publisher, msg)


# -------------------------------------------------------------------------- receiving
class Receiver:
    """This process's count of what its data-path subscriptions receive (:func:`count_deliveries`):
    a participant's, or the simulator's for the nodes in its process. ``on_delivery`` runs after
    each counted message is handled."""

    _current: ClassVar[Receiver | None] = None

    def __init__(self, on_delivery: Callable[[], None]) -> None:
        self.deliveries = Deliveries()
        self.on_delivery = on_delivery

    @classmethod
    def start(cls, on_delivery: Callable[[], None]) -> Receiver:
        cls._current = cls(on_delivery)
        return cls._current

    @classmethod
    def current(cls) -> Receiver | None:
        return cls._current

    @classmethod
    def clear_current(cls) -> None:
        cls._current = None

    def count(self, subscription: Any) -> None:
        counted = self.deliveries.add(subscription.topic_name)
        subscription.callback = functools.partial(self._counting, subscription.callback, counted)

    def _counting(self, callback: Callable[[Any], None], counted: Counted, msg: Any) -> None:
        try:
            callback(msg)
        finally:
            counted.received += 1
            self.on_delivery()
