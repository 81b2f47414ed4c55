"""The lifecycle managers: Nav2's commands over real lifecycle nodes, composed in one process as
launch_sim composes them, and the plans they follow."""
from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest
import rclpy
from nav2_msgs.srv import ManageLifecycleNodes
from rclpy.parameter import Parameter
from std_srvs.srv import Trigger

from pppbot_common.errors import PppbotError
from pppbot_common.params import ParameterError
from pppbot_common.ros.retry import Retry
from pppbot_common.ros.wait import wait_until
from pppbot_lockstep.ros.lifecycle import ManagedNode
from pppbot_nav.errors import LifecycleError
from pppbot_nav.lifecycle import (
    NAVIGATION_NODES,
    VELOCITY_CHAIN,
    Command,
    Step,
    Transition,
    command_of,
    command_remaps,
    navigation_nodes,
    plan,
    validate_node_names,
)
from pppbot_nav.ros.lifecycle_manager import LifecycleManager

NODES = ["map_server", "amcl", "planner_server"]


# ---------------------------------------------------------------- the plans
def test_startup_configures_all_then_activates_all_in_order():
    assert plan(Command.STARTUP, NODES) == [Step(n, Transition.CONFIGURE) for n in NODES] + \
        [Step(n, Transition.ACTIVATE) for n in NODES]


def test_everything_but_configure_and_activate_goes_in_reverse():
    back = NODES[::-1]
    assert plan(Command.PAUSE, NODES) == [Step(n, Transition.DEACTIVATE) for n in back]
    assert plan(Command.RESUME, NODES) == [Step(n, Transition.ACTIVATE) for n in NODES]
    assert plan(Command.RESET, NODES) == [Step(n, Transition.DEACTIVATE) for n in back] + \
        [Step(n, Transition.CLEANUP) for n in back]
    assert plan(Command.SHUTDOWN, NODES)[-3:] == [Step(n, Transition.UNCONFIGURED_SHUTDOWN) for n in back]
    assert plan(Command.CLEANUP, NODES) == [Step(n, Transition.CLEANUP) for n in back]


def test_bad_commands_and_node_names_name_what_is_allowed():
    with pytest.raises(LifecycleError, match="unknown lifecycle command 9: one of STARTUP=0, .*CLEANUP=6"):
        command_of(9)
    with pytest.raises(LifecycleError, match="names amcl twice"):
        validate_node_names(["amcl", "map_server", "amcl"])
    with pytest.raises(LifecycleError, match="node_names is empty"):
        validate_node_names([])


def test_only_the_velocity_chain_may_be_left_out_of_the_navigation_nodes():
    assert navigation_nodes() == NAVIGATION_NODES
    assert navigation_nodes(["collision_monitor"]) == tuple(n for n in NAVIGATION_NODES if n != "collision_monitor")
    assert command_remaps() == {"controller_server:cmd_vel": "cmd_vel_nav", "behavior_server:cmd_vel": "cmd_vel_nav",
                                "velocity_smoother:cmd_vel": "cmd_vel_nav"}
    assert command_remaps(VELOCITY_CHAIN) == {}
    with pytest.raises(LifecycleError, match="cannot leave out bt_navigator: only velocity_smoother and "
                                             "collision_monitor may be"):
        navigation_nodes(["bt_navigator"])


# ------------------------------------------------------------ over DDS
class Server(ManagedNode):
    """A managed node that records its transitions; configure fails while ``broken``."""

    def __init__(self, name: str, log: list[str]) -> None:
        super().__init__(name)
        self.log = log
        self.broken = False

    def configure(self) -> None:
        if self.broken:
            raise PppbotError("plugin 'GridBased' not found")
        self.log.append(f"configure {self.get_name()}")

    def activate(self) -> None:
        self.log.append(f"activate {self.get_name()}")

    def deactivate(self) -> None:
        self.log.append(f"deactivate {self.get_name()}")

    def cleanup(self) -> None:
        self.log.append(f"cleanup {self.get_name()}")


@pytest.fixture
def process(spin_in_background: Callable[..., Any]) -> Iterator[tuple[dict[str, Server], list[str], Any]]:
    """Three managed nodes spun by one executor, as run_nodes composes them; managers are made by the test."""
    log: list[str] = []
    servers = {name: Server(name, log) for name in NODES}
    spin_in_background(*servers.values())
    managers: list[LifecycleManager] = []

    def manager(**parameters: Any) -> LifecycleManager:
        overrides = [Parameter(k, value=v) for k, v in parameters.items()]
        managers.append(LifecycleManager("lifecycle_manager_test", NODES, parameter_overrides=overrides))
        return managers[-1]
    try:
        yield servers, log, manager
    finally:
        for m in managers:
            m.destroy_node()


def call(node: Any, srv_type: Any, name: str, request: Any) -> Any:
    client = node.create_client(srv_type, name)
    assert client.wait_for_service(timeout_sec=10)
    future = client.call_async(request)
    return wait_until(lambda: future.result() if future.done() else None, 60, name, node=node)


def manage(node: Any, command: Command) -> bool:
    return bool(call(node, ManageLifecycleNodes, "/lifecycle_manager_test/manage_nodes",
                     ManageLifecycleNodes.Request(command=int(command))).success)


def is_active(node: Any) -> bool:
    return bool(call(node, Trigger, "/lifecycle_manager_test/is_active", Trigger.Request()).success)


