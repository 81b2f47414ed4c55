"""The navigator's :class:`~pppbot_nav.bt.ports.RobotPorts`: rclpy action and service clients, TF and
subscriptions, made on first use and kept for the node's life.

In lockstep a tree runs the same on every machine: a goal's acceptance, and the result of a
server that answers promptly (a planner, a smoother, a costmap's clearing, ``is_path_valid``)
are waited for within the step that asked (:meth:`StepPort.hold_for`), and ``wake`` is called
when they came so the tree is ticked again at once (BehaviorTree.CPP's wake-up signal). The
result of a goal that runs for a while (following a path, a spin) is seen at the tree's next
tick, whenever it happened to arrive within that period. A goal or request to a server that is
not there is not sent (no step could wait for its answer): the node sees it refused.
"""
from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

from action_msgs.msg import GoalStatus as GoalStatusMsg
from nav2_msgs.action import ComputePathThroughPoses, ComputePathToPose, SmoothPath
from rclpy.action.client import ClientGoalHandle
from rclpy.node import Node
from rclpy.task import Future

from pppbot_common.ros.qos import LATCHED
from pppbot_common.transforms import TransformBuffer, TransformError
from pppbot_lockstep.ros.action_client import ActionClient
from pppbot_lockstep.ros.goals import Arrival, Cancels
from pppbot_lockstep.ros.node import port_of
from pppbot_lockstep.ros.runner import guarded
from pppbot_nav.bt.ports import GoalStatus, Outcome

#: actions whose servers answer as soon as they computed (their result is waited for within the step)
PROMPT_ACTIONS = (ComputePathToPose, ComputePathThroughPoses, SmoothPath)
_ENDS = {GoalStatusMsg.STATUS_SUCCEEDED: GoalStatus.SUCCEEDED, GoalStatusMsg.STATUS_CANCELED: GoalStatus.CANCELED,
         GoalStatusMsg.STATUS_ABORTED: GoalStatus.ABORTED}


class RosGoalCall:
    def __init__(self, port: RosActionPort, goal: Any, on_feedback: Callable[[Any], None] | None) -> None:
        self._port = port
        feedback = None if on_feedback is None else (lambda msg: on_feedback(msg.feedback))
        self._sent: Future = port.client.send_goal_async(goal, feedback_callback=feedback)
        self._handle: ClientGoalHandle | None = None
        self._taken = False  # the server's answer to the goal has been read
        self._result: Future | Arrival | None = None
        self._canceled = False
        port.live.append(self)
        port.ports.waited(self._sent, self._on_sent)

    def _on_sent(self, sent: Future) -> None:
        """The server answered the goal: read once, from the done callback or from the first look
        after the future is done, whichever comes first (rclpy runs done callbacks later, on the
        executor: a tick in between sees the future done before the callback ran)."""
        if self._taken:
            return
        self._taken = True
        handle = None if sent.cancelled() or sent.exception() is not None else sent.result()
        if not isinstance(handle, ClientGoalHandle) or not handle.accepted:
            return
        if self._canceled:  # canceled before it was taken: cancel it now, asked again until it ends
            self._port.ports.cancels.cancel(handle, handle.get_result_async())
            return
        self._handle = handle
        future = handle.get_result_async()
        if self._port.prompt:
            self._port.ports.waited(future)
            self._result = future
        else:  # seen from the first tick after it came, the same tick on every machine
            self._result = Arrival(future, self._port.ports.clock_s, self._port.ports.step_port)

    def _answered(self) -> bool:
        if self._sent.done():
            self._on_sent(self._sent)
        return self._taken

    def accepted(self) -> bool | None:
        if not self._answered():
            return None
        return self._handle is not None

    def outcome(self) -> Outcome | None:
        if self._result is None or not self._result.done():
            return None
        future = self._result.future if isinstance(self._result, Arrival) else self._result
        if future.exception() is not None:
            return None
        wrapped = future.result()
        status = _ENDS.get(wrapped.status)
        return None if status is None else Outcome(status, wrapped.result)

    def ended(self) -> bool:
        return (self._answered() and self._handle is None) or (self._result is not None and self._result.done())

    def cancel(self) -> None:
        if self._canceled:
            return
        self._canceled = True
        if self._handle is not None:
            future = self._result.future if isinstance(self._result, Arrival) else self._result
            self._port.ports.cancels.cancel(self._handle, future)


