"""Send a request again when its answer is lost: one policy for every service call and goal.

Fast DDS drops a service's answer to a client whose reply reader the server has not discovered
yet ("failed to send response (timeout): client will not receive response"), most often on a
busy machine with a node just started. A :class:`Request` is sent, its answer waited for up to
:attr:`Retry.attempt_s`, and sent again, at most :attr:`Retry.attempts` times in all and within
:attr:`Retry.deadline_s`; giving up raises :class:`Unanswered`, naming what was asked of whom.

A request that changes something is sent again only when it was truly lost: after each attempt
without an answer its ``check`` gives a :class:`Verdict`. For a lifecycle transition
(:func:`transition_verdict`) it is LOST only while the node still shows the state it was asked
from and began no transition; one under way (the node in ``configuring``, or too busy in its
callback to answer ``get_state``) is waited on, never asked twice; one that ended with its
answer lost is SETTLED, and the caller reads the node's state.

:class:`Request`, :func:`wait_for_answer` and :func:`transition_verdict` are the policy (no
rclpy: a request is anything with ``done()`` and ``result()``, time is a clock passed in);
:func:`call_service`, :func:`send_goal` and :class:`LifecycleCalls` adapt rclpy's clients.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from enum import Enum
from typing import Any, Generic, Protocol, TypeVar

from pppbot_common.errors import TimeoutExpired

T = TypeVar("T")
T_co = TypeVar("T_co", covariant=True)


class Pending(Protocol[T_co]):
    """A request sent, its answer to come (rclpy's ``Future``)."""

    def done(self) -> bool: ...
    def result(self) -> T_co | None: ...


#: ``wait(pending, timeout_s)``: block until ``pending`` is done or ``timeout_s`` passed.
Wait = Callable[[Any, float], object]


class Verdict(Enum):
    """What an attempt without an answer means."""

    LOST = "lost"  # no sign the server took it: send it again
    IN_PROGRESS = "in progress"  # the server is at it: wait on, never send it again
    SETTLED = "settled"  # it took effect and its answer was lost: stop waiting


@dataclass(frozen=True)
class Retry:
    """How long to wait for one answer (``attempt_s``), how many sends at most (``attempts``), and
    how long in all (``deadline_s``; None: ``attempts`` × ``attempt_s``)."""

    attempt_s: float
    attempts: int = 3
    deadline_s: float | None = None

    def __post_init__(self) -> None:
        if not self.attempt_s > 0:
            raise ValueError(f"Retry.attempt_s = {self.attempt_s!r}: must be > 0 s")
        if self.attempts < 1:
            raise ValueError(f"Retry.attempts = {self.attempts!r}: must be at least 1")
        if self.deadline_s is not None and not self.deadline_s > 0:
            raise ValueError(f"Retry.deadline_s = {self.deadline_s!r}: must be > 0 s (or None)")

    @property
    def total_s(self) -> float:
        return self.deadline_s if self.deadline_s is not None else self.attempt_s * self.attempts


class Unanswered(TimeoutExpired):
    """A request given up on; the message says what was asked of whom, how often and how long."""

    def __init__(self, what: str, sent: int, waited_s: float, why: str = "no answer") -> None:
        super().__init__(f"gave up on {what}: {why} ({sent} request{'s' if sent > 1 else ''} "
                         f"in {waited_s:.1f} s)")
        self.what, self.sent, self.waited_s = what, sent, waited_s


class AnswerLost(Unanswered):
    """The request took effect (its ``check`` said SETTLED) but its answer never came."""


class Request(Generic[T]):
    """One request and its resends, by :class:`Retry`: :meth:`poll` it (or :func:`wait_for_answer`).

    ``send()`` sends it once; ``what`` names it for :class:`Unanswered` (the service or action and
    the node); ``check()`` judges an attempt without an answer (none: every one is LOST);
    ``forget(pending)`` drops a request given up on (rclpy: ``Client.remove_pending_request``).
    """

    def __init__(self, send: Callable[[], Pending[T]], retry: Retry, what: str, *,
                 check: Callable[[], Verdict] | None = None,
                 forget: Callable[[Any], object] | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.retry, self.what = retry, what
        self._send, self._check, self._forget, self._clock = send, check, forget, clock
        self.sent = 0
        self._start = clock()
        self._deadline = self._start + retry.total_s
        self.pending = self._send_once(self._start)

    def _send_once(self, now: float) -> Pending[T]:
        self.sent += 1
        self._attempt_end = min(now + self.retry.attempt_s, self._deadline)
        self.pending = self._send()
        return self.pending

    def wait_s(self) -> float:
        """Seconds left of the current attempt."""
        return max(0.0, self._attempt_end - self._clock())

    def poll(self) -> bool:
        """Whether the answer is there (``pending.result()``); sends again when an attempt's time
        is up and its ``check`` says LOST.

        Raises:
            AnswerLost: the check said SETTLED.
            Unanswered: no answer within the attempts and the deadline.
        """
        if self.pending.done():
            return True
        if self._clock() < self._attempt_end:
            return False
        verdict = Verdict.LOST if self._check is None else self._check()
        if self.pending.done():  # the answer came while the check asked
            return True
        now = self._clock()
        if verdict is Verdict.SETTLED:
            self._give_up(now, AnswerLost, "it took effect but its answer was lost")
        if now >= self._deadline or (verdict is Verdict.LOST and self.sent >= self.retry.attempts):
            self._give_up(now, Unanswered, "no answer" if verdict is Verdict.LOST else "no answer, still under way")
        if verdict is Verdict.IN_PROGRESS:
            self._attempt_end = min(now + self.retry.attempt_s, self._deadline)
        else:
            if self._forget is not None:
                self._forget(self.pending)
            self._send_once(now)
        return False

    def _give_up(self, now: float, error: type[Unanswered], why: str) -> None:
        if self._forget is not None:
            self._forget(self.pending)
        raise error(self.what, self.sent, now - self._start, why)


def wait_for_answer(request: Request[T], wait: Wait) -> T | None:
    """Block until ``request`` is answered; its answer.

    Raises:
        AnswerLost, Unanswered: as :meth:`Request.poll`.
    """
    while not request.poll():
        wait(request.pending, request.wait_s())
    return request.pending.result()


#: lifecycle_msgs/msg/State: primary states have ids below this, transition states from it on.
FIRST_TRANSITION_STATE = 10


def transition_verdict(before_id: int, now_id: int | None, began: bool) -> Verdict:
    """An unanswered change_state asked of a node in state ``before_id``: LOST only when the node
    says it is still there (``now_id``; None: it did not answer get_state) and no transition of it
    began (``began``: a transition event heard since the request went)."""
    if now_id is None or now_id >= FIRST_TRANSITION_STATE:
        return Verdict.IN_PROGRESS  # in a transition's callback, or saying so
    if now_id != before_id or began:
        return Verdict.SETTLED  # moved on, or moved and came back (a transition that failed)
    return Verdict.LOST


# ------------------------------------------------------------------- rclpy's side
def executor_wait(executor: Any) -> Wait:
    """A :data:`Wait` that spins ``executor`` (owned by the caller's thread) meanwhile."""
    return lambda pending, timeout_s: executor.spin_until_future_complete(pending, timeout_sec=timeout_s)


def node_wait(node: Any) -> Wait:
    """A :data:`Wait` that spins ``node`` meanwhile, or, with None (a node spun by another thread),
    blocks until the future is done."""
    import rclpy

    from pppbot_common.ros.wait import wait_for_future

    if node is None:
        return wait_for_future
    return lambda pending, timeout_s: rclpy.spin_until_future_complete(node, pending, timeout_sec=timeout_s)


def asker(node: Any) -> str:
    return "" if node is None else f", asked by {node.get_fully_qualified_name()}"


def call_service(client: Any, request: Any, retry: Retry, wait: Wait, *, node: Any = None,
                 check: Callable[[], Verdict] | None = None) -> Any:
    """``request``'s answer from service ``client``, sent again as ``retry`` says (``check``: see
    :class:`Request`); ``node`` (the client's) only names the asker.

    Raises:
        AnswerLost, Unanswered: naming the service.
    """
    sent: Request[Any] = Request(lambda: client.call_async(request), retry,
                                 f"service {client.srv_name}{asker(node)}", check=check,
                                 forget=client.remove_pending_request)
    return wait_for_answer(sent, wait)


def send_goal(client: Any, goal: Any, retry: Retry, wait: Wait, *, node: Any = None,
              feedback_callback: Callable[[Any], None] | None = None) -> Any:
    """Send an action goal; its goal handle once the server answered (accepted or not). A goal
    sent again after its answer was lost is a new goal to a server that took the first (it
    preempts it), so every lost answer is taken for a lost goal; a goal given up on whose acceptance
    comes after all is canceled then, so the server runs only the goal the caller holds.

    Raises:
        Unanswered: naming the action.
    """
    sent: Request[Any] = Request(lambda: client.send_goal_async(goal, feedback_callback=feedback_callback), retry,
                                 f"a goal on action {client._action_name}{asker(node)}", forget=cancel_when_accepted)
    return wait_for_answer(sent, wait)


def cancel_when_accepted(pending: Any) -> None:
    """A goal given up on (``pending``: its ``send_goal_async`` future): if the server accepts it
    later, cancel it then."""
    def cancel(future: Any) -> None:
        handle = future.result()
        if handle is not None and handle.accepted:
            handle.cancel_goal_async()

    pending.add_done_callback(cancel)


class LifecycleCalls:
    """Lifecycle node ``target``'s ``get_state`` and ``change_state``, asked through ``node`` and
    waited for with ``wait``. A get_state is sent again whenever its answer is late; a change_state
    only when lost: :func:`transition_verdict` on the node's state and the ``transition_event`` messages
    it published since the request went."""

    def __init__(self, node: Any, target: str, retry: Retry, wait: Wait) -> None:
        from lifecycle_msgs.msg import TransitionEvent
        from lifecycle_msgs.srv import ChangeState, GetState

        self.node, self.target, self.retry, self.wait = node, target.rstrip("/"), retry, wait
        self.get_client = node.create_client(GetState, f"{self.target}/get_state")
        self.change_client = node.create_client(ChangeState, f"{self.target}/change_state")
        #: the start state (id) of each transition event heard, in order
        self.began_from: list[int] = []
        self._events = node.create_subscription(TransitionEvent, f"{self.target}/transition_event",
                                                lambda msg: self.began_from.append(msg.start_state.id), 10)

    def state(self, retry: Retry | None = None) -> tuple[int, str]:
        """The node's state: its id and label (``lifecycle_msgs/msg/State``).

        Raises:
            Unanswered: naming the get_state service.
        """
        from lifecycle_msgs.srv import GetState

        answer = call_service(self.get_client, GetState.Request(), retry or self.retry, self.wait, node=self.node)
        return int(answer.current_state.id), str(answer.current_state.label)

    def change_state(self, transition: int, before_id: int, label: str = "") -> bool | None:
        """Whether ``transition`` (a ``lifecycle_msgs/msg/Transition`` id, or its ``label``), asked
        of the node in state ``before_id``, succeeded; None: it took effect but its answer was lost (the state says
        how it ended).

        Raises:
            Unanswered: naming the change_state service and the transition.
        """
        from lifecycle_msgs.msg import Transition
        from lifecycle_msgs.srv import ChangeState

        heard = len(self.began_from)

        def check() -> Verdict:
            try:
                now_id: int | None = self.state(Retry(self.retry.attempt_s, attempts=1))[0]
            except Unanswered:
                now_id = None  # busy in a transition's callback: get_state waits for it
            return transition_verdict(before_id, now_id, before_id in self.began_from[heard:])

        request = ChangeState.Request(transition=Transition(id=transition, label=label))
        try:
            answer = call_service(self.change_client, request, self.retry, self.wait, node=self.node, check=check)
        except AnswerLost:
            return None
        return bool(answer.success)

    def destroy(self) -> None:
        self.node.destroy_client(self.get_client)
        self.node.destroy_client(self.change_client)
        self.node.destroy_subscription(self._events)
