"""Action servers whose goals never block a thread, and sequential logic that waits without blocking.

pppbot's nodes run on one thread (the EventsExecutor): a callback must return quickly, and
an awaiting coroutine would keep that executor busy (it re-runs a pending task at once).
Two helpers keep long-running goals readable anyway:

* :class:`GoalServer`: an rclpy ActionServer whose goals the node advances on its timers.
  An accepted goal is EXECUTING at once; the node ends it with :meth:`GoalServer.finish`
  (succeeded, aborted or canceled, with a result). A cancel request is accepted and shows
  as ``is_cancel_requested``; a new goal may preempt the running one.
* :class:`Flow`: runs a generator that yields what it waits for (a future, or
  :class:`Sleep` for sim time) and is resumed when that is done, from the future's
  callback or the node's tick. It reads like a thread's loop, but holds no thread: in
  lockstep every step of it happens at a fixed sim time.
"""
from __future__ import annotations

import enum
import functools
from collections.abc import Callable, Generator
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

from action_msgs.msg import GoalStatus
from rclpy.action import CancelResponse, GoalResponse
from rclpy.action.client import ClientGoalHandle
from rclpy.action.server import ServerGoalHandle
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.task import Future

from pppbot_lockstep.ros.node import StepActionServer, port_of
from pppbot_lockstep.ros.port import FREE_RUNNING, StepPort

T = TypeVar("T")


class GoalEnd(enum.Enum):
    SUCCEEDED = "succeeded"
    ABORTED = "aborted"
    CANCELED = "canceled"


def send_feedback(port: StepPort, handle: ServerGoalHandle, feedback: Any) -> None:
    """A goal's feedback, through ``port``: in lockstep it goes out at the next step and asks for
    no round of its own. Feedback tells how a goal goes; its clients (Nav2's, a navigator's
    behaviour tree, an evaluation) log it or keep it for their timers and results, as Nav2's do,
    and never answer it within the step (before, each asked a round: navigation's controller
    feedback at 20 Hz made half of its rounds)."""
    port.send(functools.partial(handle.publish_feedback, feedback), asks_round=False)


class GoalServer:
    """An action server for goals advanced by the node (see the module docstring).

    ``on_goal(handle)`` is called for each accepted goal (in the executor's thread).
    ``accept(request)`` may refuse a goal (False).
    """

    def __init__(self, node: Node, action_type: Any, name: str, on_goal: Callable[[ServerGoalHandle], None],
                 accept: Callable[[Any], bool] | None = None, **kwargs: Any) -> None:
        self.action_type = action_type
        self._on_goal = on_goal
        self._accept = accept
        self.port = port_of(node)
        self.server = StepActionServer(node, action_type, name, execute_callback=self._never,
                                       goal_callback=self._goal_response,
                                       cancel_callback=lambda _: CancelResponse.ACCEPT,
                                       handle_accepted_callback=self._accepted, **kwargs)

    def _goal_response(self, request: Any) -> GoalResponse:
        if self._accept is not None and not self._accept(request):
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT

    def _accepted(self, handle: ServerGoalHandle) -> None:
        if not handle.is_cancel_requested:
            # EXECUTING now: the goal runs on the node's timers, not in an execute callback
            # (rclpy 7.1's own state transition; :meth:`finish` schedules the result).
            handle._update_state(_rclpy.GoalEvent.EXECUTE)
        self._on_goal(handle)

    @staticmethod
    def _never(handle: ServerGoalHandle) -> Any:
        raise RuntimeError("GoalServer goals end through finish()")

    def publish_feedback(self, handle: ServerGoalHandle, feedback: Any) -> None:
        """The goal's feedback (:func:`send_feedback`)."""
        send_feedback(self.port, handle, feedback)

    def finish(self, handle: ServerGoalHandle, end: GoalEnd, result: Any) -> None:
        """End the goal with ``end`` and send ``result``: the client's result request is answered."""
        def done(goal: ServerGoalHandle) -> Any:
            if goal.is_active:
                if end is GoalEnd.SUCCEEDED and not goal.is_cancel_requested:
                    goal.succeed()
                elif end is GoalEnd.CANCELED and goal.is_cancel_requested:
                    goal.canceled()
                else:
                    goal.abort()
            return result

        self.port.replied()  # the goal's new state and result go out: a round's work
        self.server.notify_execute(handle, done)

    def destroy(self) -> None:
        self.server.destroy()


@dataclass(frozen=True)
class Sleep:
    """Yielded by a :class:`Flow`: resume once the node's clock reads ``until_s`` (sim s), or, with
    ``wake``, when that future is done if that comes first."""

    until_s: float
    wake: Future | None = None


