"""A process's part in lockstep: answer the simulator's steps once its nodes have done their work.

One :class:`Participant` per process (all its nodes share it; composition makes one participant
of many nodes): it is the process's :class:`~pppbot_lockstep.ros.port.StepPort`, made by the node
runner when the process is started with ``-p lockstep:=true`` (``lockstep_name`` names it; default:
the process's name) and handed to each node. Without it the nodes get the free-running port and
nothing here is active.

What a participant does, on the protocol of :mod:`pppbot_lockstep.protocol`:

* **Join.** Once spinning, and once its nodes have what they need to handle their first
  messages (:meth:`~pppbot_lockstep.ros.port.StepPort.require`: AMCL its map, SLAM the robot's
  static transforms), it sends JOIN on ``/lockstep/ack`` until the simulator lists it on
  ``/lockstep/status``; from then on time waits for it. LEAVE when it stops.
* **Steps.** On each ``/lockstep/step`` it sets its nodes' clocks to the step's time, runs
  the work readings from the simulator set off (:meth:`in_step`, :meth:`at_step`), on a step
  that says so fires the timers due (:meth:`create_timer`: timers that run on steps, in a
  fixed order, instead of on the clock), then answers DONE once nothing is left to run: no
  executor task made since (a future's callbacks, an action's goal: the process's
  :class:`~pppbot_lockstep.ros.node.StepExecutor` tells), and no work held by a thread
  (:meth:`hold`). The answer says whether the process sent anything since its previous
  answer (its nodes' endpoints report every send) and when its next timer is due. The
  simulator repeats a step until everyone has answered (a joiner's reader may be unknown to it
  yet); each is taken once.

DDS orders messages per writer only: a scan or a transform published before a step usually,
not always, arrives before it (most often not on a busy machine). So every publish is counted
per topic, answers carry the counts, each step the totals of the topics participants count (their
data-path subscriptions), and a participant handles a step only once those have received that
many (:class:`~pppbot_lockstep.protocol.Deliveries`); one that waits longer than
``lockstep_timeout`` names what it lacks and leaves, and the simulator stops the run: a step never
goes on without its messages. For the counts to name the right messages, what a participant sends
while time runs is held until its next step (:class:`~pppbot_lockstep.ros.counting.Outbox`):
everything sent in one round is handled in the next. Replies are not held; the step at which a
request goes out waits for the prompt reply (:meth:`hold_for`); a result that comes whenever the
server is done is seen at the first tick after it came (:class:`pppbot_lockstep.ros.goals.Arrival`).
"""
from __future__ import annotations

import functools
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

from builtin_interfaces.msg import Time as TimeMsg
from rclpy.clock import ClockType, ROSClock
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from rclpy.time import Time

from pppbot_common.ros.wire import MessageTemplate, stamp_fields, stamp_values
from pppbot_common.throttle import Throttle
from pppbot_interfaces.msg import LockstepAck, LockstepStatus, LockstepStep
from pppbot_lockstep.errors import LockstepError
from pppbot_lockstep.protocol import Counted, Deliveries, StepTimer, StepTimers
from pppbot_lockstep.ros.counting import Counters, HeldFuture, Outbox, copied
from pppbot_lockstep.ros.port import StepPort, Timer
from pppbot_lockstep.ros.requests import Execute, Requests

STEP_TOPIC = "/lockstep/step"
ACK_TOPIC = "/lockstep/ack"
STATUS_TOPIC = "/lockstep/status"
#: Steps and answers are never dropped and never replayed to a late joiner.
PROTOCOL_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.VOLATILE)
#: Who time waits for: the last status, also for late subscribers.
STATUS_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: Wall seconds between JOINs until the simulator lists the participant.
JOIN_RESEND_S = 0.5
#: Wall seconds after which a participant still waiting for a step's messages says so (it goes on
#: waiting: the simulator's lockstep_timeout ends a run that truly lost one).
DELIVERY_WARN_S = 2.0
WARN_PERIOD_S = 5.0


def stamp_ns(stamp: TimeMsg) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def time_msg(ns: int) -> TimeMsg:
    sec, nanosec = divmod(int(ns), 1_000_000_000)
    return TimeMsg(sec=sec, nanosec=nanosec)


