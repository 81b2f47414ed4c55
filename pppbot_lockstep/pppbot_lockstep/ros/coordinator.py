"""The simulator's side of lockstep: steps out, answers in, time held until everyone is done.

At each sync time the simulator publishes ``/clock`` and a ``/lockstep/step``, then
handles callbacks until every participant has answered (its own in-process nodes, such as
a hosted controller, run in the same executor). While an answer says its participant sent
messages, another round at the same time follows; then time moves on to the next sync
time: the earliest timer a participant has due, or the next reading participants consume
(a scan). Participants the launch names (``lockstep_participants``) must join before time
starts, so every run starts the same way. A participant that does not answer within
``lockstep_timeout`` wall seconds is named, and the simulator stops (the launch then stops
the rest): a node that dies or hangs never leaves the stack waiting forever.

The bookkeeping is :class:`pppbot_lockstep.protocol.Barrier`; this is its ROS adapter.
"""
from __future__ import annotations

import functools
import time
from collections.abc import Callable, Sequence
from typing import Any

from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.serialization import serialize_message

from pppbot_common.ros.wire import MessageTemplate, stamp_fields, stamp_values
from pppbot_interfaces.msg import LockstepAck, LockstepStatus, LockstepStep
from pppbot_lockstep.errors import LockstepTimeout
from pppbot_lockstep.protocol import AckOutcome, Barrier, Deliveries, Publications, StepTimers
from pppbot_lockstep.ros.counting import Counters
from pppbot_lockstep.ros.participant import (
    ACK_TOPIC,
    PROTOCOL_QOS,
    STATUS_QOS,
    STATUS_TOPIC,
    STEP_TOPIC,
    stamp_ns,
    time_msg,
)
from pppbot_lockstep.ros.port import StepPort, Timer
from pppbot_lockstep.ros.runner import Process

#: Rounds at one time before the simulator moves on anyway (participants echoing each other).
MAX_ROUNDS = 50
#: Wall seconds between reminders of whom time waits for at its start.
START_REMINDER_S = 10.0
#: Wall seconds between repeats of the start time while time holds.
HEARTBEAT_S = 0.5
#: Wall seconds between the steps at time 0 that wait for everyone to settle, and their limit.
SETTLE_PAUSE_S = 0.05
SETTLE_TIMEOUT_S = 20.0
#: Wall seconds between repeats of a step not everyone has answered. A step goes only to the
#: participants' readers the simulator has discovered: a joiner's may still be unknown to it
#: (discovery matches each side on its own). Participants ignore a step they have had.
STEP_REPEAT_S = 1.0


class CoordinatorPort(StepPort):
    """The step port of the simulator's process (its own node and the nodes it hosts: controllers,
    robot_state_publisher, twist_mux): what they publish is counted, so that steps carry it and
    participants wait for it; what they receive on the data path is counted, so that time moves
    on only once they have it; their step timers fire at sync times, before the step goes out.
    Between rounds everything goes out at once; during a round (:attr:`holding`) what they send on
    a topic a participant counts is held until the next step, as a participant holds it."""

    counts = True

    def __init__(self) -> None:
        self.counters = Counters()
        #: What this process's nodes receive from participants
        self.deliveries = Deliveries()
        self.timers = StepTimers()
        #: Per topic, what this process has sent on it (its held sends not yet)
        self.released: dict[str, int] = {}
        self.holding = False
        #: The topics a participant counts (sends on them are held during a round), and those of
        #: them no participant reacts to (held without asking for another round)
        self.held_topics: frozenset[str] = frozenset()
        self.quiet_topics: frozenset[str] = frozenset()
        self._held: list[tuple[Callable[[], None], str | None]] = []

    def _out(self, send: Callable[[], None], topic: str | None, asks_round: bool) -> None:
        if topic is not None:
            self.counters.published_on(topic)
        if self.holding and (topic is None or topic in self.held_topics):
            if asks_round and topic not in self.quiet_topics:
                self.counters.sent()
            self._held.append((send, topic))
            return
        self._released(send, topic)

    def _released(self, send: Callable[[], None], topic: str | None) -> None:
        send()
        if topic is not None:
            self.released[topic] = self.released.get(topic, 0) + 1

    def release_held(self) -> None:
        """Send what was held in the last round (its counts are in the step about to go out)."""
        held, self._held = self._held, []
        for send, topic in held:
            self._released(send, topic)

    def publish(self, publisher: Publisher, msg: Any, topic: str, *, asks_round: bool = True) -> None:
        if self.holding and topic in self.held_topics and not isinstance(msg, bytes):
            msg = serialize_message(msg)  # held: its sender may change the message meanwhile
        self._out(functools.partial(Publisher.publish, publisher, msg), topic, asks_round)

    def send(self, send: Callable[[], None], topic: str | None = None, *, asks_round: bool = True) -> None:
        self._out(send, topic, asks_round)

    def request(self, send: Callable[..., Any], key: str, *args: Any) -> Any:
        self.counters.sent()
        self.counters.published_on(key)
        self.released[key] = self.released.get(key, 0) + 1
        return send(*args)

    def replied(self) -> None:
        self.counters.sent()  # a reply by one of this process's nodes may need another round too

    def counted(self, node: Node, topic: str, callback: Callable[[Any], None],
                quiet: bool | Callable[[], bool] = False) \
            -> Callable[[Any], None]:
        counted = self.deliveries.add(topic)  # the simulator's process reacts to all it counts

        def receive(msg: Any) -> None:
            try:
                callback(msg)
            finally:
                counted.received += 1
        return receive

    def create_timer(self, node: Node, period_s: float, callback: Callable[[], object], wakes: bool = True) -> Timer:
        return self.timers.create(period_s, callback, wakes)

    def fire_timers(self, t_ns: int, warn: Callable[[str], None]) -> None:
        """Run this process's step timers due by ``t_ns``, in their order."""
        for timer in self.timers.advance(t_ns):
            if timer.canceled:
                continue
            try:
                timer.callback()
            except Exception as exc:  # noqa: BLE001 - one failing timer must not stop the simulation
                warn(f"a timer callback failed: {type(exc).__name__}: {exc}")


