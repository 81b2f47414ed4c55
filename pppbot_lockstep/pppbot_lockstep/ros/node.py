"""The seam between pppbot's nodes and lockstep: :class:`StepNode`, the node base class whose
endpoints go through the node's step port (:mod:`pppbot_lockstep.ros.port`).

Every pppbot node is a :class:`StepNode` (a lifecycle node a
:class:`~pppbot_lockstep.ros.lifecycle.ManagedNode`). The node runner hands it its process's port
(``port=``); without one (a node made by a test, a tool) it runs freely. What the node makes
itself goes through the port; rclpy is extended, never changed:

* publishers are :class:`StepPublisher` (rclpy's ``publisher_class`` argument);
* a subscription made with ``data_path=True`` counts what it receives (a step is handled only
  once every message published before it is here) and, in lockstep, is reliable; with
  ``at_step=True`` each message is handled at the next step;
* clients are :class:`StepClient` and services :class:`AnsweringService` or, counted in lockstep,
  :class:`StepService` (the instances rclpy makes, given the subclass's class: rclpy's
  ``create_client`` and ``create_service`` take no class); an answer Fast DDS could not deliver
  yet (the client just started) is sent again until it goes (:func:`delivered`);
* action servers are :class:`StepActionServer` (:class:`~pppbot_lockstep.ros.goals.GoalServer`
  makes them) and action clients :class:`~pppbot_lockstep.ros.action_client.ActionClient`;
* :meth:`StepNode.step_timer` makes a timer on sim time, fired by steps in lockstep.

What rclpy makes for itself in a node (its parameter services, ``/parameter_events``, the
``/clock`` subscription) is left as rclpy makes it, and so is every plain rclpy node.
:class:`StepExecutor` tells the port of each task the process's executor makes, so a participant
answers a step only once the work it set off has run.
"""
from __future__ import annotations

import functools
import inspect
import threading
import time
import warnings
from collections.abc import Callable
from typing import Any

from rclpy.action import ActionServer
from rclpy.client import Client
from rclpy.clock import Clock, ClockType
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message
from rclpy.service import Service
from rclpy.task import Future

from pppbot_common.throttle import Throttle
from pppbot_lockstep.ros.port import FREE_RUNNING, StepPort, Timer
from pppbot_lockstep.ros.requests import KeptRequest, action_key, counted_service, request_key


def port_of(node: Node) -> StepPort:
    """The step port ``node`` sends through (a plain rclpy node's: the free-running one)."""
    port = getattr(node, "port", None)
    return port if isinstance(port, StepPort) else FREE_RUNNING


class StepPublisher(Publisher):
    """A publisher whose messages go through its node's step port: counted on its topic and, in
    lockstep, held (serialized) until the next step."""

    _step_port: StepPort = FREE_RUNNING
    _step_topic = ""
    _asks_round = True

    def attach(self, port: StepPort, asks_round: bool = True) -> None:
        """Send through ``port``; ``asks_round=False``: nobody in lockstep reacts to these messages at
        the time they are sent (a wheel's transform), so they ask for no further round."""
        self._step_port = port
        self._step_topic = self.topic_name
        self._asks_round = asks_round

    def publish(self, msg: Any) -> None:
        """Publish ``msg`` (a message or its serialized bytes) through the node's port."""
        port = self._step_port
        if not port.counts:
            super().publish(msg)
            return
        port.publish(self, msg, self._step_topic, asks_round=self._asks_round)


class StepClient(Client):
    """A service client whose requests go through its node's step port (counted on the server's
    key, held in lockstep until the next step: the caller then gets a held future)."""

    _step_port: StepPort = FREE_RUNNING
    _step_key = ""

    def attach(self, port: StepPort) -> None:
        self._step_port = port
        self._step_key = request_key(self.service_name)

    def call_async(self, request: Any) -> Any:
        port = self._step_port
        if not port.counts:
            return super().call_async(request)
        return port.request(functools.partial(Client.call_async, self), self._step_key, request)