class Stopped(Exception):
    """Thrown into a :class:`Flow` whose ``check`` fails (its goal was canceled or preempted)."""


def check_running(handle: ServerGoalHandle, current: ServerGoalHandle | None, preempted_by: str = "a new goal") -> None:
    """The one cancel and preemption check: raises :class:`Stopped` when goal ``handle`` must
    stop, because its client asked to cancel it or because another goal (``current``, the one
    the server runs now) took its place.

    Raises:
        Stopped: "canceled" or "preempted by <preempted_by>".
    """
    if handle.is_cancel_requested:
        raise Stopped("canceled")
    if current is not handle:
        raise Stopped(f"preempted by {preempted_by}")


def stopped_end(handle: ServerGoalHandle) -> GoalEnd:
    """How a goal that did not succeed ends: canceled when its client asked, else aborted
    (preempted or failed), as Nav2's servers report it."""
    return GoalEnd.CANCELED if handle.is_cancel_requested else GoalEnd.ABORTED


Step = Generator[Any, Any, T]


class Flow(Generic[T]):
    """Runs ``steps``: each yielded future resumes it with the future's result (or raises its
    exception in it); each yielded :class:`Sleep` resumes it on the first :meth:`tick` at or after
    its time. ``check()`` runs before every resume and may raise (e.g. :class:`Stopped`) into
    the flow. ``on_end(value, error)`` gets the return value or the exception that ended it.

    In lockstep a flow is tied to steps, so that it runs the same on every machine: the step
    waits for a yielded future (a server's prompt answer: a goal accepted, a plan), so the
    answer comes within the round that asked; and a :class:`Sleep`'s ``wake`` (a result that
    comes whenever the server is done) resumes the flow at its next :meth:`tick`, not when the
    result happens to arrive.
    """

    def __init__(self, steps: Step[T], clock_s: Callable[[], float],
                 on_end: Callable[[T | None, BaseException | None], None],
                 check: Callable[[], None] | None = None, port: StepPort = FREE_RUNNING) -> None:
        self._steps = steps
        self._port = port
        self._clock_s = clock_s
        self._on_end = on_end
        self._check = check
        self._sleep_until: float | None = None
        self._waiting: Future | None = None
        self._woken_s: float | None = None  # in lockstep, when the Sleep's wake came (sim s)
        self.ended = False

    def start(self) -> None:
        self._resume(None, None)

    def tick(self) -> None:
        """Resume a sleeping flow whose time has come; run the check on a waiting one."""
        if self.ended:
            return
        now = self._clock_s()
        woken = self._woken_s is not None and now > self._woken_s
        if self._sleep_until is not None and (woken or now >= self._sleep_until):
            self._woken_s = None
            self._sleep_until = None
            self._waiting = None
            self._resume(None, None)
        elif self._check is not None:
            try:
                self._check()
            except Exception as exc:  # noqa: BLE001 - whatever check raises ends the wait
                if self._sleep_until is None and self._waiting is not None:
                    cancel_once_accepted(self._waiting)
                self._sleep_until = None
                self._waiting = None
                self._resume(None, exc)

    def _on_wake(self, future: Future) -> None:
        if self.ended or future is not self._waiting or self._sleep_until is None:
            return
        if self._port.joined:
            self._woken_s = self._clock_s()  # resumed by the first tick after this time
            return
        self._waiting = None
        self._sleep_until = None
        self._resume(None, None)

    def _on_future_released(self, release: Callable[[], None], future: Future) -> None:
        try:
            self._on_future(future)
        finally:
            release()  # after the flow went on (it may be waiting for its next answer already)

    def _on_future(self, future: Future) -> None:
        if self.ended or future is not self._waiting:
            return
        self._waiting = None
        exception = future.exception()
        self._resume(None if exception is not None else future.result(), exception)

    def _resume(self, value: Any, error: BaseException | None) -> None:
        if error is None and self._check is not None:
            try:
                self._check()
            except Exception as exc:  # noqa: BLE001 - see tick
                error = exc
                cancel_if_accepted(value)  # a goal's answer that came after its flow's goal stopped
        try:
            item = self._steps.throw(error) if error is not None else self._steps.send(value)
        except StopIteration as stop:
            self._end(stop.value, None)
            return
        except Exception as exc:  # noqa: BLE001 - the flow's own failure is its end
            self._end(None, exc)
            return
        if isinstance(item, Sleep):
            self._sleep_until = item.until_s
            if item.wake is not None:
                self._waiting = item.wake
                item.wake.add_done_callback(self._on_wake)
        elif isinstance(item, Future):
            self._waiting = item
            release = self._port.hold_for(item)
            item.add_done_callback(functools.partial(self._on_future_released, release))
        else:
            self._end(None, TypeError(f"a flow yields futures or Sleep, not {type(item).__name__}"))

    def _end(self, value: T | None, error: BaseException | None) -> None:
        self.ended = True
        self._on_end(value, error)


