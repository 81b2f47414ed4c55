"""A process's part in lockstep: answer the simulator's steps once its nodes have done their work.

One :class:`Participant` per process (all its nodes share it; composition makes one
participant of many nodes). It runs when the process is started with the parameter
``lockstep:=true`` (``--ros-args -p lockstep:=true``); ``lockstep_name`` names it
(default: the process's name). Without it nothing here is active and the nodes' timers
are ordinary rclpy timers on the ROS clock.

What a participant does, on the protocol of :mod:`pppbot_common.lockstep`:

* **Join.** Once spinning, and once its nodes have what they need to handle their first
  messages (:func:`require`: AMCL its map, SLAM the robot's static transforms), it sends
  JOIN on ``/lockstep/ack`` until the simulator lists it on ``/lockstep/status``; from
  then on time waits for it. LEAVE when it stops.
* **Steps.** On each ``/lockstep/step`` it sets its nodes' clocks to the step's time, runs
  the work readings from the simulator set off (:func:`at_step`, :func:`in_step`), on a
  step that says so fires the timers due (timers made with :func:`create_timer`: they
  run on steps, in a fixed order, instead of on the clock), then answers DONE once
  nothing is left to run: no executor task created since (a future's callbacks, an
  action's goal), and no work held by a thread (:meth:`Participant.hold`). The answer
  says whether the process sent anything since its previous answer (topics, services,
  actions: counted by wrapping rclpy's send methods, so any node composed into the
  process counts) and when its next timer is due. The simulator repeats a step until
  everyone has answered (a joiner's reader may be unknown to it yet); each is taken once.

DDS orders messages per writer only: a scan or a transform published before a step usually,
not always, arrives before it (most often not on a busy machine). So every publish is
counted per topic (:mod:`pppbot_common.ros.lockstep_counting`), answers carry the counts,
each step the totals of the topics participants count (:func:`count_deliveries`, :func:`require_match`), and a
participant handles a step only once its counted subscriptions have received that many
(:class:`~pppbot_common.lockstep.Deliveries`; after :data:`DELIVERY_TIMEOUT_S` it goes on
with a warning). For the counts to name the right messages, what a participant sends while
time runs is held until its next step (:class:`~pppbot_common.ros.lockstep_counting.Outbox`):
everything sent in one round is handled in the next. Replies are not held; the step at which
a request goes out waits for the prompt reply (:func:`hold_for`, :func:`hold_until`, flows of
:mod:`pppbot_common.ros.goals`); a result that comes whenever the server is done is seen at
the first tick after it came (:class:`pppbot_common.ros.goals.Arrival`).
"""
from __future__ import annotations

import functools
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any, ClassVar

from builtin_interfaces.msg import Time as TimeMsg
from rclpy.clock import ClockType, ROSClock
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.time import Time

from pppbot_common.lockstep import LockstepError, StepTimer, StepTimers
from pppbot_common.ros.lockstep_counting import (
    _ORIGINAL_PUBLISH,
    COUNTERS,
    OUTBOX,
    HeldFuture,
    Receiver,
    install_counting,
)
from pppbot_common.ros.lockstep_requests import REQUESTS
from pppbot_common.ros.wire import MessageTemplate, stamp_fields, stamp_values
from pppbot_common.throttle import Throttle
from pppbot_interfaces.msg import LockstepAck, LockstepStatus, LockstepStep

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
#: Wall seconds a step waits for the messages published before it (then goes on with a warning).
DELIVERY_TIMEOUT_S = 2.0
WARN_PERIOD_S = 5.0


def stamp_ns(stamp: TimeMsg) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def time_msg(ns: int) -> TimeMsg:
    sec, nanosec = divmod(int(ns), 1_000_000_000)
    return TimeMsg(sec=sec, nanosec=nanosec)