#: rclpy's warning when Fast DDS dropped an answer: the server has not matched the client's reply
#: reader yet (rmw_fastrtps waits 100 ms for it), most often for a client that just started.
_UNDELIVERED = "failed to send response (timeout)"
#: Wall seconds an undelivered answer is sent again, and how often.
RESEND_WINDOW_S, RESEND_PERIOD_S = 10.0, 0.1
_recording = threading.RLock()  # warnings.catch_warnings changes the process's warning filters (nested: a
# goal's acceptance sent while the accepted callback answers a service)


def delivered(send: Callable[[], None]) -> bool:
    """Run ``send`` (rclpy's ``send_response``); False when the answer was dropped undelivered
    (rclpy only warns). Other warnings pass on as they came."""
    with _recording, warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        send()
    undelivered = False
    for warning in caught:
        if issubclass(warning.category, RuntimeWarning) and _UNDELIVERED in str(warning.message):
            undelivered = True
        else:
            warnings.warn_explicit(warning.message, warning.category, warning.filename, warning.lineno)
    return not undelivered


def _delivered_or_gone(send: Callable[[], None]) -> bool:
    """:func:`delivered` for an action server's answer; True too when rclpy could not send it at all
    (``RCLError``: the client gone), as there is nothing to send again."""
    try:
        return delivered(send)
    except _rclpy.RCLError:
        return True


def _awaits(callback: Any) -> bool:
    """Whether an action server's callback may suspend (a coroutine function)."""
    return inspect.iscoroutinefunction(callback) or inspect.iscoroutinefunction(type(callback).__call__)


def _run_now(coroutine: Any) -> None:
    """Run ``coroutine`` to its end now: rclpy's handling of a goal request, whose callbacks are
    plain functions (it awaits nothing that is not already there)."""
    try:
        coroutine.send(None)
    except StopIteration:
        return
    coroutine.close()
    raise RuntimeError("a goal request's handling waited on something")


class AnsweringService(Service):
    """A service whose answer reaches a client it has not discovered yet: Fast DDS drops it and rclpy
    only warns, and a client that does not ask again (Nav2's BasicNavigator waiting for a node's
    ``get_state``, ``ros2 service call``) would wait for good. Here it is sent again (by the node,
    every :data:`RESEND_PERIOD_S`) until it goes or :data:`RESEND_WINDOW_S` have passed."""

    _resend: Callable[[str, Callable[[], bool]], None] | None = None

    def send_response(self, response: Any, header: Any) -> None:
        send = functools.partial(Service.send_response, self, response, header)
        if not delivered(send) and self._resend is not None:
            self._resend(self.srv_name, functools.partial(delivered, send))


class StepService(AnsweringService):
    """A service whose requests, in lockstep, wait for the next step (the port's ``serve`` keeps them
    as :class:`~pppbot_lockstep.ros.requests.KeptRequest`, answered when handled) and whose
    replies count as a round's work."""

    _step_port: StepPort = FREE_RUNNING

    def send_response(self, response: Any, header: Any) -> None:
        if isinstance(response, KeptRequest):
            response.header = header  # answered when the request is handled, at the next step
            return
        self._step_port.replied()
        super().send_response(response, header)


