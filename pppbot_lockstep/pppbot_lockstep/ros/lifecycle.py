"""Managed (lifecycle) nodes as Nav2 has them: ``nav2_util::LifecycleNode`` in rclpy.

A :class:`ManagedNode` starts *unconfigured*, as every Nav2 server does, and moves through
the states of ``lifecycle_msgs`` when asked on ``~/change_state`` (by a lifecycle manager,
:mod:`pppbot_nav.ros.lifecycle_manager`, or by ``ros2 lifecycle set``):

* **configure** reads what can fail (a map file, a plugin, a frame) and allocates; a failure
  logs one line naming the node and the problem, answers ``success: false`` and leaves the
  node unconfigured (Nav2's ``on_configure`` returning FAILURE);
* **activate** starts publishing and serving: every publisher of a managed node is a
  lifecycle publisher (its messages are dropped while the node is inactive, as rclcpp's
  ``LifecyclePublisher`` drops them), and action servers made with :meth:`ManagedNode.gated`
  goal callbacks accept goals only while active (Nav2's ``SimpleActionServer`` rejects them
  with "Action server is inactive");
* **deactivate**, **cleanup** and **shutdown** undo them in that order.

Subclasses implement :meth:`ManagedNode.configure`, :meth:`ManagedNode.activate`,
:meth:`ManagedNode.deactivate` and :meth:`ManagedNode.cleanup` (each may do nothing). Their
subscriptions, services and timers are made in ``__init__`` (a lockstep participant's process
joins once its data-path subscriptions hear their publishers); their callbacks check
:attr:`ManagedNode.active` where work must wait.

rclpy 7.1 raises out of the executor on a transition that is not valid from the current state
(``activate`` while unconfigured): here the request is refused with ``success: false`` and a
warning, as rclcpp does, and the node lives on.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

from lifecycle_msgs.msg import State
from lifecycle_msgs.srv import ChangeState
from rclpy.action import GoalResponse
from rclpy.lifecycle import LifecycleNode, LifecyclePublisher, LifecycleState, TransitionCallbackReturn
from rclpy.publisher import Publisher

from pppbot_common.errors import PppbotError
from pppbot_common.params import ParameterError
from pppbot_lockstep.ros.node import StepNode
from pppbot_lockstep.ros.port import FREE_RUNNING, StepPort

#: What a configure may fail with: logged by name, the transition fails (other exceptions are
#: errors: the node goes to errorprocessing and back to unconfigured).
CONFIGURE_FAILURES: tuple[type[BaseException], ...] = (PppbotError, ParameterError, OSError, ValueError)

#: rclpy's own transition (private to its LifecycleNodeMixin, name-mangled): the guard calls it
#: once the transition is known to be available.
RCLPY_CHANGE_STATE = "_LifecycleNodeMixin__change_state"


class ManagedPublisher(LifecyclePublisher):
    """A lifecycle publisher (silent while its node is inactive) that sends through its node's step
    port (:class:`~pppbot_lockstep.ros.node.StepPublisher`'s rules)."""

    _step_port: StepPort = FREE_RUNNING
    _step_topic = ""
    _asks_round = True

    def attach(self, port: StepPort, asks_round: bool = True) -> None:
        self._step_port = port
        self._step_topic = self.topic_name
        self._asks_round = asks_round

    def publish(self, msg: Any) -> None:
        if not self.is_activated:
            return
        if not self._step_port.counts:
            Publisher.publish(self, msg)
            return
        self._step_port.publish(self, msg, self._step_topic, asks_round=self._asks_round)


class ManagedNode(StepNode, LifecycleNode):
    """A lifecycle node with Nav2's transitions (see the module's docstring), whose endpoints go
    through its step port (:class:`~pppbot_lockstep.ros.node.StepNode`)."""

    def __init__(self, node_name: str, *, port: StepPort | None = None, **kwargs: Any) -> None:
        self._managed_publishers = False  # the node's own (parameter events) are not managed
        super().__init__(node_name, port=port, **kwargs)
        self._managed_publishers = True
        self._service_change_state.callback = self._on_change_state
        #: Why the last configure failed (empty after a success).
        self.configure_failure = ""

    # ----------------------------------------------------------- for subclasses
    def configure(self) -> None:
        """Read what can fail and allocate. Raise one of :data:`CONFIGURE_FAILURES` to fail."""

    def activate(self) -> None:
        """Start the work (the publishers are enabled already: it may publish)."""

    def deactivate(self) -> None:
        """Stop the work (the publishers are still enabled: it may publish a last time)."""

    def cleanup(self) -> None:
        """Release what configure allocated."""

    # ------------------------------------------------------------------- state
    @property
    def state(self) -> str:
        """The current state's label: ``unconfigured``, ``inactive``, ``active``, ``finalized`` and so on."""
        return str(self._state_machine.current_state[1])

    @property
    def active(self) -> bool:
        return int(self._state_machine.current_state[0]) == State.PRIMARY_STATE_ACTIVE

    def create_publisher(self, *args: Any, aside: bool = False, **kwargs: Any) -> Any:
        """Every publisher of a managed node is a lifecycle publisher: silent while inactive."""
        if not self._managed_publishers:
            return super().create_publisher(*args, **kwargs)
        publisher = self.create_lifecycle_publisher(*args, **kwargs)
        publisher.__class__ = ManagedPublisher  # the same object, sending through the step port
        publisher.attach(self._port(), asks_round=not aside)
        return publisher

    def taking_goals(self, request: Any = None) -> bool:
        """Whether a goal may be accepted now: only while active (else a warning, as Nav2's
        "Action server is inactive. Rejecting the goal.")."""
        if not self.active:
            self.get_logger().warning(f"a goal while {self.state}: action server is inactive, rejecting the goal")
        return self.active

    def gated(self, goal_callback: Callable[[Any], GoalResponse] | None = None) -> Callable[[Any], GoalResponse]:
        """An action server's goal callback that rejects goals while the node is not active (and
        otherwise asks ``goal_callback``, or accepts)."""
        def on_goal(goal: Any) -> GoalResponse:
            if not self.taking_goals(goal):
                return GoalResponse.REJECT
            return goal_callback(goal) if goal_callback is not None else GoalResponse.ACCEPT
        return on_goal

    # ------------------------------------------------------------ transitions
    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        try:
            self.configure()
        except CONFIGURE_FAILURES as exc:
            self.configure_failure = str(exc)
            self.get_logger().error(f"failed to configure: {exc}")
            return TransitionCallbackReturn.FAILURE
        self.configure_failure = ""
        self.get_logger().debug("configured")
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        result = super().on_activate(state)  # enables the lifecycle publishers
        self.activate()
        return result

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.deactivate()
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.cleanup()
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        if state.state_id == State.PRIMARY_STATE_ACTIVE:
            self.deactivate()
            super().on_deactivate(state)
        if state.state_id in (State.PRIMARY_STATE_ACTIVE, State.PRIMARY_STATE_INACTIVE):
            self.cleanup()
        return TransitionCallbackReturn.SUCCESS

    def on_error(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.get_logger().error(f"a transition from '{state.label}' raised: back to unconfigured")
        return TransitionCallbackReturn.SUCCESS

    def _on_change_state(self, request: ChangeState.Request, response: ChangeState.Response) -> ChangeState.Response:
        """``~/change_state``: rclpy's, but a transition not valid from the current state is refused."""
        transition_id = request.transition.id
        if request.transition.label:
            try:
                transition_id = self._state_machine.get_transition_by_label(request.transition.label)
            except Exception:  # an unknown label (rclpy's RCLError)
                transition_id = -1
        available = {int(t[0]): str(t[1]) for t in self._state_machine.available_transitions}
        if transition_id not in available:
            name = request.transition.label or str(request.transition.id)
            self.get_logger().warning(f"transition '{name}' is not available from '{self.state}'; "
                                      f"available: {', '.join(available.values())}")
            response.success = False
            return response
        change_state: Callable[[int], TransitionCallbackReturn] = getattr(self, RCLPY_CHANGE_STATE)
        result = change_state(transition_id)
        response.success = result == TransitionCallbackReturn.SUCCESS
        return response
