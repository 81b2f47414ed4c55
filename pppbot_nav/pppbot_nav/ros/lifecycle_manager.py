"""``lifecycle_manager``: brings Nav2's lifecycle nodes up and down, as nav2_lifecycle_manager does.

Parameters, as Nav2's: ``node_names`` (the managed nodes, in start order) and ``autostart``
(STARTUP as soon as the manager runs). Services, as Nav2's:

* ``~/manage_nodes`` (nav2_msgs/srv/ManageLifecycleNodes): STARTUP, PAUSE, RESUME, RESET,
  SHUTDOWN, CONFIGURE, CLEANUP (:mod:`pppbot_nav.lifecycle` says what each does); each
  transition is asked on ``<node>/change_state`` and checked on ``<node>/get_state``;
  a node that fails stops the command, naming it (SHUTDOWN goes on);
* ``~/is_active`` (std_srvs/srv/Trigger): whether the managed nodes are active.

``BasicNavigator.lifecycleStartup()`` finds the managers by that service type, and
``waitUntilNav2Active()`` asks the nodes' ``get_state``, so Nav2's scripts see the same.
Nav2's manager also holds a *bond* with each node (a heartbeat topic) and resets them all
when one stops answering; pppbot's does not: its nodes run in processes a launch supervises,
which stops the whole stack when a required one dies.

The manager answers its services from a thread of its own and calls the nodes from another
private node, so it can manage nodes composed into its own process (whose services the
process's executor answers meanwhile), as Nav2's does with its service thread.
"""
from __future__ import annotations

import sys
import threading
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

from nav2_msgs.srv import ManageLifecycleNodes
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_srvs.srv import Trigger

from pppbot_common.errors import TimeoutExpired
from pppbot_common.params import ParameterError, param
from pppbot_common.ros.nodes import unspun_node
from pppbot_common.ros.params import declare_parameters
from pppbot_common.ros.retry import LifecycleCalls, Retry, executor_wait
from pppbot_lockstep.ros.node import answering
from pppbot_nav.errors import LifecycleError
from pppbot_nav.lifecycle import (
    ABORTED,
    RESULTING_STATE,
    Command,
    Step,
    already_there,
    command_of,
    goes_on_after_failure,
    plan,
    validate_node_names,
)

