"""Lockstep's bookkeeping, without ROS: the simulator's barrier and a participant's timers.

In lockstep the simulator (the clock) stops at each sync time and sends a step; every
participant (a process with its nodes) answers once it has done its work for that time.
While any answer says the participant sent messages, another round at the same time
follows, so a message and everything it causes is handled before time moves on. The
next sync time is the earliest timer any participant has due (or a sensor reading).

:class:`Barrier` is the simulator's side: who is waited for, the answers of the current
round, and whether another round is needed. :class:`StepTimers` is a participant's
side: timers that fire on steps instead of on a clock, in a fixed order. Times are
integer nanoseconds of sim time. The protocol on the wire is ``pppbot_interfaces/msg/
Lockstep{Step,Ack,Status}``; the adapters are :mod:`pppbot_lockstep.ros.participant` and the
simulator node.
"""
from __future__ import annotations

import enum
import heapq
import itertools
import math
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, field

from pppbot_lockstep.errors import LockstepError


class AckOutcome(enum.Enum):
    """What :meth:`Barrier.ack` made of an answer."""

    COUNTED = "counted"
    STALE = "stale"  # an answer to an earlier step (or from a participant not waited for now)
    DUPLICATE = "duplicate"


@dataclass
class Barrier:
    """The simulator's view of the participants and of the step in progress.

    Participants named in ``expected`` must join before time starts (:meth:`may_start`);
    others may join at any time and are waited for from the next round on.
    """

    expected: set[str] = field(default_factory=set)
    members: set[str] = field(default_factory=set)
    #: Joined but not waited for yet: they become members when the next round starts.
    joining: set[str] = field(default_factory=set)
    seq: int = 0
    round: int = 0
    stamp_ns: int = 0
    #: Members that have answered the current step, and what they said.
    answered: dict[str, bool] = field(default_factory=dict)
    #: Members of the current step (a member that leaves during it is dropped here too).
    waiting_for: set[str] = field(default_factory=set)
    wakeups_ns: dict[str, int] = field(default_factory=dict)
    in_step: bool = False

    def join(self, name: str) -> None:
        """``name`` is ready; it is waited for from the next step on."""
        if not name:
            raise LockstepError("a participant joined without a name")
        if name not in self.members:
            self.joining.add(name)

    def leave(self, name: str) -> None:
        """``name`` stops: never waited for again (nor in the current step)."""
        self.members.discard(name)
        self.joining.discard(name)
        self.expected.discard(name)
        self.waiting_for.discard(name)
        self.answered.pop(name, None)
        self.wakeups_ns.pop(name, None)
        if self.in_step and set(self.answered) >= self.waiting_for:
            self.in_step = False  # the one left was the last one missing

    def may_start(self) -> bool:
        """Whether every expected participant has joined (time holds at its start until then)."""
        return not (self.expected - self.members - self.joining)

    def unjoined(self) -> list[str]:
        return sorted(self.expected - self.members - self.joining)

    def start_step(self, stamp_ns: int) -> tuple[int, int]:
        """Begin a step at ``stamp_ns``: round 0 at a new time, the next round at the same time.
        Joiners become members now. Returns (seq, round).

        Raises:
            LockstepError: a step is still in progress, or time went back.
        """
        if self.in_step:
            raise LockstepError(f"step {self.seq} is still waiting for {', '.join(self.missing())}")
        if stamp_ns < self.stamp_ns:
            raise LockstepError(f"time went back from {self.stamp_ns} ns to {stamp_ns} ns")
        self.round = self.round + 1 if stamp_ns == self.stamp_ns and self.seq > 0 else 0
        self.stamp_ns = stamp_ns
        self.seq += 1
        self.members |= self.joining
        self.joining.clear()
        self.waiting_for = set(self.members)
        self.answered = {}
        self.in_step = bool(self.waiting_for)
        return self.seq, self.round

    def ack(self, name: str, seq: int, sent: bool, next_wakeup_ns: int) -> AckOutcome:
        """Record ``name``'s answer to step ``seq``; ``next_wakeup_ns`` 0 means no timer due."""
        if seq != self.seq or name not in self.waiting_for:
            return AckOutcome.STALE
        if name in self.answered:
            return AckOutcome.DUPLICATE
        self.answered[name] = sent
        if next_wakeup_ns > 0:
            self.wakeups_ns[name] = next_wakeup_ns
        else:
            self.wakeups_ns.pop(name, None)
        if len(self.answered) == len(self.waiting_for):
            self.in_step = False
        return AckOutcome.COUNTED

    def missing(self) -> list[str]:
        """Members that have not answered the current step."""
        return sorted(self.waiting_for - set(self.answered)) if self.in_step else []

    def complete(self) -> bool:
        return not self.in_step

    def another_round(self) -> bool:
        """After a complete step: whether someone sent messages others have not handled yet."""
        return any(self.answered.values())

    def senders(self) -> list[str]:
        return sorted(name for name, sent in self.answered.items() if sent)

    def next_wakeup_ns(self) -> int | None:
        """The earliest time a member's timer is due, after the current time (None: no timer)."""
        due = [t for name, t in self.wakeups_ns.items() if name in self.members and t > self.stamp_ns]
        return min(due) if due else None