def count_deliveries(node: Node, subscription: Any) -> None:
    """In lockstep, count what ``subscription`` (on the data path) receives: the process handles a
    step only once it has every message the lockstep processes published on the topic before the
    step. Without lockstep it does nothing."""
    receiver = Receiver.current()
    participant = Participant.current()
    if receiver is None or (participant is not None and node.context is not participant.node.context):
        return
    receiver.count(subscription)


# ------------------------------------------------------------------------ participant
class Participant:
    """This process's lockstep participant (see the module's docstring).

    Made by the node runner (:func:`pppbot_common.ros.node_main.run_nodes`) before the
    process's nodes, so that their timers (:func:`create_timer`) are step timers.
    """

    _current: ClassVar[Participant | None] = None

    def __init__(self, name: str, node: Node) -> None:
        self.name = name
        self.node = node
        self.timers = StepTimers()
        self.joined = False
        self._executor: Any = None
        self._nodes: list[Node] = []
        self._lock = threading.Lock()
        self._holds = 0
        self._pending_seq: int | None = None
        self._early_step: LockstepStep | None = None
        self._last_seq = 0  # the last step taken since joining (the simulator repeats a step until all answer)
        receiver = Receiver.start(self._on_delivery)
        self.deliveries = receiver.deliveries
        REQUESTS.context, REQUESTS.receiver = node.context, receiver
        self._counted_topics: list[str] = []  # as last told to the simulator
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
        install_counting()
        self.ack_pub = node.create_publisher(LockstepAck, ACK_TOPIC, PROTOCOL_QOS)
        self._step_topics: tuple[str, ...] = ()
        node.create_subscription(LockstepStep, STEP_TOPIC, self._on_step, PROTOCOL_QOS)
        node.create_subscription(LockstepStatus, STATUS_TOPIC, self._on_status, STATUS_QOS)

    # ------------------------------------------------------------ process-wide
    @classmethod
    def current(cls) -> Participant | None:
        return cls._current

    @classmethod
    def from_parameters(cls, default_name: str) -> Participant | None:
        """The process's participant when its parameters say ``lockstep:=true`` (else None); made
        current. Its node is hidden (``_lockstep_<name>``) and belongs to the default context.

        Raises:
            LockstepError: ``lockstep_name`` is empty.
        """
        node = Node(f"_lockstep_{_node_safe(default_name)}", start_parameter_services=False, enable_rosout=False)
        enabled = bool(node.declare_parameter("lockstep", False).value)
        name = str(node.declare_parameter("lockstep_name", default_name).value)
        if not enabled:
            node.destroy_node()
            return None
        if not name:
            node.destroy_node()
            raise LockstepError("parameter 'lockstep_name' = '': a lockstep participant needs a name")
        cls._current = cls(name, node)
        return cls._current

    @classmethod
    def for_node(cls, name: str, node: Node) -> Participant:
        """A participant answering for ``node``'s context (a process that runs its own executor, such
        as the evaluation), made current."""
        cls._current = cls(name, node)
        return cls._current

    @classmethod
    def clear_current(cls) -> None:
        cls._current = None
        Receiver.clear_current()
        REQUESTS.reset()

    def start(self, executor: Any, nodes: Sequence[Node]) -> None:
        """Spinning starts with ``executor``; ``nodes`` get their clocks set to each step's time."""
        self._executor = executor
        self._nodes = list(nodes)
        self.maintain()

    # ---------------------------------------------------------------- joining
    def require(self, what: str) -> Callable[[], None]:
        """Do not join before ``what`` is there; call the returned function when it is."""
        self._requirements.add(what)
        return functools.partial(self._fulfil, what)

    def _fulfil(self, what: str) -> None:
        self._requirements.discard(what)

    def require_when(self, what: str, condition: Callable[[], bool]) -> None:
        """Do not join before ``condition()`` holds (checked as the process spins)."""
        self._conditions.append((what, condition))

    def _unmet(self) -> list[str]:
        return sorted(self._requirements | {what for what, ok in self._conditions if not ok()})

    def _graph_nodes(self) -> int:
        return len(self.node.get_node_names_and_namespaces())

    def maintain(self) -> None:
        """Called by the spin loop: (re)send JOIN until the simulator lists this participant; give up
        waiting for messages a step needs after :data:`DELIVERY_TIMEOUT_S`."""
        if self._waiting_step is not None:
            self._try_step()
        if self._waiting_step is None:  # a kept request may be this step's, waited for
            REQUESTS.overdue(self._executor.create_task)
        if self.joined or self.ack_pub.get_subscription_count() == 0:
            return
        now = time.monotonic()
        if now - self._last_join < JOIN_RESEND_S:
            return
        self._last_join = now
        unmet = self._unmet()
        if unmet:
            self._warn("requirements", f"lockstep: '{self.name}' joins once it has {', '.join(unmet)}")
            return
        self._counted_topics = self.deliveries.topics()
        self._send(LockstepAck(kind=LockstepAck.JOIN, participant=self.name, settled=True,
                               graph_nodes=self._graph_nodes(), counted_topics=self._counted_topics))

    def _on_delivery(self) -> None:
        if self._waiting_step is not None:
            self._try_step()

    def _on_status(self, msg: LockstepStatus) -> None:
        listed = self.name in msg.participants
        joining = listed and not self.joined
        if joining:
            self.node.get_logger().info(f"lockstep: joined as '{self.name}'")
            self._last_seq = 0  # a simulator started anew counts steps from 1 again
        self.joined = listed
        early, self._early_step = self._early_step, None
        if joining and early is not None:
            # The simulator lists a joiner just before its first step, on another topic: the step
            # may come first. Answered now (an answer to a step from before the listing is ignored).
            self._on_step(early)

    def leave(self) -> None:
        """Tell the simulator to stop waiting for this process (it is ending)."""
        if self.joined:
            self.joined = False
            OUTBOX.send_all()
            if self._executor is not None:
                REQUESTS.overdue(self._executor.create_task, everything=True)
            try:
                self._send(LockstepAck(kind=LockstepAck.LEAVE, participant=self.name))
                self.ack_pub.wait_for_all_acked(Duration(seconds=1.0))
            except Exception:  # noqa: BLE001 - the context may be going down already
                pass

    # ------------------------------------------------------------------ steps
    def _on_step(self, msg: LockstepStep) -> None:
        if not self.joined:
            self._early_step = msg  # the simulator may wait for us already (see _on_status)
            return
        if msg.seq <= self._last_seq:
            return  # a repeat, for a participant that missed it
        self._last_seq = msg.seq
        OUTBOX.send_sealed()  # what this process sent in the last round (see Outbox)
        self._step_topics = tuple(msg.topics)
        self.deliveries.expect(msg.topics, msg.published)
        if stamp_ns(msg.stamp) == 0:
            self.deliveries.rebase()  # time holds at its start: discovery may have lost messages
        else:
            REQUESTS.leave_step(time_runs=True)  # requests taken until it is handled wait for it
        self._waiting_step, self._waiting_since = msg, time.monotonic()
        self._try_step()

    def _try_step(self) -> None:
        """Handle the waiting step once every message published before it is here (or after
        :data:`DELIVERY_TIMEOUT_S`, with a warning naming the topics)."""
        msg = self._waiting_step
        if msg is None:
            return
        lacking = self.deliveries.lacking()
        if lacking:
            if time.monotonic() - self._waiting_since < DELIVERY_TIMEOUT_S:
                return
            self._warn("delivery", f"lockstep: step {msg.seq} (t = {stamp_ns(msg.stamp) * 1e-9:.3f} s) goes on "
                                   f"without messages published before it: " + ", ".join(
                                       f"{topic} ({expected - received} of {expected})"
                                       for topic, received, expected in lacking))
            self.deliveries.rebase()
        self._waiting_step = None
        self._handle_step(msg)

    def _handle_step(self, msg: LockstepStep) -> None:
        self.steps += 1
        t_ns = self._last_step_ns = stamp_ns(msg.stamp)
        self._set_clocks(t_ns)
        # The step's time for timers (re)started now, before the timers run (a goal's).
        self.timers.now_ns = max(self.timers.now_ns, t_ns)
        if t_ns > 0:
            OUTBOX.holding = True  # from now on sends go out at the next step (at time 0 they need no order)
        self._run_deferred()
        REQUESTS.enter_step(self._run_request)
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
        self._task_mark = COUNTERS.tasks

    def _idle_check(self) -> None:
        if COUNTERS.tasks != self._task_mark:
            self._post_idle_check()
            return
        if self._timers_due:
            self._fire_timers_due()
            return
        self._answer_if_free()

    def _run_request(self, execute: Callable[[], Any]) -> None:
        """Handle a request kept for this step (:mod:`~pppbot_common.ros.lockstep_requests`) before answering it."""
        self.hold()

        async def run() -> None:
            try:
                await execute()
            finally:
                self.release()
        self._executor.create_task(run)

    def hold(self) -> None:
        """A thread of this process has work the current step must wait for (call in the executor's
        thread, when the work is handed over)."""
        with self._lock:
            self._holds += 1

    def await_reply(self, future: Any) -> Callable[[], None]:
        """See :func:`hold_for`."""
        if isinstance(future, HeldFuture) and not future.sent:
            future.when_sent(self.hold)
        else:
            self.hold()
        return self._replied

    def _replied(self) -> None:
        # The server may have handled the request after answering this round: what it sent then
        # is held for its next answer. Another round at this time lets that answer come, so the
        # request's consequences are handled at this time whichever came first.
        COUNTERS.sent()
        self.release()

    def release(self) -> None:
        """That work is done (any thread); answers a step that waited for it."""
        with self._lock:
            self._holds -= 1
            if self._holds < 0:
                self._holds = 0
                raise LockstepError(f"lockstep participant '{self.name}': release() without hold()")
        self._answer_if_free()

    def _answer_if_free(self) -> None:
        with self._lock:
            if self._pending_seq is None or self._holds > 0:
                return
            timers_due = self._timers_due
            if not timers_due:
                seq, self._pending_seq = self._pending_seq, None
                REQUESTS.leave_step(OUTBOX.holding)
        if timers_due:  # released by a worker thread: the timers run in the executor's (a task is thread-safe)
            self._executor.create_task(self._fire_timers_due)
            return
        with OUTBOX.lock:  # the counts answered are those of the sends held so far
            OUTBOX.seal()
            sends = COUNTERS.sends
            published = [COUNTERS.published.get(topic, 0) for topic in self._step_topics]
        sent, self._sends_at_answer = sends > self._sends_at_answer, sends
        wakeup = self.timers.next_wakeup_ns()
        starting = self._last_step_ns == 0  # time holds at its start: the simulator asks whether all is set
        values: dict[str, Any] = {"seq": seq, "sent": sent, **stamp_values(wakeup or 0, "next_wakeup"),
                                  "settled": not starting or not self._unmet(),
                                  "graph_nodes": self._graph_nodes() if starting else 0}
        counted_topics = self.deliveries.topics()
        if counted_topics != self._counted_topics:  # a subscription made since: told once
            self._counted_topics = counted_topics
            self._send(LockstepAck(kind=LockstepAck.DONE, participant=self.name, published=published,
                                   counted_topics=counted_topics, **_message_values(values)))
            return
        if published:
            values["published"] = published
        _ORIGINAL_PUBLISH(self.ack_pub, self._done_wire(len(published)).serialize(values))

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
        _ORIGINAL_PUBLISH(self.ack_pub, msg)  # the protocol's own messages are not "sent" work

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