class StepActionServer(ActionServer):
    """An action server whose goal, cancel and result requests, in lockstep, wait for the next step
    and whose replies count as a round's work.

    A goal's acceptance or result that Fast DDS dropped (the client just started, its reply reader
    not matched yet: rclpy only warns) is sent again until it goes, as :class:`AnsweringService`
    sends a service's answer: a client that never hears its goal was accepted (Nav2's
    BasicNavigator) would wait without end while the goal runs.

    rclpy keeps each goal and its result for ``result_timeout`` (900 s) after it ends, as
    Python messages: at 1 Hz replanning a path server's kept goals and paths made a
    navigation process grow by 50 MB over its first 15 minutes. Here an ended goal forgets
    its request, and its result is kept serialized (a tenth of the size), to be read back
    for a client asking for it late."""

    def __init__(self, node: Node, action_type: Any, action_name: str, *args: Any, **kwargs: Any) -> None:
        super().__init__(node, action_type, action_name, *args, **kwargs)
        self._step_port = port_of(node)
        self._step_key = action_key(node, action_name)
        self._step_counted = self._step_port.count_requests(node, self._step_key)
        self._name = action_name

    async def _execute_goal_request(self, request_header_and_message: Any) -> None:
        header, request = request_header_and_message
        goal_uuid = bytes(request.goal_id.uuid)
        known = goal_uuid in self._goal_handles  # a goal ID taken before: rclpy refuses it
        handle_it = ActionServer._execute_goal_request(self, request_header_and_message)
        if _awaits(self._goal_callback) or _awaits(self._handle_accepted_callback):
            await handle_it  # it may wait on others: its acceptance is not watched
        elif not delivered(functools.partial(_run_now, handle_it)):
            handle = None if known else self._goal_handles.get(goal_uuid)
            response = self._action_type.Impl.SendGoalService.Response(accepted=handle is not None)
            if handle is not None:
                response.stamp = handle._goal_info.stamp  # rclpy's ServerGoalHandle: when it was accepted
            self._send_again("send_goal", functools.partial(self._handle.send_goal_response, header, response))
        result = self._result_futures.get(goal_uuid)
        if result is not None and not result.done():  # accepted and running
            result.add_done_callback(functools.partial(self._keep_ended, goal_uuid))

    def _keep_ended(self, goal_uuid: bytes, result: Future) -> None:
        """Goal ``goal_uuid`` ended with ``result``: keep only what a client may still ask for."""
        handle = self._goal_handles.get(goal_uuid)
        if handle is not None:
            handle._goal_request = None  # rclpy's ServerGoalHandle: nobody reads an ended goal's request
        if self._result_futures.get(goal_uuid) is not result or result.exception() is not None:
            return
        kept = Future()
        kept.set_result(serialize_message(result.result()))
        if result in self._futures:  # not when the server was destroyed meanwhile
            self.remove_future(result)
            self.add_future(kept)
        self._result_futures[goal_uuid] = kept

    def _send_result_response(self, request_header: Any, future: Future) -> None:
        response = future.result()
        if isinstance(response, bytes):  # kept serialized by _keep_ended
            response = deserialize_message(response, self._action_type.Impl.GetResultService.Response)
        send = functools.partial(self._handle.send_result_response, request_header, response)
        if not _delivered_or_gone(send):
            self._send_again("get_result", send)

    def _send_again(self, what: str, send: Callable[[], None]) -> None:
        """Have the node send an answer Fast DDS dropped again until it goes (a plain rclpy node,
        which cannot: named)."""
        name = f"{self._node.resolve_topic_name(self._name, only_expand=True)}/_action/{what}"
        resend = getattr(self._node, "_send_again", None)
        if resend is None:
            self._node.get_logger().warning(f"{name}: an answer could not reach its client")
        else:
            resend(name, functools.partial(_delivered_or_gone, send))

    async def execute(self, taken_data: Any) -> None:
        """rclpy's, with the requests in ``taken_data`` handled now or kept for the next step."""
        port = self._step_port
        requests = {kind: taken_data[kind] for kind in ("goal", "cancel", "result") if kind in taken_data}
        if not port.counts or not requests:
            await super().execute(taken_data)
            return
        rest = {kind: value for kind, value in taken_data.items() if kind not in requests}
        if rest:
            await super().execute(rest)  # expired goals: the server's own bookkeeping

        async def handle() -> None:
            port.replied()
            await ActionServer.execute(self, requests)

        if not port.take_requests(self._step_counted, self._step_key, handle, len(requests)):
            await handle()