class StepTimer:
    """A periodic timer driven by steps (see :class:`StepTimers`); ``cancel`` and ``reset`` as rclpy's."""

    def __init__(self, owner: StepTimers, period_ns: int, callback: Callable[[], object], wakes: bool,
                 next_ns: int, ident: int) -> None:
        self.owner = owner
        self.period_ns = period_ns
        self.callback = callback
        #: Whether its deadline is a sync time (False: it fires at the first step at or after it).
        self.wakes = wakes
        self.next_ns = next_ns
        self.ident = ident
        self.canceled = False

    @property
    def timer_period_ns(self) -> int:
        return self.period_ns

    def cancel(self) -> None:
        self.canceled = True

    def is_canceled(self) -> bool:
        return self.canceled

    def reset(self) -> None:
        """Restart: the next call one period after the current sim time (uncancels, as rclpy's)."""
        self.canceled = False
        self.next_ns = self.owner.now_ns + self.period_ns
        self.owner.schedule(self)

    def destroy(self) -> None:
        self.canceled = True
        self.owner.remove(self)


class StepTimers:
    """Timers that fire on steps: at step time ``t`` every timer due by ``t`` fires once, in the
    order of their deadlines (then of their creation), and its next deadline is the first
    period boundary after ``t`` (missed periods are skipped, as rcl's timers skip them)."""

    def __init__(self) -> None:
        self.now_ns = 0
        self._timers: list[StepTimer] = []
        self._ids = itertools.count()

    def create(self, period_s: float, callback: Callable[[], object], wakes: bool = True) -> StepTimer:
        """A timer whose first call is one period from now.

        Raises:
            LockstepError: the period is not a positive number.
        """
        if not (math.isfinite(period_s) and period_s > 0):
            raise LockstepError(f"a timer period must be a positive number of seconds, not {period_s}")
        period_ns = max(1, round(period_s * 1e9))
        timer = StepTimer(self, period_ns, callback, wakes, self.now_ns + period_ns, next(self._ids))
        self._timers.append(timer)
        return timer

    def schedule(self, timer: StepTimer) -> None:
        if timer not in self._timers:
            self._timers.append(timer)

    def remove(self, timer: StepTimer) -> None:
        if timer in self._timers:
            self._timers.remove(timer)

    def advance(self, now_ns: int) -> list[StepTimer]:
        """Time is ``now_ns``: the timers due, in firing order, their next deadlines moved on.

        A timer that fires several times in one step (its period shorter than the gap)
        fires once.
        """
        self.now_ns = max(self.now_ns, now_ns)
        due = [(t.next_ns, t.ident, t) for t in self._timers if not t.canceled and t.next_ns <= self.now_ns]
        heapq.heapify(due)
        fired = []
        while due:
            _, _, timer = heapq.heappop(due)
            missed = (self.now_ns - timer.next_ns) // timer.period_ns
            timer.next_ns += (missed + 1) * timer.period_ns
            fired.append(timer)
        return fired

    def next_wakeup_ns(self) -> int | None:
        """The earliest deadline of a waking timer (None: none)."""
        due = [t.next_ns for t in self._timers if t.wakes and not t.canceled]
        return min(due) if due else None


