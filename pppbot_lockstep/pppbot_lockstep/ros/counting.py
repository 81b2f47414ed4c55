"""What a lockstep process sends, counted, and held until its next step.

Each :class:`~pppbot_lockstep.ros.port.StepPort` in lockstep owns one :class:`Counters` and one
:class:`Outbox`: the endpoints its nodes make (:mod:`pppbot_lockstep.ros.node`) report every
send to them. A participant's answer says whether its process sent anything (another round is
then needed) and how many messages it published per topic; each step carries the totals, and
the participant handles a step once its data-path subscriptions have them all
(:class:`pppbot_lockstep.protocol.Deliveries`).
"""
from __future__ import annotations

import copy
import itertools
import threading
from collections.abc import Callable
from typing import Any

import rclpy.task


class Counters:
    """What was sent and how many executor tasks were made (all counts only grow)."""

    def __init__(self) -> None:
        self._sends = itertools.count(1)
        self._tasks = itertools.count(1)
        self.sends = 0
        self.tasks = 0
        #: Messages published per topic, and requests per server key (the totals steps carry).
        self.published: dict[str, int] = {}

    def sent(self) -> None:
        """Something went out that others will act on: the round's answer asks for another."""
        self.sends = next(self._sends)

    def published_on(self, topic: str) -> None:
        self.published[topic] = self.published.get(topic, 0) + 1

    def task(self) -> None:
        self.tasks = next(self._tasks)


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

    So, once time runs (:attr:`holding`), every send is held (counted at once, so the answer
    reports it and another round follows); the answer seals what is held (:meth:`seal`); the
    next step sends what was sealed (:meth:`send_sealed`), before the participant waits for
    that step's messages. Everything sent in one round is thus handled in the next, by
    everyone, in the same order on every machine. A message is serialized when it is held, so
    its sender may reuse it; a request is copied and its caller gets a :class:`HeldFuture`.
    Replies (a service's, an action's goal response and result) are not held: the client's
    steps wait for them, and a paused simulation still gets its answers.
    """

    def __init__(self, counters: Counters) -> None:
        self.counters = counters
        self.holding = False
        self.lock = threading.Lock()
        self._held: list[Callable[[], None]] = []
        self._sealed: list[Callable[[], None]] = []

    def send(self, send: Callable[[], None], topic: str | None = None, *, asks_round: bool = True) -> None:
        """Count ``send`` (on ``topic``, when given) and do it now, or at the next step while holding."""
        with self.lock:
            if asks_round:
                self.counters.sent()
            if topic is not None:
                self.counters.published_on(topic)
            if self.holding:
                self._held.append(send)
                return
        send()

    def request(self, send: Callable[[], Any], key: str) -> Any:
        """A request counted on its server's ``key``: its future now, or a :class:`HeldFuture` while holding."""
        with self.lock:
            holding = self.holding
        if not holding:
            self.send(lambda: None, key)
            return send()
        held = HeldFuture()
        self.send(lambda: held.follow(send), key)
        return held

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


def copied(value: Any) -> Any:
    """A ROS message copied (the sender may change it after the call); anything else as it is."""
    return copy.deepcopy(value) if hasattr(type(value), "get_fields_and_field_types") else value
