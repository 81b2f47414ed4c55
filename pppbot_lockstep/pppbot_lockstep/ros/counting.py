"""What a lockstep process sends, counted, and held until its next step.

Each :class:`~pppbot_lockstep.ros.port.StepPort` in lockstep owns one :class:`Counters` and one
:class:`Outbox`: the endpoints its nodes make (:mod:`pppbot_lockstep.ros.node`) report every
send to them. A participant's answer says whether its process sent anything (another round is
then needed) and how many messages it published per topic; each step carries the totals, and
the participant handles a step once its data-path subscriptions have them all
(:class:`pppbot_lockstep.protocol.Deliveries`).
"""
from __future__ import annotations

import array
import copy
import itertools
import threading
from collections.abc import Callable
from typing import Any

import numpy as np
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
    """In lockstep, what a participant sends to other processes goes out when the next step comes.

    Steps carry how many messages were published on each counted topic before them, and a
    participant handles a step once its subscriptions have that many. That only works if no
    message of the step at hand can arrive before it: a count says how many, not which. A
    transform that another participant publishes while handling the step would otherwise be
    counted in place of the simulator's, published before the step and still on its way; and
    what participants send while their timers run would reach the others before or after their
    own timers ran, depending on the machine's load.

    So, once time runs (:attr:`holding`), a send on a topic another process counts
    (:attr:`held_topics`, from the step) is held (counted at once, so the answer reports it and
    another round follows, unless no other process reacts to the topic, :attr:`quiet_topics`: then
    it goes with the next step, whenever that is); the answer seals what is held (:meth:`seal`); the next step sends
    what was sealed (:meth:`send_sealed`), before the participant waits for that step's messages.
    Everything one participant sends another in one round is thus handled in the next, by
    everyone, in the same order on every machine. What nobody else counts goes out at once while
    the participant is in a step (:attr:`in_step`, from its arrival until the answer): to the
    simulator's process, which waits for it after the answers, or to the participant itself, which
    handles it before answering (``on_own`` says which topics it counts), so a chain of nodes in one
    process takes one round; sent outside a step, it goes out right after the next answer.
    A message is serialized when it is held, so its sender may reuse it; a request is always held,
    copied, and its caller gets a :class:`HeldFuture`. Replies (a service's, an action's goal
    response and result) are not held: the client's steps wait for them, and a paused simulation
    still gets its answers.
    """

    def __init__(self, counters: Counters, on_own: Callable[[str], None] | None = None) -> None:
        self.counters = counters
        self.holding = False
        #: from a step's arrival until its answer: sends nobody else counts go out at once
        self.in_step = False
        #: the topics another lockstep process counts (held), and those this process counts
        self.held_topics: frozenset[str] = frozenset()
        self.own_topics: frozenset[str] = frozenset()
        #: of the held topics, those no other process reacts to: held without asking for a round
        self.quiet_topics: frozenset[str] = frozenset()
        self.lock = threading.Lock()
        self._on_own = on_own
        #: (send, whether it may go out with the answer: nobody else counts its topic)
        self._held: list[tuple[Callable[[], None], bool]] = []
        self._sealed: list[Callable[[], None]] = []
        self._with_answer: list[Callable[[], None]] = []

    def send(self, send: Callable[[], None], topic: str | None = None, *, asks_round: bool = True,
             hold: bool = False) -> None:
        """Count ``send`` (on ``topic``, when given) and do it now, or later when held (see the
        class; ``hold``: until the next step, while holding)."""
        with self.lock:
            if topic is not None:
                self.counters.published_on(topic)
            if not self.holding:
                if asks_round:
                    self.counters.sent()  # at time 0 everything goes out at once, and asks for a round
            else:
                others = hold or topic is None or topic in self.held_topics
                if not others and self.in_step:
                    if topic in self.own_topics and self._on_own is not None:
                        self._on_own(topic)  # handled before the answer
                else:
                    if asks_round and (others or topic in self.own_topics) \
                            and (hold or topic not in self.quiet_topics):
                        self.counters.sent()
                    self._held.append((send, not others))
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
        self.send(lambda: held.follow(send), key, hold=True)
        return held

    def seal(self) -> None:
        """The answer: what is held for others goes out at the next step, the rest right after the
        answer (:meth:`send_with_answer`); the step's handling ends (call with :attr:`lock` held, as
        the answer reads the counts)."""
        for send, with_answer in self._held:
            (self._with_answer if with_answer else self._sealed).append(send)
        self._held = []
        self.in_step = False

    def send_with_answer(self) -> None:
        """Send what nobody else counts, held since the step's answer was sealed (call after the answer)."""
        with self.lock:
            ready, self._with_answer = self._with_answer, []
        for send in ready:
            send()

    def send_sealed(self) -> None:
        """The next step came: send what was held for it."""
        with self.lock:
            sealed, self._sealed = self._sealed, []
        for send in sealed:
            send()

    def send_all(self) -> None:
        """Stop holding; send everything held, in order (the participant leaves)."""
        with self.lock:
            self.holding = False
            held = self._with_answer + self._sealed + [send for send, _ in self._held]
            self._with_answer, self._sealed, self._held = [], [], []
        for send in held:
            send()


def copied(value: Any) -> Any:
    """A ROS message copied (the sender may change it after the call); anything else as it is."""
    return _copy(value) if hasattr(type(value), "get_fields_and_field_types") else value


#: Field values a copy shares: they cannot change.
_IMMUTABLE = frozenset({int, float, str, bool, bytes, type(None)})
#: Each message class's slots (rosidl's classes keep their fields there).
_SLOTS: dict[type, tuple[str, ...]] = {}


def _copy(value: Any) -> Any:
    """A deep copy of a message (or a field's value), built slot by slot without the message's
    ``__init__``: 6 times faster than :func:`copy.deepcopy` (a path of 300 poses, a FollowPath
    goal, took 12 ms). Lists, ``array.array`` and numpy arrays are copied; what is not a
    rosidl message or one of those, deep-copied."""
    kind = type(value)
    if kind in _IMMUTABLE:
        return value
    if kind is list:
        return [_copy(item) for item in value]
    if kind is array.array:
        return array.array(value.typecode, value)
    if kind is np.ndarray:
        return value.copy()
    slots = _SLOTS.get(kind)
    if slots is None:
        if (not hasattr(kind, "get_fields_and_field_types") or "__slots__" not in vars(kind)
                or kind.__bases__ != (object,)):  # a subclass's own slots would leave its base's out
            return copy.deepcopy(value)
        slots = _SLOTS[kind] = tuple(vars(kind)["__slots__"])
    twin = object.__new__(kind)
    for slot in slots:
        object.__setattr__(twin, slot, _copy(getattr(value, slot)))
    return twin