# ----------------------------------------------------------------------------- delivery
# DDS keeps the order of one writer's messages only: a scan or a transform published before
# a step may reach a participant after the step (rarely, most often on a busy machine). So
# each step says how many messages the lockstep processes have published on the topics the
# participants wait for, and a participant handles the step only once it has received them.
class Publications:
    """The simulator's tally: per topic that a participant counts (its data-path subscriptions),
    how many messages the lockstep processes have published on it in all.

    Participants report their own cumulative counts with every answer, aligned with
    :attr:`topics` of the step answered; the simulator's process adds its own. Topics become
    counted at a step's start (:meth:`next_topics`), so one step's answers all share its list.
    """

    def __init__(self) -> None:
        self.topics: tuple[str, ...] = ()
        self._wanted: set[str] = set()
        #: Per participant, its last cumulative count per topic; their sums over participants.
        self._last: dict[str, dict[str, int]] = {}
        self._others: dict[str, int] = {}
        #: Per participant, the topics it counts, and those it is quiet on (handling sends nothing).
        self._counting: dict[str, frozenset[str]] = {}
        self._quiet: dict[str, frozenset[str]] = {}
        #: counted_by and reacted_by per (which, own topics): they change only as the above do
        self._memo: dict[tuple[str, frozenset[str]], list[int]] = {}

    def want(self, topics: Sequence[str]) -> None:
        """This process counts receptions on ``topics`` too (from the next step on)."""
        self._wanted.update(t for t in topics if t)

    def joined(self, name: str, topics: Sequence[str], quiet: Sequence[str] = ()) -> None:
        """``name`` (re)joined, counting ``topics``: a new process counts from zero."""
        self._last[name] = {}
        self.counting(name, topics, quiet)

    def counting(self, name: str, topics: Sequence[str], quiet: Sequence[str] = ()) -> None:
        """``name`` counts receptions on ``topics`` (from the next step on), quiet on ``quiet``."""
        self._counting[name] = frozenset(t for t in topics if t)
        self._quiet[name] = frozenset(quiet) & self._counting[name]
        self._memo.clear()
        self.want(topics)

    def left(self, name: str) -> None:
        """``name`` left: it counts nothing any more."""
        self._counting.pop(name, None)
        self._quiet.pop(name, None)
        self._memo.clear()

    def counted_by(self, own: Collection[str] = ()) -> list[int]:
        """Per topic of :attr:`topics`: how many lockstep processes count it, the simulator's (which
        counts ``own``) among them only when a participant counts it too.

        A participant holds what it sends on a topic some other process counts until its next step
        (the others then handle it in the next round, in the same order on every machine): where
        ``counted_by`` minus its own count is above zero. What only the simulator's process counts
        (it waits for it after the answers anyway), only the sender itself or nobody goes out at once.
        """
        def counted(topic: str) -> int:
            participants = sum(topic in counting for counting in self._counting.values())
            return participants + (1 if participants and topic in own else 0)
        return self._per_topic("counted", own, counted)

    def reacted_by(self, own: Collection[str] = ()) -> list[int]:
        """Per topic of :attr:`topics`: how many of the processes :meth:`counted_by` counts react to
        it (are not quiet on it; the simulator's process reacts to what it counts). A held send asks
        for another round at its time only where a process other than its sender reacts."""
        def reacting(topic: str) -> int:
            participants = sum(topic in counting for counting in self._counting.values())
            reacted = sum(topic in counting and topic not in self._quiet.get(name, frozenset())
                          for name, counting in self._counting.items())
            return reacted + (1 if participants and topic in own else 0)
        return self._per_topic("reacted", own, reacting)

    def _per_topic(self, which: str, own: Collection[str], count: Callable[[str], int]) -> list[int]:
        """``count`` of each topic of :attr:`topics`, kept (per ``which`` and ``own``) until they or
        what participants count change."""
        key = (which, frozenset(own))
        counts = self._memo.get(key)
        if counts is None:
            counts = self._memo[key] = [count(topic) for topic in self.topics]
        return list(counts)

    def others(self) -> dict[str, int]:
        """Per topic: what the participants have published on it in all, as they last reported."""
        return dict(self._others)

    def next_topics(self) -> tuple[str, ...]:
        """The counted topics for the step starting now (sorted; they only grow)."""
        if len(self._wanted) != len(self.topics):
            self.topics = tuple(sorted(self._wanted))
            self._memo.clear()
        return self.topics

    def report(self, name: str, counts: Sequence[int]) -> None:
        """``name``'s cumulative counts, aligned with :attr:`topics` (a shorter list: those first)."""
        last = self._last.setdefault(name, {})
        for topic, reported in zip(self.topics, counts, strict=False):  # counts may be shorter
            count = int(reported)
            delta = count - last.get(topic, 0)
            if delta > 0:
                self._others[topic] = self._others.get(topic, 0) + delta
                last[topic] = count

    def totals(self, own: Mapping[str, int]) -> list[int]:
        """Per topic of :attr:`topics`: what the participants and ``own`` (this process) published."""
        return [self._others.get(topic, 0) + own.get(topic, 0) for topic in self.topics]