class Coordinator:
    def __init__(self, node: Node, expected: list[str], timeout_s: float, log: Callable[[str], None],
                 port: CoordinatorPort) -> None:
        self.node = node
        self.barrier = Barrier(expected=set(expected))
        self.timeout_s = timeout_s
        self.log = log
        self.port = port
        self.rounds = 0
        self.steps = 0
        self.extra_rounds = 0
        self.repeats = 0
        # The protocol's own publishers: plain ones, not the port's (a step is not a round's work).
        self.step_pub = node.create_publisher(LockstepStep, STEP_TOPIC, PROTOCOL_QOS, publisher_class=Publisher)
        self.publications = Publications()
        self.deliveries = port.deliveries
        #: Per topic, what participants have sent that is out (not held for a step): this process waits for it
        self._others_sent: dict[str, int] = {}
        self.late_deliveries = 0
        self._step_wires: dict[tuple[str, ...], MessageTemplate] = {}
        self.status_pub = node.create_publisher(LockstepStatus, STATUS_TOPIC, STATUS_QOS, publisher_class=Publisher)
        node.create_subscription(LockstepAck, ACK_TOPIC, self._on_ack, PROTOCOL_QOS)
        self._members_published: tuple[list[str], list[str]] | None = None
        #: (settled, graph nodes) each participant answered the current step with
        self._readiness: dict[str, tuple[bool, int]] = {}
        self.publish_status(0)

    # --------------------------------------------------------------- answers
    def _on_ack(self, msg: LockstepAck) -> None:
        name = msg.participant
        if msg.kind == LockstepAck.JOIN:
            if name not in self.barrier.members and name not in self.barrier.joining:
                self.log(f"lockstep: '{name}' joins")
            self.barrier.join(name)
            self.publications.joined(name, msg.counted_topics, msg.quiet_topics)
            # Listed at once (waited for from the next step on); asked again, it missed the status.
            self.publish_status(self.barrier.stamp_ns, force=True)
        elif msg.kind == LockstepAck.LEAVE:
            if name in self.barrier.members or name in self.barrier.joining:
                self.log(f"lockstep: '{name}' leaves (so far: {self.steps} steps, {self.rounds} rounds)")
            self.barrier.leave(name)
            self.publications.left(name)
            self.publish_status(self.barrier.stamp_ns)
        elif msg.kind == LockstepAck.DONE:
            outcome = self.barrier.ack(name, msg.seq, msg.sent, stamp_ns(msg.next_wakeup))
            if outcome is AckOutcome.DUPLICATE:
                self.log(f"lockstep: '{name}' answered step {msg.seq} twice")
            elif outcome is AckOutcome.COUNTED:
                self._readiness[name] = (bool(msg.settled), int(msg.graph_nodes))
                self.publications.report(name, msg.published)
                if msg.counted_topics:  # sent when they changed
                    self.publications.counting(name, msg.counted_topics, msg.quiet_topics)

    def publish_status(self, t_ns: int, force: bool = False) -> None:
        """Who is waited for: members, and joiners (waited for from the next step on; an answer of
        theirs to the current one is ignored)."""
        members = sorted(self.barrier.members | self.barrier.joining)
        unjoined = self.barrier.unjoined()
        if not force and self._members_published == (members, unjoined):
            return
        self._members_published = (members, unjoined)
        self.status_pub.publish(LockstepStatus(stamp=time_msg(t_ns), participants=members, expected=unjoined))

    # ------------------------------------------------------------------ start
    def wait_for_start(self, process: Process, heartbeat: Callable[[], None]) -> bool:
        """Hold time at its start until every expected participant has joined, and then until all are
        settled (see :meth:`settle`); False when stopped. ``heartbeat`` runs every
        :data:`HEARTBEAT_S` meanwhile (the simulator republishes /clock, so that nodes starting
        now learn the time)."""
        reminded = beat = time.monotonic()
        while not self.barrier.may_start():
            if not process.running():
                return False
            process.spin_once(0.1)
            if time.monotonic() - beat > HEARTBEAT_S:
                beat = time.monotonic()
                heartbeat()
            if time.monotonic() - reminded > START_REMINDER_S:
                reminded = time.monotonic()
                self.log(f"lockstep: time holds at 0 until {', '.join(self.barrier.unjoined())} join(s)")
        return self.settle(process, heartbeat)

    def settle(self, process: Process, heartbeat: Callable[[], None]) -> bool:
        """Steps at time 0 until every participant answers settled (its data-path topics matched) and
        sees as many nodes as the simulator does: then discovery is over everywhere, and no message
        of the first steps can be lost to it. At most :data:`SETTLE_TIMEOUT_S` (then time starts anyway,
        with a warning naming who was not settled)."""
        deadline = time.monotonic() + SETTLE_TIMEOUT_S
        while process.running():
            self._readiness = {}
            self.sync(process, 0, readings=True, timers=False)
            nodes = len(self.node.get_node_names_and_namespaces())
            unsettled = sorted(name for name, (settled, seen) in self._readiness.items()
                               if not settled or seen != nodes)
            if not unsettled:
                return True
            if time.monotonic() > deadline:
                details = ", ".join(f"{n} (settled {self._readiness[n][0]}, sees {self._readiness[n][1]} of "
                                    f"{nodes} nodes)" for n in unsettled)
                self.log(f"lockstep: starting although not everyone is settled after {SETTLE_TIMEOUT_S:g} s: "
                         f"{details}")
                return True
            pause = time.monotonic() + SETTLE_PAUSE_S
            while time.monotonic() < pause and process.running():
                process.spin_once(SETTLE_PAUSE_S)
            heartbeat()
        return False

    # ------------------------------------------------------------------ steps
    def sync(self, process: Process, t_ns: int, readings: bool = True, timers: bool = True) -> None:
        """Steps at ``t_ns`` until no participant has anything left to do at this time. The first
        step has the simulator's readings (``readings``: it published what participants handle in
        steps, such as a scan) and, when ``timers``, says so: each participant handles the
        readings, its worker threads' work included, then runs its timers due. One round for both:
        what a participant sends is held for the next round, so its timers see what it made of the
        readings, and what the others made of them at the next sync time. Rounds follow while
        anyone sends.

        Raises:
            LockstepTimeout: a participant did not answer within ``timeout_s`` wall seconds.
        """
        self.steps += 1
        if readings or timers:
            self._rounds(process, t_ns, timers=timers)

    def _rounds(self, process: Process, t_ns: int, timers: bool) -> None:
        """Steps at ``t_ns`` until nobody sends (the first with ``timers``) or the process stops.

        Before each step this process sends what it held in the last round and, before the first,
        runs its timers due; then it waits until its own nodes have what it published (a hosted
        robot_state_publisher the joint states), so the step's totals hold what they sent in turn.
        After the answers it waits for what participants sent it at once (a command for twist_mux);
        what they hold for the next round (on topics a participant counts) comes with the next step.
        """
        port = self.port
        for index in range(MAX_ROUNDS):
            before = set(self.barrier.members)
            seq, _ = self.barrier.start_step(t_ns)
            if self.barrier.members != before:
                self.publish_status(t_ns)  # a joiner learns it is waited for before its first step
            port.holding = False
            port.release_held()
            if index == 0 and timers:
                port.fire_timers(t_ns, self.log)
            self.publications.want(self.deliveries.topics())
            topics = self.publications.next_topics()
            self._drain(process, t_ns)
            if not self.barrier.members:
                return
            own = self.deliveries.topics()
            counted_by = self.publications.counted_by(own) if topics else []
            reacted_by = self.publications.reacted_by(own) if topics else []
            port.held_topics = frozenset(t for t, n in zip(topics, counted_by, strict=True) if n > 0)
            port.quiet_topics = frozenset(t for t, n in zip(topics, self.publications.reacted_by(), strict=True)
                                          if n == 0)
            step_others = self.publications.others()
            values: dict[str, Any] = {"seq": seq, **stamp_values(t_ns, "stamp"), "round": index,
                                      "timers": timers and index == 0}
            # What was published before this step, participants' held sends included: they go out
            # as the participants get the step (see pppbot_lockstep.ros.counting.Outbox).
            if topics:
                values["published"] = self.publications.totals(port.counters.published)
                values["counted_by"] = counted_by
                values["reacted_by"] = reacted_by
            wire = self._step_wire(topics).serialize(values)
            port.holding = True
            self.step_pub.publish(wire)
            sends = port.counters.sends
            self.rounds += 1
            self._wait_for_answers(process, seq, t_ns, wire)
            if not process.running():
                return
            # Participants sent at once what no other participant counts: here by now, as they
            # answered; what they hold (on topics a participant counts) comes with the next step.
            others = self.publications.others()
            self._others_sent = {t: others.get(t, 0) if n == 0 else step_others.get(t, 0)
                                 for t, n in zip(topics, counted_by, strict=True)}
            self._drain(process, t_ns)
            if not self.barrier.another_round() and port.counters.sends == sends:
                port.holding = False
                return
            self.extra_rounds += 1
        port.holding = False
        self.log(f"lockstep: still sending after {MAX_ROUNDS} rounds at t = {t_ns * 1e-9:.3f} s "
                 f"({', '.join(self.barrier.senders()) or 'the simulator'}); time moves on")
        return

    def _step_wire(self, topics: tuple[str, ...]) -> MessageTemplate:
        """The step's template for these counted topics (they change only as participants join)."""
        wire = self._step_wires.get(topics)
        if wire is None:
            fields = ["seq", *stamp_fields("stamp"), "round", "timers"] + (
                ["published", "counted_by", "reacted_by"] if topics else [])
            zeros = [0] * len(topics)
            wire = self._step_wires[topics] = MessageTemplate(
                LockstepStep(topics=list(topics), published=zeros, counted_by=zeros, reacted_by=zeros), fields)
        return wire

    def _wait_for_answers(self, process: Process, seq: int, t_ns: int, wire: Any) -> None:
        """Until every member has answered step ``seq`` (repeated every :data:`STEP_REPEAT_S`)."""
        deadline = time.monotonic() + self.timeout_s
        repeat = time.monotonic() + STEP_REPEAT_S
        while not self.barrier.complete():
            if time.monotonic() > repeat:
                repeat = time.monotonic() + STEP_REPEAT_S
                self.repeats += 1
                self.step_pub.publish(wire)  # the protocol's own: not a send of the round's
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                missing = self.barrier.missing()
                raise LockstepTimeout(
                    f"lockstep: {', '.join(repr(n) for n in missing)} did not answer step {seq} "
                    f"(t = {t_ns * 1e-9:.3f} s) within lockstep_timeout = {self.timeout_s:g} s; stopping")
            if not process.running():
                return
            process.spin_once(min(remaining, 0.2))

    def _drain(self, process: Process, t_ns: int) -> None:
        """Until this process's nodes have what was sent them: what participants sent that is out
        (:attr:`_others_sent`) and what this process sent, including what its nodes send as they get
        it (a hosted twist_mux passing a command on). Time never moves on without them: after
        ``timeout_s`` the run stops, naming what did not come.

        Raises:
            LockstepTimeout: a message did not come within ``timeout_s``.
        """
        deliveries = self.deliveries
        if not deliveries.subscriptions:
            return
        topics = self.publications.topics
        released = self.port.released
        start = time.monotonic()
        waited = False
        while True:
            deliveries.expect(topics, [self._others_sent.get(t, 0) + released.get(t, 0) for t in topics])
            if t_ns == 0:
                deliveries.rebase()  # time holds at its start: discovery may have lost messages
                return
            lacking = deliveries.lacking()
            if not lacking or not process.running():
                return
            if time.monotonic() - start > self.timeout_s:
                raise LockstepTimeout(f"lockstep: at t = {t_ns * 1e-9:.3f} s the simulator's process did not get "
                                      f"messages published before the step within lockstep_timeout = "
                                      f"{self.timeout_s:g} s: {_lacking_text(lacking)}; stopping")
            if not waited:
                waited = True
                self.late_deliveries += 1
            process.spin_once(0.05)

    def next_wakeup_ns(self) -> int | None:
        """The next sync time a timer asks for: a participant's, or one of this process's nodes'."""
        due = [t for t in (self.barrier.next_wakeup_ns(), self.port.timers.next_wakeup_ns())
               if t is not None and t > self.barrier.stamp_ns]
        return min(due) if due else None

    @property
    def active(self) -> bool:
        """Whether anyone is waited for (without participants, time runs freely)."""
        return bool(self.barrier.members or self.barrier.joining)


def _lacking_text(lacking: Sequence[tuple[str, int, int]]) -> str:
    return ", ".join(f"{topic} ({expected - received} of {expected})" for topic, received, expected in lacking)