class StepNode(Node):
    """A node whose endpoints go through ``port`` (its process's, from the node runner; none: it
    runs freely). Takes rclpy Node's arguments after its name."""

    def __init__(self, node_name: str, *, port: StepPort | None = None, **kwargs: Any) -> None:
        self._undelivered: list[tuple[str, Callable[[], bool], float]] = []  # service, send again, until
        self._resend_timer: Any = None
        self._resend_failures = Throttle(FAILED_REQUEST_PERIOD_S)
        super().__init__(node_name, **kwargs)
        #: what this node's endpoints send and time through (see the module's docstring)
        self.port: StepPort = port or FREE_RUNNING

    def create_publisher(self, msg_type: Any, topic: str, qos_profile: QoSProfile | int, *,
                         aside: bool = False, **kwargs: Any) -> Publisher:
        """rclpy's, through the node's port; ``aside=True``: messages nobody in lockstep reacts to at
        their time (counted for delivery, asking no further round)."""
        kwargs.setdefault("publisher_class", StepPublisher)
        publisher = super().create_publisher(msg_type, topic, qos_profile, **kwargs)
        if isinstance(publisher, StepPublisher):
            publisher.attach(self._port(), asks_round=not aside)
        return publisher

    def create_subscription(self, msg_type: Any, topic: str, callback: Callable[[Any], None],
                            qos_profile: QoSProfile | int, *, data_path: bool = False, at_step: bool = False,
                            quiet: bool | Callable[[], bool] = False, needs_publisher: bool = True, what: str = "",
                            **kwargs: Any) -> Any:
        """rclpy's. ``data_path=True``: a subscription on lockstep's data path (what the simulator and
        the participants publish as the run goes on): its receptions are counted, in lockstep it is
        reliable, and the process joins once it hears every publisher and at least one
        (``needs_publisher=False``: none may come, such as a teleop input; ``what`` says what it
        waits for). ``at_step=True``: each message is handled at the next step (one that makes
        the node send). ``quiet=True`` (data path): handling a message sends nothing (it is recorded,
        or kept for the node's timers), so what others send on the topic needs no round of its own:
        it comes with the next step, before the timers run, as it would have (a callable: asked when
        the process tells its topics, at joining)."""
        port = self._port()
        if at_step:
            callback = port.at_step(callback)
        if data_path:
            callback = port.counted(self, self.resolve_topic_name(topic), callback, quiet)
            if port.counts:
                qos_profile = _reliable(qos_profile if isinstance(qos_profile, QoSProfile)
                                        else QoSProfile(depth=qos_profile))
        subscription = super().create_subscription(msg_type, topic, callback, qos_profile, **kwargs)
        if data_path and needs_publisher:
            port.require_match(self, subscription, what)
        return subscription

    def create_client(self, srv_type: Any, srv_name: str, **kwargs: Any) -> Client:
        client = super().create_client(srv_type, srv_name, **kwargs)
        client.__class__ = StepClient  # the same object, with the subclass's call_async
        assert isinstance(client, StepClient)
        client.attach(self._port())
        return client

    def create_service(self, srv_type: Any, srv_name: str, callback: Callable[[Any, Any], Any],
                       **kwargs: Any) -> Service:
        """rclpy's, with a callback that always answers (:func:`answering`)."""
        callback = answering(self, srv_name, callback)
        service = super().create_service(srv_type, srv_name, callback, **kwargs)
        port = self._port()
        key = request_key(service.service_name)
        if port.counts and counted_service(key):
            service.__class__ = StepService  # the same object, with the subclass's send_response
            assert isinstance(service, StepService)
            service._step_port = port
            service.callback = port.serve(self, key, callback,
                                          lambda request: KeptRequest(service, callback, request))
        else:
            service.__class__ = AnsweringService
        assert isinstance(service, AnsweringService)
        service._resend = self._send_again
        return service

    def _send_again(self, service: str, attempt: Callable[[], bool]) -> None:
        self._undelivered.append((service, attempt, time.monotonic() + RESEND_WINDOW_S))
        if self._resend_timer is None:  # made on the first answer to send again: a node never has one idle
            self._resend_timer = self.create_timer(RESEND_PERIOD_S, self._resend_undelivered,
                                                   clock=Clock(clock_type=ClockType.STEADY_TIME))
        else:
            self._resend_timer.reset()

    def _resend_undelivered(self) -> None:
        now, left = time.monotonic(), []
        for service, attempt, until in self._undelivered:
            if attempt():
                continue
            if now < until:
                left.append((service, attempt, until))
            elif self._resend_failures.allow(service, now):
                self.get_logger().warning(f"{service}: an answer could not reach its client within "
                                          f"{RESEND_WINDOW_S:g} s (the client gone before it was discovered?)")
        self._undelivered = left
        if not left:
            self._resend_timer.cancel()

    def step_timer(self, period_s: float, callback: Callable[[], object], *, wakes: bool = True) -> Timer:
        """A periodic timer on sim time: fired by lockstep's steps in lockstep (``wakes=False``: at the
        first step at or after its deadline, without making one), else an rclpy timer on the node's
        clock."""
        return self._port().create_timer(self, period_s, callback, wakes)

    def destroy_step_timer(self, timer: Timer) -> None:
        self._port().destroy_timer(self, timer)

    def _port(self) -> StepPort:
        # rclpy's Node.__init__ makes its own endpoints (parameter services, /parameter_events)
        # before this node has a port: those stay rclpy's.
        return getattr(self, "port", FREE_RUNNING)