# ---------------------------------------------------------------------- node helpers
Timer = Any  # rclpy.timer.Timer or StepTimer: both have cancel(), reset(), is_canceled()


def create_timer(node: Node, period_s: float, callback: Callable[[], object], *, wakes: bool = True) -> Timer:
    """A periodic timer on sim time: on lockstep steps when the process takes part in lockstep,
    otherwise an rclpy timer on the node's clock.

    ``wakes=False``: in lockstep, the timer fires at the first step at or after its deadline
    but does not make one (for outputs nobody waits on, such as a transform republished
    ahead of its use).
    """
    participant = Participant.current()
    if participant is not None and node.context is participant.node.context:
        return participant.timers.create(period_s, callback, wakes)
    return node.create_timer(period_s, callback)


def destroy_timer(node: Node, timer: Timer) -> None:
    """Undo :func:`create_timer`."""
    if isinstance(timer, StepTimer):
        timer.destroy()
    else:
        node.destroy_timer(timer)


def require(node: Node, what: str) -> Callable[[], None]:
    """``node``'s process joins lockstep only once ``what`` is there (call the returned function
    then). Without lockstep the function does nothing."""
    participant = Participant.current()
    if participant is None or node.context is not participant.node.context:
        return _nothing
    return participant.require(what)


def require_match(node: Node, endpoint: Any, what: str = "") -> None:
    """In lockstep, ``node``'s process joins only once ``endpoint`` (a publisher or a subscription of a
    topic on the data path) is matched: a publisher with at least one subscriber, a subscription
    with at least one publisher and with every publisher the graph knows of. A message sent at the
    first step is then not lost to discovery still going on."""
    participant = Participant.current()
    if participant is None or node.context is not participant.node.context:
        return
    topic = endpoint.topic_name
    if hasattr(endpoint, "get_subscription_count"):
        participant.require_when(what or f"a subscriber of {topic}", lambda: endpoint.get_subscription_count() > 0)
    else:
        participant.require_when(what or f"the publishers of {topic}",
                                 lambda: endpoint.get_publisher_count() >= max(1, node.count_publishers(topic)))
        count_deliveries(node, endpoint)


