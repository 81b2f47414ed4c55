"""A node's step port: what a pppbot node sends and times through, in lockstep or not.

The node runner (:func:`pppbot_lockstep.ros.runner.run_nodes`) hands every node of a process one
port: a :class:`StepPort` when the process runs freely (every call does what rclpy would do), the
process's :class:`~pppbot_lockstep.ros.participant.Participant` when it takes part in lockstep,
or the simulator's :class:`~pppbot_lockstep.ros.coordinator.CoordinatorPort`. A node uses it
through :class:`~pppbot_lockstep.ros.node.StepNode`, whose publishers, subscriptions, clients,
services, action servers and timers call it; nothing in rclpy is replaced, and a plain rclpy node
in the same process does exactly what it would do anywhere.

What a port decides:

* **sends** (:meth:`StepPort.send`, :meth:`StepPort.request`): counted and, in lockstep, held
  until the next step;
* **receptions** on the data path (:meth:`StepPort.counted`): counted, so a step is handled only
  once every message published before it is here;
* **requests** to the node's servers (:meth:`StepPort.serve`): in lockstep, kept for the next step;
* **timers** (:meth:`StepPort.create_timer`): in lockstep, fired by steps in a fixed order;
* **work held** by a thread or a reply (:meth:`StepPort.hold`, :meth:`StepPort.hold_for`), work
  deferred to the next step (:meth:`StepPort.in_step`), and what the process needs before it
  joins (:meth:`StepPort.require`, :meth:`StepPort.require_match`).
"""
from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

from rclpy.node import Node
from rclpy.publisher import Publisher

from pppbot_lockstep.protocol import StepTimer

Timer = Any  # rclpy.timer.Timer or StepTimer: both have cancel(), reset(), is_canceled()
Execute = Callable[[], Any]


def _nothing() -> None:
    pass


class StepPort:
    """The port of a process that runs freely: sends go out at once, timers run on the node's
    clock, requests are handled as they come, nothing is waited for. Subclasses take part in
    lockstep."""

    #: whether the process takes part in lockstep (its nodes' sends held, their timers stepped, the
    #: requests to their servers kept for steps)
    lockstep = False
    #: whether sends and data-path receptions are counted (in lockstep, and in the simulator's process)
    counts = False

    @property
    def joined(self) -> bool:
        """Whether the process has joined lockstep (time waits for it)."""
        return False

    # ---------------------------------------------------------------- sends
    def publish(self, publisher: Publisher, msg: Any, topic: str, *, asks_round: bool = True) -> None:
        """Publish ``msg`` (a message or its bytes) on ``publisher`` (whose topic is ``topic``);
        ``asks_round=False``: nobody in lockstep reacts to it at this time (a wheel's transform)."""
        Publisher.publish(publisher, msg)

    def send(self, send: Callable[[], None], topic: str | None = None, *, asks_round: bool = True) -> None:
        """Send now (``send`` puts something on the wire, a goal's feedback say; ``topic`` counts it
        there)."""
        send()

    def request(self, send: Callable[..., Any], key: str, *args: Any) -> Any:
        """Send a request to the server of ``key``: ``send(*args)`` sends it and returns its future;
        the request's future (in lockstep, one held until the next step: ``args`` are copied)."""
        return send(*args)

    def replied(self) -> None:
        """A server of this process sent a reply or a goal's new state (a round's worth of work)."""

    def task_created(self) -> None:
        """The process's executor made a task (work to wait for before answering a step)."""

    # ----------------------------------------------------------- receptions
    def counted(self, node: Node, topic: str, callback: Callable[[Any], None],
                quiet: bool | Callable[[], bool] = False) \
            -> Callable[[Any], None]:
        """``callback`` for a data-path subscription of ``node`` on ``topic`` (fully qualified);
        ``quiet``: handling a message sends nothing (see :meth:`StepNode.create_subscription`)."""
        return callback

    def serve(self, node: Node, key: str, callback: Callable[..., Any], make_kept: Callable[[Any], Any]) \
            -> Callable[..., Any]:
        """``callback`` for a server of ``node`` whose requests count on ``key``; ``make_kept(request)``
        wraps a request kept for the next step."""
        return callback

    def count_requests(self, node: Node, key: str) -> Any:
        """Count the requests an action server of ``node`` takes on ``key``; what :meth:`take_requests`
        is given."""
        return None

    def take_requests(self, counted: Any, key: str, execute: Execute, requests: int) -> bool:
        """An action server took ``requests`` requests counted on ``key`` (``counted``: what
        :meth:`count_requests` gave); True when they are kept for the next step (``execute`` then
        runs them), False to run them now."""
        return False

    # ---------------------------------------------------------------- timers
    def create_timer(self, node: Node, period_s: float, callback: Callable[[], object], wakes: bool = True) -> Timer:
        """A periodic timer on sim time (``wakes=False``, in lockstep: fires at the first step at or
        after its deadline without making one)."""
        return node.create_timer(period_s, callback)

    def destroy_timer(self, node: Node, timer: Timer) -> None:
        if isinstance(timer, StepTimer):
            timer.destroy()
        else:
            node.destroy_timer(timer)

    # ------------------------------------------------------------------ work
    def in_step(self, work: Callable[[], None]) -> None:
        """Run ``work`` now, or, in lockstep, at the next step (work the simulator's data set off
        between steps, so that what it sends goes out at a step)."""
        work()

    def at_step(self, callback: Callable[[Any], None]) -> Callable[[Any], None]:
        """``callback`` for messages that make the node send: in lockstep each is handled at the
        next step."""
        def handle(msg: Any) -> None:
            self.in_step(functools.partial(callback, msg))
        return handle

    def hold(self) -> Callable[[], None]:
        """Mark work a worker thread will do for the current step; call the returned function when
        it is done."""
        return _nothing

    def hold_for(self, future: Any) -> Callable[[], None]:
        """The step at which the request behind ``future`` goes out waits for its reply; call the
        returned function once the reply has been handled."""
        return _nothing

    # --------------------------------------------------------------- joining
    def require(self, what: str) -> Callable[[], None]:
        """The process joins lockstep only once ``what`` is there (call the returned function then)."""
        return _nothing

    def require_when(self, what: str, condition: Callable[[], bool]) -> None:
        """The process joins lockstep only once ``condition()`` holds."""

    def require_match(self, node: Node, endpoint: Any, what: str = "") -> None:
        """The process joins lockstep only once ``endpoint`` (a publisher or a subscription on the
        data path) is matched: a message sent at the first step is then not lost to discovery."""


#: The port of a process that runs freely (it keeps no state: one serves every such node).
FREE_RUNNING = StepPort()
