"""Readiness from the ROS graph, for the supervisor: "a first message arrived on <topic>", "a
node has its publishers, subscriptions and action servers", "a lockstep participant has joined".

A hidden node spins in a background thread. A message probe is a subscription that
remembers whether a message came; subscriptions are made before the nodes start, so
nothing is missed (and latched topics are asked for with transient local QoS). An
endpoint probe asks the graph (as ``ros2 node info`` does) each time it is called.
"""
from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable, Sequence

import rclpy
from lifecycle_msgs.msg import State
from lifecycle_msgs.srv import GetState
from rclpy.action import get_action_server_names_and_types_by_node
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.qos import QoSProfile
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock

from pppbot_common.dds_participants import discovery_stays_on_this_machine, others_on_this_machine
from pppbot_common.ros.messages import get_interface
from pppbot_common.ros.nodes import unspun_node
from pppbot_common.ros.qos import DEFAULT, LATCHED
from pppbot_common.ros.retry import Request, Retry, Unanswered
from pppbot_interfaces.msg import LockstepStatus
from pppbot_lockstep.ros.participant import STATUS_QOS, STATUS_TOPIC

#: how long a new launch listens for another simulation's /clock on its domain (a simulation
#: publishes it at 100 Hz; discovering and matching its publisher takes one to three seconds, on a
#: busy machine more: a missed first announcement waits for the next, three seconds on)
DOMAIN_CHECK_S = 6.0
#: with no other node in the graph after this long, the domain is taken to be empty (on a busy
#: machine discovering another participant's nodes can take over a second)
EMPTY_DOMAIN_S = 2.0
#: a lifecycle probe's get_state request unanswered this long (wall s) is sent again
STATE_RETRY_S = 2.0
STATE_RETRY = Retry(STATE_RETRY_S, attempts=3)


def domain_taken_message(what: str, environ: dict[str, str] | None = None) -> str:
    """The refusal: what runs on which domain, and how to pick another."""
    import os
    domain = (environ or dict(os.environ)).get("ROS_DOMAIN_ID", "0")
    other = 1 if domain != "1" else 2
    return (f"ROS_DOMAIN_ID={domain} already has {what}; a second one would mix with it (its clock, maps and "
            f"transforms). Stop it, or run on another domain: ROS_DOMAIN_ID={other} make run (every terminal of "
            "a stack needs the same ROS_DOMAIN_ID)")


def free_domain(candidates: Sequence[int], wait_s: float = DOMAIN_CHECK_S) -> int:
    """The first of ``candidates`` (ROS_DOMAIN_IDs) on which no other node shows up within ``wait_s``.

    Raises:
        RuntimeError: every candidate is in use.
    """
    for domain in candidates:
        context = rclpy.Context()
        rclpy.init(args=[], context=context, domain_id=domain, signal_handler_options=SignalHandlerOptions.NO)
        try:
            node = unspun_node("_pppbot_domain_probe", context=context, enable_rosout=False)
            deadline = time.monotonic() + wait_s
            others: list[str] = []
            while not others and time.monotonic() < deadline:
                time.sleep(0.1)
                others = [n for n, _ in node.get_node_names_and_namespaces() if n != "_pppbot_domain_probe"]
            node.destroy_node()
        finally:
            rclpy.try_shutdown(context=context)
        if not others:
            return domain
    raise RuntimeError(f"every ROS_DOMAIN_ID tried ({', '.join(map(str, candidates))}) has nodes on it")