@pytest.mark.ros
def test_autostart_brings_the_nodes_up_in_order_and_commands_take_them_down_in_reverse(ros_node, process):
    servers, log, manager = process
    manager(autostart=True)
    wait_until(lambda: all(s.active for s in servers.values()), 30, "the nodes active", node=ros_node)
    assert log == [f"configure {n}" for n in NODES] + [f"activate {n}" for n in NODES]
    assert is_active(ros_node)
    log.clear()
    assert manage(ros_node, Command.PAUSE) and not is_active(ros_node)
    assert {s.state for s in servers.values()} == {"inactive"}
    assert manage(ros_node, Command.RESUME) and is_active(ros_node)
    assert manage(ros_node, Command.RESET)
    assert log == [f"deactivate {n}" for n in NODES[::-1]] + [f"activate {n}" for n in NODES] + \
        [f"deactivate {n}" for n in NODES[::-1]] + [f"cleanup {n}" for n in NODES[::-1]]
    assert manage(ros_node, Command.STARTUP) and is_active(ros_node)
    assert manage(ros_node, Command.SHUTDOWN) and {s.state for s in servers.values()} == {"finalized"}


@pytest.mark.ros
def test_a_node_that_fails_to_configure_stops_the_startup_with_its_name(ros_node, process):
    servers, log, manager = process
    servers["amcl"].broken = True
    m = manager()
    assert not manage(ros_node, Command.STARTUP)
    assert log == ["configure map_server"]  # planner_server never asked, nobody activated
    assert servers["map_server"].state == "inactive" and servers["amcl"].state == "unconfigured"
    assert servers["amcl"].configure_failure == "plugin 'GridBased' not found"
    assert not is_active(ros_node) and m.state == "unknown"
    servers["amcl"].broken = False
    assert manage(ros_node, Command.STARTUP) and is_active(ros_node)  # map_server is not configured twice
    assert log.count("configure map_server") == 1


def lose_first_answer(service: Any) -> list[Any]:
    """``service`` drops its first answer, as Fast DDS drops one to a client whose reader the server
    has not discovered yet; the list fills with the headers of the answers dropped."""
    send = service.send_response
    lost: list[Any] = []

    def send_response(response: Any, header: Any) -> None:
        if not lost:
            lost.append(header)
            return
        send(response, header)
    service.send_response = send_response
    return lost


@pytest.mark.ros
def test_lost_answers_are_asked_again_and_the_state_decides(ros_node, process):
    servers, log, manager = process
    amcl = servers["amcl"]
    lost = [lose_first_answer(amcl._service_get_state), lose_first_answer(amcl._service_change_state)]
    manager(autostart=True)
    wait_until(lambda: all(s.active for s in servers.values()), 60, "the nodes active", node=ros_node)
    assert all(len(headers) == 1 for headers in lost)  # both first answers were dropped
    # configure's answer was lost: amcl, configured by the first request, showed inactive; the
    # manager took that (it did not ask again) and went on
    assert log == [f"configure {n}" for n in NODES] + [f"activate {n}" for n in NODES]
    assert is_active(ros_node)


def test_a_manager_on_sim_time_does_not_follow_the_clock(ros_node, process):
    """Nav2's params files give every node use_sim_time: true; the manager never reads its clock, so
    it takes no /clock (100 messages a sim second, in an executor of its own, for nothing)."""
    _, _, manager = process
    m = manager(use_sim_time=True)
    assert "/clock" not in [s.topic_name for s in m.subscriptions]
    assert "/clock" not in [s.topic_name for s in m._calls.subscriptions]


@pytest.mark.ros
def test_a_manager_in_a_process_on_sim_time_takes_no_clock():
    """A launch gives the whole process use_sim_time (its arguments apply to every node, the
    manager's service client too): neither of the manager's nodes takes /clock."""
    context = rclpy.Context()
    rclpy.init(args=["--ros-args", "-p", "use_sim_time:=true"], context=context)
    try:
        m = LifecycleManager("lifecycle_manager_test", NODES, context=context)
        try:
            assert "/clock" not in [s.topic_name for s in m.subscriptions]
            assert "/clock" not in [s.topic_name for s in m._calls.subscriptions]
        finally:
            m.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


class SlowFailure(ManagedNode):
    """A managed node whose configure works for ``configure_s`` (wall), then fails."""

    def __init__(self, name: str, configure_s: float) -> None:
        super().__init__(name)
        self.configure_s = configure_s
        self.configures = 0

    def configure(self) -> None:
        self.configures += 1
        time.sleep(self.configure_s)  # the work itself (a plugin loading), longer than an attempt
        raise PppbotError("plugin 'GridBased' not found")


@pytest.mark.ros
def test_a_slow_configure_that_fails_is_asked_once_and_the_failure_names_the_node(ros_node, spin_in_background):
    attempt_s = 0.5
    slow = SlowFailure("slow_server", configure_s=4 * attempt_s)
    spin_in_background(slow)
    manager = LifecycleManager("lifecycle_manager_test", ["slow_server"], retry=Retry(attempt_s, attempts=10))
    try:
        assert not manage(ros_node, Command.STARTUP)
        assert slow.configures == 1  # never asked again while configuring, nor after it failed
        assert slow.state == "unconfigured" and slow.configure_failure == "plugin 'GridBased' not found"
        assert manager.last_error == "Failed to change state for node: slow_server (configure left it unconfigured)"
        assert not is_active(ros_node)
    finally:
        manager.destroy_node()


@pytest.mark.ros
def test_node_names_must_be_names(ros_node):
    with pytest.raises(ParameterError, match="node_names"):
        LifecycleManager("lifecycle_manager_bad", parameter_overrides=[Parameter("node_names", value=["a", "a"])])
