"""Requests to a lockstep participant's servers (services, actions) are handled at steps.

A request is work like a message: a planner's answer depends on the costmap and the robot's
pose it sees when it plans. Handled as it arrives, it would see whatever part of the step's
readings had arrived by then, which depends on the machine's load. So, once time runs, a
request taken while the process is between steps (waiting for a step's messages, or done with
one and waiting for the next) is kept and handled when the next step is handled, after the
work its readings set off and before the process answers (:meth:`Requests.enter_step`).

For that to be the step the request was sent at, requests are counted like messages: a client
counts each request it sends on its server's key (:func:`request_key`; held requests are
counted when held, see :class:`~pppbot_common.ros.lockstep_counting.Outbox`), a participant's
servers count the requests they take, and a step is handled once its servers have taken
every request counted before it.

A request that no step comes for (the simulation paused, or a client outside lockstep while
time holds) is handled after :data:`OVERDUE_S` wall seconds.
"""
from __future__ import annotations

import functools
import threading
import time
from collections.abc import Awaitable, Callable
from typing import Any

import rclpy.action.client
import rclpy.action.server
import rclpy.node
import rclpy.service

from pppbot_common.lockstep import Counted

#: Wall seconds after which a request kept for a step that does not come is handled anyway.
OVERDUE_S = 2.0

Execute = Callable[[], Awaitable[Any]]


def request_key(name: str) -> str:
    """The counted key of requests to the service or action ``name`` (fully qualified)."""
    return f"{name}#requests"


def action_key(node: Any, action_name: str) -> str:
    """:func:`request_key` of an action, as its client and its server both name it."""
    return request_key(node.resolve_topic_name(action_name, only_expand=True))


def client_key(client: Any) -> str:
    """:func:`request_key` of a service client or an action client (cached on it)."""
    try:
        return str(client._pppbot_request_key)
    except AttributeError:
        if isinstance(client, rclpy.action.client.ActionClient):
            key = action_key(client._node, client._action_name)
        else:
            key = request_key(client.service_name)
        client._pppbot_request_key = key
        return key


#: Services every node has: their requests are kept for a step like any other but not counted
#: (counting them would put a dozen keys per node on every step; nodes in lockstep do not call them).
UNCOUNTED = tuple(request_key(f"/{name}") for name in (
    "describe_parameters", "get_parameter_types", "get_parameters", "list_parameters", "set_parameters",
    "set_parameters_atomically", "get_type_description"))