class Unsent:
    """A goal or request not sent, its server not being there: refused at once, never answered (no
    step waits for it; the node fails as Nav2's does when its server is missing)."""

    def accepted(self) -> bool | None:
        return False

    def outcome(self) -> Outcome | None:
        return None

    def response(self) -> Any | None:
        return None

    def refused(self) -> bool:
        return True

    def ended(self) -> bool:
        return True

    def cancel(self) -> None:
        pass


class RosActionPort:
    def __init__(self, ports: RosPorts, name: str, action_type: Any) -> None:
        self.ports = ports
        self.client = ActionClient(ports.node, action_type, name)
        self.prompt = action_type in PROMPT_ACTIONS
        self.live: list[RosGoalCall] = []

    def ready(self) -> bool:
        return self.client.server_is_ready()

    def send(self, goal: Any, on_feedback: Callable[[Any], None] | None = None) -> RosGoalCall | Unsent:
        self.live = [call for call in self.live if not call.ended()]
        if not self.ready():
            self.ports.missing(f"action server '{self.client._action_name}'")  # noqa: SLF001 - rclpy keeps it there
            return Unsent()
        return RosGoalCall(self, goal, on_feedback)

    def cancel_all(self) -> None:
        """Cancel every goal of this server the navigator's tree sent that has not ended."""
        for call in self.live:
            if not call.ended():
                call.cancel()
        self.live = []


class RosServiceCall:
    def __init__(self, future: Future) -> None:
        self._future = future

    def response(self) -> Any | None:
        if not self._future.done() or self._future.exception() is not None:
            return None
        return self._future.result()

    def refused(self) -> bool:
        return False


class RosServicePort:
    def __init__(self, ports: RosPorts, name: str, service_type: Any) -> None:
        self.ports = ports
        self.client = ports.node.create_client(service_type, name)

    def ready(self) -> bool:
        return self.client.service_is_ready()

    def call(self, request: Any) -> RosServiceCall | Unsent:
        if not self.ready():
            self.ports.missing(f"service '{self.client.srv_name}'")
            return Unsent()
        future = self.client.call_async(request)
        self.ports.waited(future)
        return RosServiceCall(future)


class RosPorts:
    """The tree's ports on ``node``: ``tf`` its transform buffer, ``cancels`` what re-asks canceled
    goals until they end, ``wake`` what ticks the tree again (a prompt answer came)."""

    def __init__(self, node: Node, tf: TransformBuffer, cancels: Cancels, wake: Callable[[], None],
                 warn: Callable[[str, str], None] = lambda key, message: None) -> None:
        self.node = node
        self._warn = warn
        self.tf = tf
        self.cancels = cancels
        self.wake = wake
        self.step_port = port_of(node)
        self._actions: dict[str, RosActionPort] = {}
        self._services: dict[str, RosServicePort] = {}
        self._topics: dict[str, list[Any]] = {}

    def clock_s(self) -> float:
        return float(self.node.get_clock().now().nanoseconds * 1e-9)

    def missing(self, what: str) -> None:
        self._warn("bt_server", f"the tree's node found no {what}: it fails, as Nav2's does without its server")

    def waited(self, future: Future, then: Callable[[Future], None] | None = None) -> None:
        """In lockstep the step waits for ``future`` (a prompt answer); when it is done, ``then`` and a tick."""
        release = self.step_port.hold_for(future)

        def done(answered: Future) -> None:
            try:
                if then is not None:
                    then(answered)
                self.wake()
            finally:
                release()
        future.add_done_callback(done)

    def action(self, name: str, action_type: Any) -> RosActionPort:
        port = self._actions.get(name)
        if port is None or port.client._action_type is not action_type:  # noqa: SLF001 - rclpy keeps it there
            port = self._actions[name] = RosActionPort(self, name, action_type)
        return port

    def service(self, name: str, service_type: Any) -> RosServicePort:
        port = self._services.get(name)
        if port is None or port.client.srv_type is not service_type:
            port = self._services[name] = RosServicePort(self, name, service_type)
        return port

    def transform(self, target_frame: str, source_frame: str) -> tuple[float, float, float] | None:
        try:
            return self.tf.lookup(target_frame, source_frame)
        except TransformError:
            return None

    def latest(self, topic: str, message_type: Any, *, latched: bool = False) -> Any | None:
        kept = self._topics.get(topic)
        if kept is None:
            kept = self._topics[topic] = [None]
            keep = functools.partial(kept.__setitem__, 0)
            self.node.create_subscription(message_type, topic, guarded(self.node, keep, message_type.__name__),
                                          LATCHED if latched else 10)
        return kept[0]