#: How long a node's lifecycle services may take to appear (a process still importing on a busy
#: machine), and to answer (s, wall).
SERVICE_WAIT_S = 60.0
CALL_TIMEOUT_S = 30.0
#: A request still unanswered after this long (s, wall) is sent again if it was lost
#: (:mod:`pppbot_common.ros.retry`: Fast DDS drops a service's answer to a client whose reply
#: reader the server has not discovered yet, most often on a busy machine with a node just
#: started); a change_state only while the node's state has not moved, never during a transition.
RESEND_S = 3.0
RETRY = Retry(RESEND_S, attempts=int(CALL_TIMEOUT_S // RESEND_S), deadline_s=CALL_TIMEOUT_S)


@dataclass(frozen=True)
class LifecycleManagerParameters:
    node_names: list = param([""], "the lifecycle nodes to manage, in start order (unset: the process's own)")
    autostart: bool = param(False, "bring the nodes up (STARTUP) as soon as the manager runs")

    def validate(self) -> None:
        if list(self.node_names) == [""]:
            return  # unset
        try:
            validate_node_names([str(n) for n in self.node_names])
        except LifecycleError as exc:
            raise ParameterError("node_names", self.node_names, str(exc)) from exc


class LifecycleManager(Node):
    """A lifecycle manager named ``name``; ``node_names`` is the parameter's default."""

    #: run_nodes leaves this node out of the process's executor: it spins itself.
    spins_itself = True

    def __init__(self, name: str = "lifecycle_manager", node_names: Sequence[str] = (), autostart: bool = False,
                 port: Any = None, retry: Retry = RETRY, **kwargs: Any) -> None:
        """``node_names`` and ``autostart``: the defaults of the parameters (a bringup's), which a
        parameters file overrides. ``port``: the process's step port. A lifecycle manager is a plain
        rclpy node that spins itself (its services answer at once, in lockstep too); with
        ``autostart`` in a lockstep process (the composed navigation, and localization) the process
        joins only once the nodes are active, so sim time starts with them serving, on every run.
        ``retry``: how long each request to a node is waited for and how often sent again."""
        super().__init__(name, **kwargs)
        # Its clock is never read (its timeouts are wall time): following /clock at 100 Hz in its own
        # Python executor took a third of the navigation process's CPU while the robot stood still.
        self.set_parameters([Parameter("use_sim_time", value=False)])
        given = set(self._parameter_overrides)  # from the command line and parameters files
        self.params = p = declare_parameters(self, LifecycleManagerParameters)
        if "autostart" not in given and autostart:
            self.set_parameters([Parameter("autostart", value=True)])
            self.params = p = replace(p, autostart=True)
        self.node_names = [str(n) for n in p.node_names] if list(p.node_names) != [""] else list(node_names)
        if not self.node_names:
            raise ParameterError("node_names", p.node_names, "must name the lifecycle nodes to manage, in start order")
        self.set_parameters([Parameter("node_names", value=self.node_names)])
        self.state = "unconfigured"
        #: the last command's failure, as logged (empty after a success)
        self.last_error = ""
        # Nor is its service client's: on sim time it took every /clock message (in DDS, unspun).
        self._calls = unspun_node(f"{name}_service_client", context=self.context, enable_rosout=False,
                                  parameter_overrides=[Parameter("use_sim_time", value=False)])
        self._calls_executor = SingleThreadedExecutor(context=self.context)
        self._calls_executor.add_node(self._calls)
        wait = executor_wait(self._calls_executor)
        self._lifecycle = {n: LifecycleCalls(self._calls, n, retry, wait) for n in self.node_names}
        self._lock = threading.Lock()  # one command at a time
        self.create_service(ManageLifecycleNodes, "~/manage_nodes", answering(self, "~/manage_nodes", self._on_manage))
        self.create_service(Trigger, "~/is_active", answering(self, "~/is_active", self._on_is_active))
        self._executor = SingleThreadedExecutor(context=self.context)
        self._executor.add_node(self)
        self._stop = threading.Event()
        if p.autostart and port is not None:
            port.require_when(f"{name}: the managed nodes active", lambda: self.state == "active")
        self._thread = threading.Thread(target=self._spin, name=name, daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        if self.params.autostart:
            self.get_logger().info(f"starting the managed nodes: {', '.join(self.node_names)}")
            self.run(Command.STARTUP)
        while not self._stop.is_set() and self.context.ok():
            try:
                self._executor.spin_once(timeout_sec=0.1)
            except Exception:  # the context went down under it: the process is ending
                if self.context.ok() and not self._stop.is_set():
                    raise
                return

    # ---------------------------------------------------------------- commands
    def run(self, command: Command) -> bool:
        """Carry out ``command`` over the managed nodes; whether every node did as asked (if not,
        :attr:`last_error` says which failed and why)."""
        with self._lock:
            ok = True
            self.last_error = ""
            for step in plan(command, self.node_names):
                if not self._change(step):
                    ok = False
                    if not goes_on_after_failure(command):
                        self.get_logger().error(ABORTED[command])
                        self.state = "unknown"
                        return False
            self.state = RESULTING_STATE[command]
            if ok and command == Command.STARTUP:
                self.get_logger().info("Managed nodes are active")
            return ok

    def _change(self, step: Step) -> bool:
        calls = self._lifecycle[step.node]
        try:
            before = self._state_of(calls)
        except TimeoutExpired as exc:
            return self._failed(step, str(exc))
        if already_there(before[1], step):
            return True
        self.get_logger().info(f"{step.transition.name.capitalize().replace('_', ' ')} {step.node}")
        why = ""
        try:
            calls.change_state(int(step.transition), before[0])  # None: its answer was lost
        except TimeoutExpired as exc:
            why = str(exc)
        # The state decides (a transition that failed, or whose answer was lost, shows there).
        try:
            after = self._state_of(calls)[1]
        except TimeoutExpired as exc:
            return self._failed(step, why or str(exc))
        if after != step.goal_label:
            return self._failed(step, why or f"{step.transition.name.lower()} left it {after}")
        return True

    def _state_of(self, calls: LifecycleCalls) -> tuple[int, str]:
        """The node's state (id, label).

        Raises:
            TimeoutExpired: its get_state service did not appear, or did not answer.
        """
        for client in (calls.get_client, calls.change_client):
            if not client.wait_for_service(timeout_sec=SERVICE_WAIT_S):
                raise TimeoutExpired(f"its service {client.srv_name} did not appear within {SERVICE_WAIT_S:g} s")
        return calls.state()

    def _failed(self, step: Step, why: str) -> bool:
        self.last_error = f"Failed to change state for node: {step.node} ({why})"
        self.get_logger().error(self.last_error)
        return False

    # ---------------------------------------------------------------- services
    def _on_manage(self, request: ManageLifecycleNodes.Request,
                   response: ManageLifecycleNodes.Response) -> ManageLifecycleNodes.Response:
        try:
            command = command_of(request.command)
        except LifecycleError as exc:
            self.get_logger().error(f"~/manage_nodes: {exc}")
            response.success = False
            return response
        response.success = self.run(command)
        return response

    def _on_is_active(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        response.success = self.state == "active"
        return response

    def destroy_node(self) -> None:
        self._stop.set()
        if threading.current_thread() is not self._thread:
            self._thread.join(timeout=2.0)
        self._executor.shutdown(timeout_sec=1.0)
        self._calls_executor.shutdown(timeout_sec=1.0)
        for calls in self._lifecycle.values():
            calls.destroy()
        self._calls.destroy_node()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    from pppbot_lockstep.ros.runner import run_nodes

    return run_nodes([LifecycleManager], "lifecycle_manager", args, fatal=(ParameterError,), lockstep=False)


if __name__ == "__main__":
    sys.exit(main())