class GraphProbe:
    def __init__(self) -> None:
        # The supervisor owns Ctrl-C; rclpy must not install its own handler.
        self.context = rclpy.Context()
        rclpy.init(args=[], context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = unspun_node("_launch_sim_probe", context=self.context, enable_rosout=False)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._closed = False
        self._joined: set[str] = set()
        self._status_subscribed = False
        self._thread = threading.Thread(target=self._spin, name="graph-probe", daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        with contextlib.suppress(ExternalShutdownException, rclpy.executors.ShutdownException):
            self.executor.spin()

    def first_message(self, topic: str, type_name: str, latched: bool | QoSProfile = False) -> Callable[[], bool]:
        """A probe that turns true once a message arrives on ``topic`` (``latched``: transient local)."""
        seen = threading.Event()
        qos = latched if isinstance(latched, QoSProfile) else LATCHED if latched else DEFAULT
        self.node.create_subscription(get_interface(type_name), topic, lambda _msg: seen.set(), qos, raw=True)
        self.executor.wake()
        return seen.is_set

    def endpoints(self, node: str, publishes: Sequence[str] = (), subscribes: Sequence[str] = (),
                  action_servers: Sequence[str] = ()) -> Callable[[], bool]:
        """A probe that turns true once node ``node`` (in the root namespace) publishes, subscribes
        and serves (actions) every one of the given fully qualified names; once true it stays
        true, as a message probe does (and answers so after :meth:`close`)."""
        seen = threading.Event()

        def probe() -> bool:
            if seen.is_set() or self._closed:
                return seen.is_set()
            try:
                have = [{name for name, _ in self.node.get_publisher_names_and_types_by_node(node, "/")},
                        {name for name, _ in self.node.get_subscriber_names_and_types_by_node(node, "/")},
                        {name for name, _ in get_action_server_names_and_types_by_node(self.node, node, "/")}]
            except RuntimeError:  # rclpy's RCLError: the node is not discovered yet
                return False
            if all(set(wanted) <= got for wanted, got in zip((publishes, subscribes, action_servers), have,
                                                             strict=True)):
                seen.set()
            return seen.is_set()
        return probe

    def lifecycle_active(self, node: str) -> Callable[[], bool]:
        """A probe that turns true once lifecycle node ``node`` (in the root namespace) says it is
        active on ``<node>/get_state``, as ``ros2 lifecycle get`` and BasicNavigator ask; once true
        it stays true. A request unanswered for :data:`STATE_RETRY_S` is sent again
        (:class:`~pppbot_common.ros.retry.Request`: Fast DDS drops an answer to a client its server
        has not discovered yet); one given up on is followed by a new one."""
        seen = threading.Event()
        client = self.node.create_client(GetState, f"/{node}/get_state")
        asking: list[Request[GetState.Response]] = []

        def probe() -> bool:
            if seen.is_set() or self._closed:
                return seen.is_set()
            try:
                if asking and asking[0].poll():
                    answer = asking.pop().pending.result()
                    if answer is not None and answer.current_state.id == State.PRIMARY_STATE_ACTIVE:
                        seen.set()
            except Unanswered:
                asking.pop()
            if not seen.is_set() and not asking and client.service_is_ready():
                asking.append(Request(lambda: client.call_async(GetState.Request()), STATE_RETRY,
                                      f"service {client.srv_name}, asked by {self.node.get_fully_qualified_name()}",
                                      forget=client.remove_pending_request))
                self.executor.wake()
            return seen.is_set()
        return probe

    def running_stack(self, wait_s: float = DOMAIN_CHECK_S) -> str | None:
        """What already runs a simulation on this domain (something publishing ``/clock``), heard
        within ``wait_s``; None when nothing does. A probe's own readiness checks would be fooled by
        it, and its nodes would mix with this launch's.

        Discovery kept on this machine and no participant in the domain besides this process and
        those that started it (:func:`~pppbot_common.dds_participants.others_on_this_machine`):
        nothing can run there, and it answers at once. Other participants here: it listens the
        whole ``wait_s`` (discovering one can take an announcement period of three seconds). Where
        that cannot be told: a domain that shows no other node after :data:`EMPTY_DOMAIN_S` is
        taken for empty."""
        others = others_on_this_machine(self.context.get_domain_id())
        if others == 0 and discovery_stays_on_this_machine():
            return None
        heard = threading.Event()
        subscription = self.node.create_subscription(Clock, "/clock", lambda _msg: heard.set(), DEFAULT, raw=True)
        self.executor.wake()  # the spinning thread waits on the entities it had: take the new one in
        try:
            start = time.monotonic()
            while not heard.wait(0.1) and time.monotonic() - start < wait_s:
                if self.node.count_publishers("/clock") > 0:
                    heard.set()  # the graph shows a /clock publisher: as good as a message, and sooner
                elif not others and time.monotonic() - start > EMPTY_DOMAIN_S and not self._other_nodes():
                    break
        finally:
            self.node.destroy_subscription(subscription)
        if not heard.is_set():
            return None
        names = self._other_nodes()
        return "a simulation running (something publishes /clock" + (f"; nodes: {', '.join(names)})" if names else ")")

    def _other_nodes(self) -> list[str]:
        return sorted({name for name, _ in self.node.get_node_names_and_namespaces() if not name.startswith("_")})

    def joined(self, participant: str) -> Callable[[], bool]:
        """A probe that turns true once the simulator lists ``participant`` as joined on /lockstep/status."""
        if not self._status_subscribed:
            self._status_subscribed = True
            self.node.create_subscription(LockstepStatus, STATUS_TOPIC, self._on_status, STATUS_QOS)
        return lambda: participant in self._joined

    def _on_status(self, msg: LockstepStatus) -> None:
        self._joined |= set(msg.participants)

    def close(self) -> None:
        """Stop listening (idempotent); probes keep answering what they saw."""
        if self._closed:
            return
        self._closed = True
        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
        self._thread.join(timeout=2.0)
