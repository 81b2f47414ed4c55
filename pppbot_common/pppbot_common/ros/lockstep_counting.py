"""Counting for lockstep: what this process sends (per topic, and whether anything at all) and
what its data-path subscriptions receive.

:func:`install_counting` wraps rclpy's send methods once per process, so any node composed
into the process counts: a participant's answer says whether it sent anything (another
round is then needed) and how many messages it published per topic; each step carries the
totals, and a :class:`Receiver` tells whether its subscriptions have them all
(:class:`pppbot_common.lockstep.Deliveries`). Used by :mod:`pppbot_common.ros.lockstep`
(a participant) and by the simulator's coordinator.

The same wrappers hold a participant's sends until the next step (:class:`Outbox`).
"""
from __future__ import annotations

import copy
import functools
import inspect
import itertools
import threading
from collections.abc import Callable
from typing import Any, ClassVar

import rclpy.action.client
import rclpy.action.server
import rclpy.client
import rclpy.publisher
import rclpy.service
import rclpy.task
from rclpy.serialization import serialize_message

from pppbot_common.lockstep import Counted, Deliveries
from pppbot_common.ros.lockstep_requests import client_key, install_requests


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
#: Of those, the ones an :class:`Outbox` may hold back (the others answer a request as it comes,
#: or change the sender's own state), and which of them return a future.
HELD_METHODS = {"publish", "call_async", "send_goal_async", "_cancel_goal_async", "_get_result_async",
                "publish_feedback"}
FUTURE_METHODS = {"call_async", "send_goal_async", "_cancel_goal_async", "_get_result_async"}


class HeldFuture(rclpy.task.Future):
    """The future of a request an :class:`Outbox` holds: done when the request, once sent, is."""

    def __init__(self) -> None:
        super().__init__()
        self.sent = False
        self._when_sent: list[Callable[[], None]] = []

    def when_sent(self, callback: Callable[[], None]) -> None:
        """Run ``callback`` as the request goes out."""
        self._when_sent.append(callback)

    def follow(self, send: Callable[[], Any]) -> None:
        """Send the request now (``send`` returns its future) and complete with it."""
        self.sent = True
        for callback in self._when_sent:
            callback()
        send().add_done_callback(self._copy)

    def _copy(self, future: Any) -> None:
        if future.cancelled():
            self.cancel()
        elif future.exception() is not None:
            self.set_exception(future.exception())
        else:
            self.set_result(future.result())


class Outbox:
    """In lockstep, what a participant sends goes out when the next step comes.

    Steps carry how many messages were published on each counted topic before them, and a
    participant handles a step once its subscriptions have that many. That only works if no
    message of the step at hand can arrive before it: a count says how many, not which. A
    transform that another participant publishes while handling the step would otherwise be
    counted in place of the simulator's, published before the step and still on its way; and
    what participants send while their timers run would reach the others before or after their
    own timers ran, depending on the machine's load.

    So, once time runs, every send is held (counted at once, so the answer reports it and
    another round follows); the answer seals what is held (:meth:`seal`); the next step sends
    what was sealed (:meth:`send_sealed`), before the participant waits for that step's
    messages. Everything sent in one round is thus handled in the next, by everyone, in the
    same order on every machine. A message is serialized when it is held, so its sender may
    reuse it; a request is copied and its caller gets a :class:`HeldFuture`. Replies (a
    service's, an action's goal response and result) are not held: the client's steps wait
    for them (:func:`pppbot_common.ros.lockstep.hold_for`), and a paused simulation still
    gets its answers.
    """

    def __init__(self) -> None:
        self.holding = False
        self.lock = threading.Lock()
        self._held: list[Callable[[], None]] = []
        self._sealed: list[Callable[[], None]] = []

    def hold(self, send: Callable[[], None], topic: str | None = None, *, asks_round: bool = True) -> None:
        with self.lock:
            if asks_round:
                COUNTERS.sent()
            if topic is not None:
                COUNTERS.published_on(topic)
            self._held.append(send)

    def seal(self) -> None:
        """What is held so far goes out at the next step (call with :attr:`lock` held, as the
        answer reads the counts)."""
        self._sealed.extend(self._held)
        self._held = []

    def send_sealed(self) -> None:
        with self.lock:
            sealed, self._sealed = self._sealed, []
        for send in sealed:
            send()

    def send_all(self) -> None:
        """Stop holding; send everything held, in order (the participant leaves)."""
        with self.lock:
            self.holding = False
            held, self._sealed, self._held = self._sealed + self._held, [], []
        for send in held:
            send()