class Requests:
    """This process's requests kept for the next step, and whether it is inside one."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        #: The participant's context (None: no participant in this process, nothing is kept).
        self.context: Any = None
        #: Time runs and the participant is not handling a step: requests are kept.
        self.between_steps = False
        self.receiver: Any = None
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

    def reset(self) -> None:
        """No participant any more (its process's lockstep ends): nothing is kept or counted."""
        self.overdue(lambda execute: None, everything=True)
        self.context = self.receiver = None

    def overdue(self, run: Callable[[Execute], None], *, everything: bool = False) -> None:
        """``run`` the requests kept longer than :data:`OVERDUE_S` (all with ``everything``)."""
        now = time.monotonic()
        with self.lock:
            due = [item for item in self._kept if everything or now - item[1] >= OVERDUE_S]
            self._kept = [item for item in self._kept if item not in due]
            if everything:
                self.between_steps = False
        for _, _, execute in due:
            run(execute)

    # ------------------------------------------------------------------ counting
    def count(self, node: Any, key: str) -> Counted | None:
        """Count the requests a server of ``node`` takes: in the participant's process, for a node its
        executor spins (not a lifecycle manager, which serves its requests from a thread of its own)."""
        if (self.receiver is None or self.context is None or node.context is not self.context
                or getattr(node, "spins_itself", False)):
            return None
        return self.receiver.deliveries.add(key, catch_up=True)

    def taken(self, counted: Counted | None, requests: int) -> None:
        if counted is None or not requests:
            return
        counted.received += requests
        self.receiver.on_delivery()


REQUESTS = Requests()


def install_requests() -> None:
    """Count and keep requests to this process's servers (once; idempotent)."""
    if getattr(rclpy.node.Node, "_pppbot_requests", False):
        return
    create_service = rclpy.node.Node.create_service

    @functools.wraps(create_service)
    def kept_service(self: Any, srv_type: Any, srv_name: str, callback: Any, **kwargs: Any) -> Any:
        service: Any = create_service(self, srv_type, srv_name, callback, **kwargs)
        key = request_key(service.service_name)
        counted = None if key.endswith(UNCOUNTED) else REQUESTS.count(self, key)
        if counted is not None:  # only a counted request is kept: no step would wait for another
            service.callback = functools.partial(_service_callback, service, key, counted, service.callback)
        return service

    send_response = rclpy.service.Service.send_response

    @functools.wraps(send_response)
    def kept_response(self: Any, response: Any, header: Any) -> None:
        if isinstance(response, KeptRequest):
            response.header = header  # answered when the request is handled, at the next step
            return
        send_response(self, response, header)

    server_init = rclpy.action.server.ActionServer.__init__

    @functools.wraps(server_init)
    def counted_server(self: Any, node: Any, action_type: Any, action_name: str, *args: Any, **kwargs: Any) -> None:
        server_init(self, node, action_type, action_name, *args, **kwargs)
        self._pppbot_request_key = action_key(node, action_name)
        self._pppbot_counted = REQUESTS.count(node, self._pppbot_request_key)

    execute_data = rclpy.action.server.ActionServer.execute

    @functools.wraps(execute_data)
    async def kept_execute(self: Any, taken_data: Any) -> None:
        requests = {kind: taken_data[kind] for kind in ("goal", "cancel", "result") if kind in taken_data}
        rest = {kind: value for kind, value in taken_data.items() if kind not in requests}
        if rest:
            await execute_data(self, rest)  # expired goals: the server's own bookkeeping
        counted = getattr(self, "_pppbot_counted", None)
        if requests:
            execute = functools.partial(execute_data, self, requests)
            # Kept (or not) before it is counted: the count may let the step be handled, which
            # then runs what is kept, in order.
            keeping = counted is not None and REQUESTS.keep(self._pppbot_request_key, execute)
            REQUESTS.taken(counted, len(requests))
            if not keeping:
                await execute()

    rclpy.node.Node.create_service = kept_service  # type: ignore[method-assign]
    rclpy.service.Service.send_response = kept_response  # type: ignore[method-assign]
    rclpy.action.server.ActionServer.__init__ = counted_server  # type: ignore[method-assign]
    rclpy.action.server.ActionServer.execute = kept_execute  # type: ignore[method-assign]
    rclpy.node.Node._pppbot_requests = True  # type: ignore[attr-defined]


class KeptRequest:
    """A service request kept for the next step: what the service's callback returns meanwhile (the
    executor then hands it the request's header instead of sending a response)."""

    def __init__(self, service: Any, callback: Callable[[Any, Any], Any], request: Any) -> None:
        self.service = service
        self.callback = callback
        self.request = request
        self.header: Any = None

    async def execute(self) -> None:
        response = self.callback(self.request, self.service.srv_type.Response())
        self.service.send_response(response, self.header)


def _service_callback(service: Any, key: str, counted: Counted, callback: Callable[[Any, Any], Any],
                      request: Any, response: Any) -> Any:
    """A service's callback: the request handled now, or kept for the next step (both executors,
    rclpy's and the EventsExecutor, call the callback and then ``send_response``)."""
    kept = KeptRequest(service, callback, request)
    keeping = REQUESTS.keep(key, kept.execute)
    REQUESTS.taken(counted, 1)
    return kept if keeping else callback(request, response)