def in_step(node: Node, work: Callable[[], None]) -> None:
    """Run ``work`` now, or, in lockstep, at the next step: for work the simulator's data set off
    between steps (a transform that lets a waiting scan through), so that what it sends goes out
    at a step, at the same sim time on every run."""
    participant = Participant.current()
    if participant is None or node.context is not participant.node.context or not participant.joined:
        work()
    else:
        participant.defer(work)


def at_step(node: Node, callback: Callable[[Any], None]) -> Callable[[Any], None]:
    """``callback`` for messages from the simulator that make the node send (a scan: AMCL's pose and
    transform): in lockstep each message is handled at the next step, so that what it causes goes
    out after every participant has that step, and is seen by all at the same round."""
    def handle(msg: Any) -> None:
        in_step(node, functools.partial(callback, msg))
    return handle


def in_lockstep() -> bool:
    """Whether this process takes part in lockstep (and has joined)."""
    participant = Participant.current()
    return participant is not None and participant.joined


def hold() -> Callable[[], None]:
    """Mark work a worker thread will do for the current step; call the returned function when
    it is done. Without lockstep both are no-ops."""
    participant = Participant.current()
    if participant is None:
        return _nothing
    participant.hold()
    return participant.release


def hold_for(future: Any) -> Callable[[], None]:
    """In lockstep, the step at which the request behind ``future`` goes out (requests are held
    until the next step: :class:`~pppbot_common.ros.lockstep_counting.Outbox`) waits for its
    reply (a goal accepted or refused, a cancel, a service's answer, a planner's path); call the
    returned function once the reply has been handled. Servers send replies at once, so the
    server handles the request, and the client its reply, within that round on every
    machine. Without lockstep both are no-ops."""
    participant = Participant.current()
    if participant is None:
        return _nothing
    return participant.await_reply(future)


def _nothing() -> None:
    pass