OUTBOX = Outbox()


def install_counting() -> None:
    """Count every send and every executor task of this process (once; idempotent)."""
    if COUNTERS.installed:
        return
    for cls, name in SEND_METHODS:
        method = getattr(cls, name)
        if name == "publish":
            wrapped = _counting_publish(method)
        elif name in HELD_METHODS:
            wrapped = _counting_held(method, returns_future=name in FUTURE_METHODS)
        else:
            wrapped = _counting(method)
        setattr(cls, name, wrapped)
    task_init = rclpy.task.Task.__init__

    @functools.wraps(task_init)
    def counting_init(self: Any, *args: Any, **kwargs: Any) -> None:
        COUNTERS.task()
        task_init(self, *args, **kwargs)

    rclpy.task.Task.__init__ = counting_init  # type: ignore[method-assign]
    install_requests()
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


def _counting_held(method: Callable[..., Any], returns_future: bool) -> Callable[..., Any]:
    @functools.wraps(method)
    def counted(self: Any, *args: Any, **kwargs: Any) -> Any:
        # A request is counted on its server's key, as a message on its topic (lockstep_requests).
        key = client_key(self) if returns_future else None
        if not OUTBOX.holding:
            COUNTERS.sent()
            if key is not None:
                COUNTERS.published_on(key)
            return method(self, *args, **kwargs)
        args = tuple(_copied(a) for a in args)
        kwargs = {k: _copied(v) for k, v in kwargs.items()}
        if not returns_future:
            OUTBOX.hold(lambda: method(self, *args, **kwargs))
            return None
        held = HeldFuture()
        OUTBOX.hold(lambda: held.follow(lambda: method(self, *args, **kwargs)), key)
        return held
    return counted


def _copied(value: Any) -> Any:
    """A ROS message copied (the sender may change it after the call); anything else as it is."""
    return copy.deepcopy(value) if hasattr(type(value), "get_fields_and_field_types") else value


def _counting_publish(method: Callable[..., Any]) -> Callable[..., Any]:
    @functools.wraps(method)
    def counted(self: Any, msg: Any) -> None:
        _publish(self, msg, asks_round=True)
    return counted


def _publish(publisher: Any, msg: Any, asks_round: bool) -> None:
    """Count and publish ``msg`` (held while the :data:`OUTBOX` is holding: serialized now, so
    the sender may reuse it)."""
    topic = _topic_of(publisher)
    if OUTBOX.holding:
        wire = msg if isinstance(msg, bytes) else serialize_message(msg)
        OUTBOX.hold(lambda: _ORIGINAL_PUBLISH(publisher, wire), topic, asks_round=asks_round)
        return
    if asks_round:
        COUNTERS.sent()
    COUNTERS.published_on(topic)
    _ORIGINAL_PUBLISH(publisher, msg)


def _topic_of(publisher: Any) -> str:
    """The publisher's topic, cached on it (rclpy asks rcl each time)."""
    try:
        return str(publisher._pppbot_topic)
    except AttributeError:
        publisher._pppbot_topic = publisher.topic_name
        return str(publisher._pppbot_topic)


def publish_aside(publisher: Any, msg: Any) -> None:
    """Publish a message nobody in lockstep reacts to at this time (a wheel's transform, for
    RViz): counted for delivery (and held like any other), but it asks for no further round."""
    _publish(publisher, msg, asks_round=False)


def publish_uncounted(publisher: Any, msg: Any) -> None:
    """Publish ``msg`` (a message or its serialized bytes) at once, outside lockstep's counts and
    rounds: for what no participant waits for (a camera's frames, rendered whenever they are)."""
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