class Participant(StepPort):
    """This process's lockstep participant and its nodes' step port (see the module's docstring).

    ``node`` is the participant's own hidden node (``_lockstep_<name>``), in the process's context.
    """

    lockstep = True
    counts = True

    def __init__(self, name: str, node: Node) -> None:
        if not name:
            raise LockstepError("parameter 'lockstep_name' = '': a lockstep participant needs a name")
        self.name = name
        self.node = node
        self.timers = StepTimers()
        self.counters = Counters()
        self.requests = Requests()
        self.deliveries = Deliveries()
        self.outbox = Outbox(self.counters, on_own=self.deliveries.expect_own)
        self._joined = False
        self._executor: Any = None
        self._nodes: list[Node] = []
        self._lock = threading.Lock()
        self._holds = 0
        self._pending_seq: int | None = None
        self._early_step: LockstepStep | None = None
        self._last_seq = 0  # the last step taken since joining (the simulator repeats a step until all answer)
        self._counted_topics: tuple[list[str], list[str]] = ([], [])  # counted, quiet: as last told
        self._waiting_step: LockstepStep | None = None  # until the messages published before it are here
        self._waiting_since = 0.0
        self._done_wires: dict[int, MessageTemplate] = {}
        self._task_mark = 0
        self._sends_at_answer = 0
        self._last_join = -1e9
        self._throttle = Throttle(WARN_PERIOD_S)
        self._requirements: set[str] = set()
        self._deferred: dict[Callable[[], None], None] = {}  # in order, each once
        self._conditions: list[tuple[str, Callable[[], bool]]] = []
        self.steps = 0
        self._last_step_ns = 0
        self._timers_ns = -1  # the time timers last ran at
        #: The current step's timers wait until the process is done with the step's readings.
        self._timers_due = False
        self.ack_pub = node.create_publisher(LockstepAck, ACK_TOPIC, PROTOCOL_QOS)
        self._step_topics: tuple[str, ...] = ()
        self._holding_key: tuple[tuple[str, ...], tuple[int, ...], tuple[int, ...], tuple[str, ...]] | None = None
        self._awaiting_own = False  # an answer waits for a message this process sent itself
        node.create_subscription(LockstepStep, STEP_TOPIC, self._on_step, PROTOCOL_QOS)
        node.create_subscription(LockstepStatus, STATUS_TOPIC, self._on_status, STATUS_QOS)

    @classmethod
    def from_parameters(cls, default_name: str, spare: list[Node]) -> Participant | None:
        """The process's participant when its parameters say ``lockstep:=true`` (else None). Its node
        is hidden (``_lockstep_<name>``) and belongs to the default context.

        Without lockstep the node that read the parameters goes to ``spare``, for the caller to
        destroy once its own nodes exist: the last node of a context takes the context's DDS
        participant with it, and a participant destroyed while discovery is under way can hang
        Fast DDS for good (its ``set_listener`` waits for a discovery callback that waits for it).

        Raises:
            LockstepError: ``lockstep_name`` is empty.
        """
        node = Node(f"_lockstep_{_node_safe(default_name)}", start_parameter_services=False, enable_rosout=False)
        enabled = bool(node.declare_parameter("lockstep", False).value)
        name = str(node.declare_parameter("lockstep_name", default_name).value)
        if not enabled:
            spare.append(node)
            return None
        try:
            return cls(name, node)
        except LockstepError:
            node.destroy_node()
            raise

    def start(self, executor: Any, nodes: Sequence[Node]) -> None:
        """Spinning starts with ``executor``; ``nodes`` get their clocks set to each step's time."""
        self._executor = executor
        self._nodes = list(nodes)
        self.maintain()

    @property
    def joined(self) -> bool:
        return self._joined

    # ----------------------------------------------------------- the port: sends
    def publish(self, publisher: Publisher, msg: Any, topic: str, *, asks_round: bool = True) -> None:
        if self.outbox.holding and not isinstance(msg, bytes):
            msg = serialize_message(msg)  # held: its sender may change the message meanwhile
        self.outbox.send(functools.partial(Publisher.publish, publisher, msg), topic, asks_round=asks_round)

    def send(self, send: Callable[[], None], topic: str | None = None, *, asks_round: bool = True) -> None:
        self.outbox.send(send, topic, asks_round=asks_round)

    def request(self, send: Callable[..., Any], key: str, *args: Any) -> Any:
        if self.outbox.holding:
            args = tuple(copied(a) for a in args)
        return self.outbox.request(functools.partial(send, *args), key)

    def replied(self) -> None:
        # A reply (a goal accepted, a service's answer) or a goal's new state: the client acts on it,
        # so another round at this time lets that happen at this time.
        self.counters.sent()

    def task_created(self) -> None:
        self.counters.task()

    # ------------------------------------------------------ the port: receptions
    def counted(self, node: Node, topic: str, callback: Callable[[Any], None],
                quiet: bool | Callable[[], bool] = False) \
            -> Callable[[Any], None]:
        counted = self.deliveries.add(topic, quiet=quiet)

        def receive(msg: Any) -> None:
            try:
                callback(msg)
            finally:
                counted.received += 1
                self._on_delivery()
        return receive

    def serve(self, node: Node, key: str, callback: Callable[..., Any], make_kept: Callable[[Any], Any]) \
            -> Callable[..., Any]:
        counted = self.deliveries.add(key, catch_up=True)

        def handle(request: Any, response: Any) -> Any:
            kept = make_kept(request)
            keeping = self.requests.keep(key, kept.execute)
            self._taken(counted, 1)
            return kept if keeping else callback(request, response)
        return handle

    def count_requests(self, node: Node, key: str) -> Counted:
        return self.deliveries.add(key, catch_up=True)

    def take_requests(self, counted: Any, key: str, execute: Execute, requests: int) -> bool:
        # Kept (or not) before it is counted: the count may let the step be handled, which then
        # runs what is kept, in order.
        keeping = self.requests.keep(key, execute)
        self._taken(counted, requests)
        return keeping

    def _taken(self, counted: Counted, requests: int) -> None:
        counted.received += requests
        self._on_delivery()

    # ---------------------------------------------------------- the port: timers
    def create_timer(self, node: Node, period_s: float, callback: Callable[[], object], wakes: bool = True) -> Timer:
        return self.timers.create(period_s, callback, wakes)

    # ------------------------------------------------------------ the port: work
    def in_step(self, work: Callable[[], None]) -> None:
        if not self._joined:
            work()
        else:
            self.defer(work)

    def hold(self) -> Callable[[], None]:
        """A thread of this process has work the current step must wait for (call in the executor's
        thread, when the work is handed over); the returned function says it is done."""
        with self._lock:
            self._holds += 1
        return self.release

    def hold_for(self, future: Any) -> Callable[[], None]:
        if isinstance(future, HeldFuture) and not future.sent:
            future.when_sent(self._hold_now)
        else:
            self._hold_now()
        return self._replied

    def _hold_now(self) -> None:
        with self._lock:
            self._holds += 1

    def _replied(self) -> None:
        # The server may have handled the request after answering this round: what it sent then
        # is held for its next answer. Another round at this time lets that answer come, so the
        # request's consequences are handled at this time whichever came first.
        self.counters.sent()
        self.release()

    def release(self) -> None:
        """Work held is done (any thread); answers a step that waited for it."""
        with self._lock:
            self._holds -= 1
            if self._holds < 0:
                self._holds = 0
                raise LockstepError(f"lockstep participant '{self.name}': release() without hold()")
        self._answer_if_free()

    # ---------------------------------------------------------- the port: joining
    def require(self, what: str) -> Callable[[], None]:
        self._requirements.add(what)
        return functools.partial(self._requirements.discard, what)

    def require_when(self, what: str, condition: Callable[[], bool]) -> None:
        self._conditions.append((what, condition))

    def require_match(self, node: Node, endpoint: Any, what: str = "") -> None:
        topic = endpoint.topic_name
        if isinstance(endpoint, Publisher):
            self.require_when(what or f"a subscriber of {topic}", lambda: endpoint.get_subscription_count() > 0)
        else:
            self.require_when(what or f"the publishers of {topic}",
                              lambda: endpoint.get_publisher_count() >= max(1, node.count_publishers(topic)))

    def _unmet(self) -> list[str]:
        return sorted(self._requirements | {what for what, ok in self._conditions if not ok()})

    def _graph_nodes(self) -> int:
        return len(self.node.get_node_names_and_namespaces())

    # -------------------------------------------------------------------- joining
    def maintain(self) -> None:
        """Called by the spin loop: (re)send JOIN until the simulator lists this participant; say what
        a step still waits for once it has waited :data:`DELIVERY_WARN_S`."""
        if self._waiting_step is not None:
            self._try_step()
        elif self._awaiting_own and not self.deliveries.lacking():
            self._awaiting_own = False
            self._post_idle_check()
        if self._waiting_step is None:  # a kept request may be this step's, waited for
            self.requests.overdue(self._executor.create_task)
        if self._joined or self.ack_pub.get_subscription_count() == 0:
            return
        now = time.monotonic()
        if now - self._last_join < JOIN_RESEND_S:
            return
        self._last_join = now
        unmet = self._unmet()
        if unmet:
            self._warn("requirements", f"lockstep: '{self.name}' joins once it has {', '.join(unmet)}")
            return
        self._counted_topics = counted, quiet = self.deliveries.topics(), self.deliveries.quiet_topics()
        self._send(LockstepAck(kind=LockstepAck.JOIN, participant=self.name, settled=True,
                               graph_nodes=self._graph_nodes(), counted_topics=counted, quiet_topics=quiet))

    def _on_delivery(self) -> None:
        if self._waiting_step is not None:
            self._try_step()
        elif self._awaiting_own:
            self._awaiting_own = False
            self._post_idle_check()

    def _on_status(self, msg: LockstepStatus) -> None:
        listed = self.name in msg.participants
        joining = listed and not self._joined
        if joining:
            self.node.get_logger().info(f"lockstep: joined as '{self.name}'")
            self._last_seq = 0  # a simulator started anew counts steps from 1 again
        self._joined = listed
        early, self._early_step = self._early_step, None
        if joining and early is not None:
            # The simulator lists a joiner just before its first step, on another topic: the step
            # may come first. Answered now (an answer to a step from before the listing is ignored).
            self._on_step(early)

    def leave(self) -> None:
        """Tell the simulator to stop waiting for this process (it is ending)."""
        if self._joined:
            self._joined = False
            self.outbox.send_all()
            if self._executor is not None:
                self.requests.overdue(self._executor.create_task, everything=True)
            try:
                self._send(LockstepAck(kind=LockstepAck.LEAVE, participant=self.name))
                self.ack_pub.wait_for_all_acked(Duration(seconds=1.0))
            except Exception:  # noqa: BLE001 - the context may be going down already
                pass

    # ---------------------------------------------------------------------- steps
    def _on_step(self, msg: LockstepStep) -> None:
        if not self._joined:
            self._early_step = msg  # the simulator may wait for us already (see _on_status)
            return
        if msg.seq <= self._last_seq:
            return  # a repeat, for a participant that missed it
        self._last_seq = msg.seq
        with self.outbox.lock:
            self.outbox.in_step = True  # until the answer: what nobody else counts goes out at once
        self.outbox.send_sealed()  # what this process sent in the last round (see Outbox)
        self._step_topics = tuple(msg.topics)
        self._update_held_topics(tuple(msg.counted_by), tuple(msg.reacted_by))
        self.deliveries.expect(msg.topics, msg.published)
        if stamp_ns(msg.stamp) == 0:
            self.deliveries.rebase()  # time holds at its start: discovery may have lost messages
        else:
            self.requests.leave_step(time_runs=True)  # requests taken until it is handled wait for it
        self._waiting_step, self._waiting_since = msg, time.monotonic()
        self._try_step()

    def _update_held_topics(self, counted_by: tuple[int, ...], reacted_by: tuple[int, ...] = ()) -> None:
        """The topics whose sends are held (another process counts them), those of them no other
        process reacts to (held without asking for a round), and those this process counts, from
        the step (they change only as subscriptions are made)."""
        own = tuple(self.deliveries.topics())
        key = (self._step_topics, counted_by, reacted_by, own)
        if key == self._holding_key:
            return
        self._holding_key = key
        mine = set(own)
        loud = mine - set(self.deliveries.quiet_topics())
        reacted = reacted_by if len(reacted_by) == len(counted_by) else counted_by  # (an older simulator)
        with self.outbox.lock:
            self.outbox.held_topics = frozenset(
                topic for topic, count in zip(self._step_topics, counted_by, strict=False)
                if count - (topic in mine) > 0)
            self.outbox.quiet_topics = frozenset(
                topic for topic, count in zip(self._step_topics, reacted, strict=False)
                if topic in self.outbox.held_topics and count - (topic in loud) <= 0)
            self.outbox.own_topics = frozenset(mine)

    def _try_step(self) -> None:
        """Handle the waiting step once every message published before it is here; say what it waits
        for once it has waited :data:`DELIVERY_WARN_S` (the simulator's ``lockstep_timeout`` ends a
        run whose message never comes: a step never goes on without its messages)."""
        msg = self._waiting_step
        if msg is None:
            return
        lacking = self.deliveries.lacking()
        if lacking:
            if time.monotonic() - self._waiting_since >= DELIVERY_WARN_S:
                self._warn("delivery", f"lockstep: step {msg.seq} (t = {stamp_ns(msg.stamp) * 1e-9:.3f} s) waits "
                                       f"for messages published before it: " + ", ".join(
                                           f"{topic} ({expected - received} of {expected})"
                                           for topic, received, expected in lacking))
            return
        self._waiting_step = None
        self._handle_step(msg)

    def _handle_step(self, msg: LockstepStep) -> None:
        self.steps += 1
        t_ns = self._last_step_ns = stamp_ns(msg.stamp)
        self._set_clocks(t_ns)
        # The step's time for timers (re)started now, before the timers run (a goal's).
        self.timers.now_ns = max(self.timers.now_ns, t_ns)
        if t_ns > 0:
            self.outbox.holding = True  # from now on sends are held (at time 0 they need no order)
        self._run_deferred()
        self.requests.enter_step(self._run_request)
        timers_due = msg.timers and t_ns > self._timers_ns
        if timers_due:
            self._timers_ns = t_ns
        with self._lock:
            self._pending_seq = msg.seq
            # The timers run once the readings' work is done, a worker thread's included
            # (:meth:`hold`): a timer sees what its own process made of this time's readings
            # (SLAM's transform after the scan's match), on every machine.
            self._timers_due = timers_due
        self._post_idle_check()

    def _fire_timers_due(self) -> None:
        """Run the step's timers due (in the executor's thread), then answer once idle again."""
        with self._lock:
            if not self._timers_due or self._pending_seq is None or self._holds > 0:
                return
            self._timers_due = False
        for timer in self.timers.advance(self._timers_ns):
            if not timer.canceled:
                self._fire(timer)
        self._post_idle_check()

    def defer(self, work: Callable[[], None]) -> None:
        """Run ``work`` at the next step (once, however often deferred meanwhile)."""
        self._deferred[work] = None

    def _run_deferred(self) -> None:
        while self._deferred:
            work = next(iter(self._deferred))
            del self._deferred[work]
            try:
                work()
            except Exception as exc:  # noqa: BLE001 - as a failing timer
                self._warn(f"deferred:{getattr(work, '__qualname__', work)}",
                           f"deferred work failed: {type(exc).__name__}: {exc}")

    def _set_clocks(self, t_ns: int) -> None:
        """The step's time on every node's clock that runs on sim time (normally /clock, which the
        simulator sends just before the step, has set it already)."""
        for node in self._nodes:
            clock = node.get_clock()
            if isinstance(clock, ROSClock) and clock.ros_time_is_active and clock.now().nanoseconds < t_ns:
                clock.set_ros_time_override(Time(nanoseconds=t_ns, clock_type=ClockType.ROS_TIME))

    def _fire(self, timer: StepTimer) -> None:
        try:
            timer.callback()
        except Exception as exc:  # noqa: BLE001 - one failing timer must not stop the process's answers
            self._warn(f"timer:{timer.ident}", f"a timer callback failed: {type(exc).__name__}: {exc}")

    def _post_idle_check(self) -> None:
        """Answer once every task queued so far has run: a task created meanwhile posts the check again."""
        self._executor.create_task(self._idle_check)
        self._task_mark = self.counters.tasks

    def _idle_check(self) -> None:
        if self.counters.tasks != self._task_mark:
            self._post_idle_check()
            return
        if self._timers_due:
            self._fire_timers_due()
            return
        self._answer_if_free()

    def _run_request(self, execute: Execute) -> None:
        """Handle a request kept for this step before answering it."""
        self._hold_now()

        async def run() -> None:
            try:
                await execute()
            finally:
                self.release()
        self._executor.create_task(run)

    def _answer_if_free(self) -> None:
        with self._lock:
            if self._pending_seq is None or self._holds > 0:
                return
            if self.deliveries.lacking():  # what it sent itself, on its way to its own nodes
                self._awaiting_own = True
                return
            timers_due = self._timers_due
            if not timers_due:
                seq, self._pending_seq = self._pending_seq, None
                self.requests.leave_step(self.outbox.holding)
        if timers_due:  # released by a worker thread: the timers run in the executor's (a task is thread-safe)
            self._executor.create_task(self._fire_timers_due)
            return
        with self.outbox.lock:  # the counts answered are those of the sends held so far
            self.outbox.seal()
            sends = self.counters.sends
            published = [self.counters.published.get(topic, 0) for topic in self._step_topics]
        sent, self._sends_at_answer = sends > self._sends_at_answer, sends
        wakeup = self.timers.next_wakeup_ns()
        starting = self._last_step_ns == 0  # time holds at its start: the simulator asks whether all is set
        values: dict[str, Any] = {"seq": seq, "sent": sent, **stamp_values(wakeup or 0, "next_wakeup"),
                                  "settled": not starting or not self._unmet(),
                                  "graph_nodes": self._graph_nodes() if starting else 0}
        counted_topics = (self.deliveries.topics(), self.deliveries.quiet_topics())
        if counted_topics != self._counted_topics:  # a subscription made since: told once
            self._counted_topics = counted_topics
            self._send(LockstepAck(kind=LockstepAck.DONE, participant=self.name, published=published,
                                   counted_topics=counted_topics[0], quiet_topics=counted_topics[1],
                                   **_message_values(values)))
            self.outbox.send_with_answer()
            return
        if published:
            values["published"] = published
        self.ack_pub.publish(self._done_wire(len(published)).serialize(values))
        self.outbox.send_with_answer()

    def _done_wire(self, topics: int) -> MessageTemplate:
        """DONE's template for a step with ``topics`` counted topics."""
        wire = self._done_wires.get(topics)
        if wire is None:
            fields = ["seq", "sent", *stamp_fields("next_wakeup"), "settled", "graph_nodes"]
            wire = self._done_wires[topics] = MessageTemplate(
                LockstepAck(kind=LockstepAck.DONE, participant=self.name, published=[0] * topics),
                fields + (["published"] if topics else []))
        return wire

    def _send(self, msg: LockstepAck) -> None:
        self.ack_pub.publish(msg)  # the protocol's own messages are not "sent" work (a plain publisher)

    def _warn(self, key: str, text: str) -> None:
        if self._throttle.allow(key, time.monotonic()):
            self.node.get_logger().warning(text)


def _message_values(values: dict[str, Any]) -> dict[str, Any]:
    """Template values (:func:`stamp_values` fields) as message constructor arguments."""
    out = {k: v for k, v in values.items() if "." not in k}
    out["next_wakeup"] = TimeMsg(sec=values["next_wakeup.sec"], nanosec=values["next_wakeup.nanosec"])
    return out


def _node_safe(name: str) -> str:
    safe = "".join(ch if ch.isalnum() or ch == "_" else "_" for ch in name)
    return safe if safe and not safe[0].isdigit() else f"_{safe}"