#: A kind of failure of a service's callback is logged at most once per this (wall s).
FAILED_REQUEST_PERIOD_S = 5.0


def answering(node: Node, name: str, callback: Callable[[Any, Any], Any]) -> Callable[[Any, Any], Any]:
    """A service ``callback`` that answers every request: one it fails on (an exception) is answered
    with the response as it stands (a service's own failure fields, such as ``success``, are false
    until set), and the failure is logged, at most once per :data:`FAILED_REQUEST_PERIOD_S` for each
    kind. An unanswered request would leave its caller waiting forever."""
    throttle = Throttle(FAILED_REQUEST_PERIOD_S)

    def call(request: Any, response: Any) -> Any:
        try:
            return callback(request, response)
        except Exception as exc:  # one bad request must neither end the node nor go unanswered
            if throttle.allow(type(exc).__name__, time.monotonic()):
                node.get_logger().error(f"{name}: could not handle a request ({type(exc).__name__}: {exc}); "
                                        "answered with an empty response")
            return response

    return call


def subscribe(node: Node, msg_type: Any, topic: str, callback: Callable[[Any], None], qos_profile: QoSProfile | int,
              **lockstep: Any) -> Any:
    """``node.create_subscription``, with :meth:`StepNode.create_subscription`'s ``lockstep`` keywords
    (``data_path``, ``at_step``, ...) when ``node`` is a :class:`StepNode`; for a plain rclpy node (a
    test's, a tool's) an ordinary one."""
    if isinstance(node, StepNode):
        return node.create_subscription(msg_type, topic, callback, qos_profile, **lockstep)
    return node.create_subscription(msg_type, topic, callback, qos_profile)


def _reliable(qos: QoSProfile) -> QoSProfile:
    """``qos`` made reliable: in lockstep no data-path message may be lost (the simulator's and the
    participants' publishers are reliable; a step waits for what a best-effort reader would drop)."""
    if qos.reliability == ReliabilityPolicy.RELIABLE:
        return qos
    return QoSProfile(history=qos.history, depth=qos.depth, reliability=ReliabilityPolicy.RELIABLE,
                      durability=qos.durability)


class StepExecutor(_rclpy.EventsExecutor):
    """rclpy's EventsExecutor telling ``port`` of every task it makes (a future's callback, an
    action's goal): a participant answers a step once those have run."""

    def __init__(self, port: StepPort, context: Any = None) -> None:
        import rclpy
        context = context or rclpy.get_default_context()
        super().__init__(context)
        self._step_port = port
        context.on_shutdown(self.wake)  # as rclpy.experimental.EventsExecutor does

    def create_task(self, callback: Any, *args: Any, **kwargs: Any) -> Any:
        self._step_port.task_created()
        return super().create_task(callback, *args, **kwargs)