@dataclass
class Counted:
    """One subscription a participant counts receptions on."""

    topic: str
    received: int = 0
    #: Messages published before it could receive them (None: not known yet, set at the next step).
    offset: int | None = None
    #: What it received beyond a step's total came from outside lockstep (a server's requests from a
    #: command line): taken as published before, so the next counted one is still waited for.
    catch_up: bool = False
    #: Handling a message sends nothing (a recording, a state timers read): see LockstepAck.quiet_topics.
    #: A callable is asked each time the participant tells its topics (a listener shared by a
    #: process's nodes is quiet while every node's reaction to it is).
    quiet: bool | Callable[[], bool] = False

    def is_quiet(self) -> bool:
        return self.quiet() if callable(self.quiet) else self.quiet


class Deliveries:
    """A participant's side: whether its counted subscriptions have received everything published
    on their topics before the step at hand."""

    def __init__(self) -> None:
        self.subscriptions: list[Counted] = []
        self.totals: dict[str, int] = {}

    def expect_own(self, topic: str) -> None:
        """This process sent one more message on ``topic`` (not held: only it counts the topic) and
        handles it in the step at hand."""
        if topic in self.totals:
            self.totals[topic] += 1

    def add(self, topic: str, catch_up: bool = False, quiet: bool | Callable[[], bool] = False) -> Counted:
        counted = Counted(topic, catch_up=catch_up, quiet=quiet)
        self.subscriptions.append(counted)
        return counted

    def remove(self, counted: Counted) -> None:
        if counted in self.subscriptions:
            self.subscriptions.remove(counted)

    def topics(self) -> list[str]:
        return sorted({c.topic for c in self.subscriptions})

    def quiet_topics(self) -> list[str]:
        """The topics every subscription of this process on which is quiet."""
        loud = {c.topic for c in self.subscriptions if not c.is_quiet()}
        return sorted({c.topic for c in self.subscriptions} - loud)

    def expect(self, topics: Sequence[str], totals: Sequence[int]) -> None:
        """A step's totals. A subscription that learns its topic's total for the first time takes
        what it has not received by then as published before it listened."""
        self.totals.update(zip(topics, (int(t) for t in totals), strict=False))
        for counted in self.subscriptions:
            if counted.topic not in self.totals:
                continue
            total = self.totals[counted.topic]
            if counted.offset is None or (counted.catch_up and counted.received > total - counted.offset):
                counted.offset = total - counted.received

    def lacking(self) -> list[tuple[str, int, int]]:
        """(topic, received, expected) of each subscription still waiting for messages."""
        out = []
        for c in self.subscriptions:
            if c.offset is not None and c.topic in self.totals:
                expected = self.totals[c.topic] - c.offset
                if c.received < expected:
                    out.append((c.topic, c.received, expected))
        return out

    def rebase(self) -> None:
        """Take everything not received so far as never coming (at time's start, when discovery may
        have lost messages, or after waiting for them in vain)."""
        for c in self.subscriptions:
            if c.topic in self.totals:
                c.offset = self.totals[c.topic] - c.received