def cancel_once_accepted(sent: Future) -> None:
    """A goal's send (``send_goal_async``'s future) its flow stopped waiting for: the goal, if
    the server accepts it, is canceled then. As a Nav2 BT action node halted while its goal is
    pending cancels it, so a goal canceled or preempted between a send and its answer leaves
    nothing running (a FollowPath driving the robot on, a navigation nobody follows)."""
    sent.add_done_callback(
        lambda future: cancel_if_accepted(None if future.cancelled() or future.exception() is not None
                                          else future.result()))


def cancel_if_accepted(answer: Any) -> None:
    """Cancel ``answer`` if it is a goal the server accepted (a send's answer no flow goes on with)."""
    if isinstance(answer, ClientGoalHandle) and answer.accepted:
        answer.cancel_goal_async()


#: the statuses of a goal that ended
ENDED_STATUSES = frozenset({GoalStatus.STATUS_SUCCEEDED, GoalStatus.STATUS_CANCELED, GoalStatus.STATUS_ABORTED})


class Cancels:
    """Goals a node canceled, asked again until they end. A cancel request or its answer can be
    lost (Fast DDS drops samples to an endpoint not matched yet: a client just started on a busy
    machine), and a goal whose cancel was lost runs on with nobody following it. ``timer`` (the
    node's tick) is restarted by :meth:`cancel` when stopped; the node calls :meth:`tick` from it
    and keeps it on while it returns True: a goal not ended
    ``again_s`` of node time after a cancel is canceled again, at most ``attempts`` times in all
    (asking again is harmless: a server cancels a goal once)."""

    def __init__(self, clock_s: Callable[[], float], timer: Any = None, again_s: float = 1.0,
                 attempts: int = 5) -> None:
        self._clock_s, self._timer, self.again_s, self.attempts = clock_s, timer, again_s, attempts
        self._goals: list[tuple[ClientGoalHandle, Any, float, int]] = []  # handle, result, last ask (s), asks

    def cancel(self, handle: ClientGoalHandle, result: Any = None) -> None:
        """Cancel ``handle`` (``result``: its ``get_result_async`` future, if asked for) until it ends."""
        handle.cancel_goal_async()
        self._goals.append((handle, result, self._clock_s(), 1))
        if self._timer is not None and self._timer.is_canceled():
            self._timer.reset()  # it ticks until the goal ended

    def tick(self) -> bool:
        """Ask again where due; whether any canceled goal has yet to end."""
        now = self._clock_s()
        pending = []
        for handle, result, asked_s, asks in self._goals:
            if (result is not None and result.done()) or handle.status in ENDED_STATUSES:
                continue
            if now - asked_s < self.again_s:
                pending.append((handle, result, asked_s, asks))
            elif asks < self.attempts:  # else given up: the server is gone or ignores cancels
                handle.cancel_goal_async()
                pending.append((handle, result, now, asks + 1))
        self._goals = pending
        return bool(pending)


def hold_until(port: StepPort, future: Any) -> Any:
    """``port``'s :meth:`~StepPort.hold_for` ``future`` (a server's prompt answer), released when it
    is done. Returns ``future``."""
    release = port.hold_for(future)
    future.add_done_callback(lambda _: release())
    return future


class Arrival:
    """A future that a server completes whenever it is done (an action's result), as periodic
    ticks should see it: in lockstep, done from the first tick after the sim time it arrived at.
    A result sent at a step thus reaches the client's logic at the same tick on every machine,
    whether it arrived before or after the client's own timer of that step. ``clock_s`` reads
    the node's sim time."""

    def __init__(self, future: Any, clock_s: Callable[[], float | None], port: StepPort = FREE_RUNNING) -> None:
        self.future = future
        self._clock_s = clock_s
        self._lockstep = port.joined
        self.arrived_s: float | None = None
        future.add_done_callback(self._arrived)

    def _arrived(self, future: Any) -> None:
        self.arrived_s = self._clock_s() or 0.0

    def done(self) -> bool:
        if not self._lockstep:
            return bool(self.future.done())
        now = self._clock_s()
        return self.arrived_s is not None and now is not None and now > self.arrived_s

    def result(self) -> Any:
        return self.future.result()
