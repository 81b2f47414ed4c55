"""Requests to a lockstep participant's servers (services, actions) are handled at steps.

A request is work like a message: a planner's answer depends on the costmap and the robot's
pose it sees when it plans. Handled as it arrives, it would see whatever part of the step's
readings had arrived by then, which depends on the machine's load. So, once time runs, a
request taken while the process is between steps (waiting for a step's messages, or done with
one and waiting for the next) is kept and handled when the next step is handled, after the
work its readings set off and before the process answers (:meth:`Requests.enter_step`).

For that to be the step the request was sent at, requests are counted like messages: a client
counts each request it sends on its server's key (:func:`request_key`; held requests are
counted when held, see :class:`~pppbot_lockstep.ros.counting.Outbox`), a participant's
servers count the requests they take, and a step is handled once its servers have taken
every request counted before it.

A request that no step comes for (the simulation paused, or a client outside lockstep while
time holds) is handled after :data:`OVERDUE_S` wall seconds.
"""
from __future__ import annotations

import threading
import time
from collections.abc import Awaitable, Callable
from typing import Any

#: Wall seconds after which a request kept for a step that does not come is handled anyway.
OVERDUE_S = 2.0

Execute = Callable[[], Awaitable[Any]]


def request_key(name: str) -> str:
    """The counted key of requests to the service or action ``name`` (fully qualified)."""
    return f"{name}#requests"


def action_key(node: Any, action_name: str) -> str:
    """:func:`request_key` of an action, as its client and its server both name it."""
    return request_key(node.resolve_topic_name(action_name, only_expand=True))


#: Services every node has: their requests are neither counted nor kept (counting them would put
#: a dozen keys per node on every step; nodes in lockstep do not call them).
UNCOUNTED = tuple(request_key(f"/{name}") for name in (
    "describe_parameters", "get_parameter_types", "get_parameters", "list_parameters", "set_parameters",
    "set_parameters_atomically", "get_type_description"))


def counted_service(key: str) -> bool:
    """Whether requests to the service of ``key`` are counted (and kept for steps)."""
    return not key.endswith(UNCOUNTED)


class Requests:
    """A participant's requests kept for its next step, and whether it is inside one."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        #: Time runs and the participant is not handling a step: requests are kept.
        self.between_steps = False
        self._kept: list[tuple[str, float, Execute]] = []

    def keep(self, key: str, execute: Execute) -> bool:
        """Keep ``execute`` for the next step when between steps; False to run it now."""
        with self.lock:
            if not self.between_steps:
                return False
            self._kept.append((key, time.monotonic(), execute))
            return True

    def enter_step(self, run: Callable[[Execute], None]) -> None:
        """A step is being handled: ``run`` each kept request (in the order of their keys, then of
        their arrival: the same on every machine) and handle new ones at once."""
        with self.lock:
            self.between_steps = False
            kept, self._kept = sorted(self._kept, key=lambda item: item[0]), []
        for _, _, execute in kept:
            run(execute)

    def leave_step(self, time_runs: bool) -> None:
        """The step is answered, or a step came that is not handled yet: from now on requests wait
        for the next step handled (while time runs)."""
        with self.lock:
            self.between_steps = time_runs

    def overdue(self, run: Callable[[Execute], None], *, everything: bool = False) -> None:
        """``run`` the requests kept longer than :data:`OVERDUE_S` (all with ``everything``, and from
        then on none is kept: the participant leaves)."""
        now = time.monotonic()
        with self.lock:
            due = [item for item in self._kept if everything or now - item[1] >= OVERDUE_S]
            self._kept = [item for item in self._kept if item not in due]
            if everything:
                self.between_steps = False
        for _, _, execute in due:
            run(execute)


class KeptRequest:
    """A service request kept for the next step: what the service's callback returns meanwhile (the
    executor then hands it the request's header instead of sending a response, see
    :class:`pppbot_lockstep.ros.node.StepService`)."""

    def __init__(self, service: Any, callback: Callable[[Any, Any], Any], request: Any) -> None:
        self.service = service
        self.callback = callback
        self.request = request
        self.header: Any = None

    async def execute(self) -> None:
        response = self.callback(self.request, self.service.srv_type.Response())
        self.service.send_response(response, self.header)
