"""run_node: how a node's main() ends."""
from __future__ import annotations

import functools
import signal
import subprocess
import sys
import threading
from collections.abc import Sequence

import pytest
import rclpy
from rclpy.node import Node

from pppbot_common.errors import PppbotError
from pppbot_common.process import block_stop_signals
from pppbot_lockstep.ros.runner import Warnings, run_node

pytestmark = pytest.mark.ros


def test_an_error_while_the_context_goes_down_is_a_clean_end():
    """SIGINT: Python sees it inside a binding call (which then fails) a moment before
    rclpy's signal thread shuts the context down. That is still exit 0."""
    def spin(node: Node) -> None:
        threading.Timer(0.3, rclpy.try_shutdown).start()
        raise RuntimeError("Unable to convert call argument '0' to Python object")

    assert run_node(lambda: Node("ends_on_sigint"), "ends_on_sigint", [], spin=spin, signal_handlers=False) == 0


def test_a_real_error_is_raised():
    def spin(node: Node) -> None:
        raise ValueError("a bug")

    with pytest.raises(ValueError, match="a bug"):
        run_node(lambda: Node("has_a_bug"), "has_a_bug", [], spin=spin, signal_handlers=False)
    assert not rclpy.ok()


def test_a_fatal_error_at_start_is_one_line_and_exit_1(capsys):
    def factory(port: object = None) -> Node:
        raise PppbotError("parameter 'x' = -1: must be positive")

    assert run_node(factory, "bad_start", [], signal_handlers=False) == 1
    assert capsys.readouterr().err == "[bad_start] error: parameter 'x' = -1: must be positive\n"


def test_without_lockstep_the_parameter_node_goes_only_once_the_nodes_exist():
    """The node that reads the lockstep parameters is the process's first: destroyed before the
    process's own nodes exist, it would take the process's DDS participant with it (and a new one
    would be made), and a participant destroyed during discovery can hang Fast DDS for good."""
    seen: list[list[str]] = []

    def factory(port: object = None) -> Node:
        node = Node("made_after_the_probe")
        seen.append(node.get_node_names())
        return node

    def loop(nodes: Sequence[Node], process: object) -> int:
        seen.append(nodes[0].get_node_names())
        return 0

    from pppbot_lockstep.ros.runner import run_nodes

    assert run_nodes([factory], "probe_kept", [], loop=loop) == 0
    assert "_lockstep_probe_kept" in seen[0]  # the process's participant was never let go
    assert "_lockstep_probe_kept" not in seen[1]  # and the probe is gone once the nodes exist


_STARTING_NODE = """
import sys, time
print("importing", flush=True)
time.sleep(1.0)  # a node's imports: the launch may stop it meanwhile
from pppbot_lockstep.ros.runner import take_stop_signals
stop = take_stop_signals()
sys.exit(0 if stop.is_set() else 3)
"""


@pytest.mark.parametrize("blocked, expected", [(True, 0), (False, -signal.SIGINT)])
def test_a_stop_while_a_node_imports_is_taken_by_its_runner_when_the_launch_blocks_it(blocked, expected):
    """A launch starts pppbot's nodes with the stop signals blocked: a SIGINT during the imports
    waits for the runner, which then ends cleanly (without it, Python dies of the signal)."""
    proc = subprocess.Popen([sys.executable, "-c", _STARTING_NODE], stdout=subprocess.PIPE, text=True,
                            preexec_fn=block_stop_signals if blocked else None)
    assert proc.stdout is not None and proc.stdout.readline().strip() == "importing"
    proc.send_signal(signal.SIGINT)
    assert proc.wait(30) == expected


def test_composed_nodes_share_one_clock_subscription_and_all_follow_clock():
    """share_clock: of the nodes on sim time, only the first keeps its /clock subscription; every
    node's clock still follows /clock."""
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from rosgraph_msgs.msg import Clock

    from pppbot_common.ros.wait import wait_until
    from pppbot_lockstep.ros.runner import share_clock

    rclpy.init()
    try:
        sim_time = [Parameter("use_sim_time", value=True)]
        nodes = [Node(f"composed_{i}", parameter_overrides=sim_time) for i in range(3)]
        wall = Node("on_wall_time")
        share_clock([*nodes, wall])
        clock_subscribers = [n for n in nodes if any(s.topic_name == "/clock" for s in n.subscriptions)]
        assert clock_subscribers == [nodes[0]]
        publisher = wall.create_publisher(Clock, "/clock", 10)
        executor = SingleThreadedExecutor()
        for node in (*nodes, wall):
            executor.add_node(node)
        msg = Clock()
        msg.clock.sec = 42

        def all_at_42() -> bool:
            publisher.publish(msg)
            executor.spin_once(timeout_sec=0.05)
            return all(n.get_clock().now().nanoseconds == 42 * 10**9 for n in nodes)

        assert wait_until(all_at_42, 10.0, "every composed clock at 42 s")
        assert wall.get_clock().now().nanoseconds > 10**18  # the wall-time node is left alone
        executor.shutdown()
        for node in (*nodes, wall):
            node.destroy_node()
    finally:
        rclpy.try_shutdown()


def test_composed_nodes_share_one_tf_listener_and_each_hears_of_new_transforms():  # noqa: PLR0915
    """TfListener: the nodes of one process share one buffer and one /tf subscription; each
    node's callback runs after a transform arrives; a node made after /tf_static arrived is
    told at once; after the first nodes are destroyed a new one listens again."""
    from geometry_msgs.msg import TransformStamped
    from rclpy.executors import SingleThreadedExecutor
    from tf2_msgs.msg import TFMessage

    from pppbot_common.ros.qos import LATCHED
    from pppbot_common.ros.wait import wait_until
    from pppbot_lockstep.ros.runner import Warnings
    from pppbot_lockstep.ros.tf_listener import _SHARED, TfListener

    def transform(parent: str, child: str, x: float, sec: int = 0) -> TFMessage:
        t = TransformStamped()
        t.header.frame_id, t.child_frame_id = parent, child
        t.header.stamp.sec = sec
        t.transform.translation.x, t.transform.rotation.w = x, 1.0
        return TFMessage(transforms=[t])

    rclpy.init()
    try:
        source = Node("tf_source")
        static_pub = source.create_publisher(TFMessage, "/tf_static", LATCHED)
        dynamic_pub = source.create_publisher(TFMessage, "/tf", 10)
        heard = {0: 0, 1: 0}

        def hear(i: int) -> None:
            heard[i] += 1

        nodes = [Node(f"listening_{i}") for i in range(2)]
        listeners = [TfListener(n, Warnings(n), on_tf=functools.partial(hear, i)) for i, n in enumerate(nodes)]
        assert listeners[0].buffer is listeners[1].buffer
        tf_subscribers = [n for n in nodes if any(s.topic_name == "/tf" for s in n.subscriptions)]
        assert tf_subscribers == [nodes[0]]
        executor = SingleThreadedExecutor()
        for node in (source, *nodes):
            executor.add_node(node)
        static_pub.publish(transform("base_link", "laser", 0.1))

        def spin_until(condition, what: str) -> None:
            def step() -> bool:
                executor.spin_once(timeout_sec=0.05)
                return condition()
            assert wait_until(step, 10.0, what)

        def has_static() -> bool:
            try:
                listeners[0].buffer.lookup("base_link", "laser")
            except Exception:
                return False
            return True
        spin_until(has_static, "the static transform")
        late = Node("listening_late")
        told: list[bool] = []
        _SHARED[late.context].add(late, None, lambda: told.append(True))  # what needs_static registers
        assert told == [True]  # /tf_static had arrived: the late node is not left waiting

        def both_heard() -> bool:
            dynamic_pub.publish(transform("odom", "base_link", 1.0, sec=1))
            return heard[0] > 0 and heard[1] > 0
        spin_until(both_heard, "both nodes told of /tf")
        assert listeners[1].buffer.lookup("odom", "laser", 1.0)[0] == pytest.approx(1.1)
        with pytest.raises(ValueError, match="cache_s"):  # a later listener's cache is checked too
            TfListener(late, Warnings(late), cache_s=float("nan"))
        # A composed node destroyed before the owner is no longer told; the owner's node still is.
        executor.remove_node(nodes[1])
        nodes[1].destroy_node()
        before = dict(heard)

        def owner_heard_again() -> bool:
            dynamic_pub.publish(transform("odom", "base_link", 2.0, sec=2))
            return heard[0] > before[0]
        spin_until(owner_heard_again, "the owner's node told of /tf after the other was destroyed")
        assert heard[1] == before[1]
        assert [node for node, _ in _SHARED[late.context]._on_tf] == [nodes[0]]
        executor.shutdown()
        for node in (nodes[0], late):
            node.destroy_node()
        again = Node("listening_again")
        assert TfListener(again, Warnings(again)).buffer is not listeners[0].buffer  # a new owner, a new buffer
        assert any(s.topic_name == "/tf" for s in again.subscriptions)
        assert _SHARED[again.context].owner is again
        again.destroy_node()
        source.destroy_node()
    finally:
        rclpy.try_shutdown()


def test_warnings_that_are_normal_while_a_stack_comes_up_are_debug_until_settled() -> None:
    class Log:
        def __init__(self) -> None:
            self.lines: list[tuple[str, str]] = []

        def debug(self, text: str) -> None:
            self.lines.append(("debug", text))

        def warning(self, text: str) -> None:
            self.lines.append(("warning", text))

    log = Log()
    node = type("FakeNode", (), {"get_logger": lambda self: log})()
    warn = Warnings(node, 0.0, settling=("transform",))
    warn("transform", "no transform yet")
    warn("scan", "a malformed scan")  # not a settling kind: a warning at once
    warn.settled("transform")
    warn("transform", "no transform any more")
    late = Warnings(node, 0.0, settling=("transform",))
    late.quiet_until = 0.0  # the node started long ago: a frame that never came is a warning
    late("transform", "still no transform")
    assert log.lines == [("debug", "no transform yet"), ("warning", "a malformed scan"),
                         ("warning", "no transform any more"), ("warning", "still no transform")]


@pytest.mark.parametrize("text, message", [
    ("map_server:\n  ros__parameters:\n    yaml_filename: [unclosed\n    x: 1\n",
     "line 4, column 6: not valid YAML"),
    ("map_server:\n  yaml_filename: maze\n", "line 2, column 18: key 'map_server/yaml_filename' must hold"),
])
def test_a_node_given_a_bad_params_file_says_so_in_one_line_and_exits_1(tmp_path, text, message):
    params = tmp_path / "params.yaml"
    params.write_text(text)
    done = subprocess.run([sys.executable, "-m", "pppbot_nav.ros.map_server", "--ros-args", "--params-file",
                           str(params)], capture_output=True, text=True, timeout=30, check=False)
    assert done.returncode == 1
    lines = done.stderr.splitlines()
    assert len(lines) == 1, done.stderr
    assert lines[0].startswith(f"[map_server] error: {params}: {message}")


def test_a_command_line_rcl_refuses_is_one_line_and_exit_1():
    done = subprocess.run([sys.executable, "-m", "pppbot_nav.ros.map_server", "--ros-args", "--no-such-flag"],
                          capture_output=True, text=True, timeout=30, check=False)
    assert done.returncode == 1
    assert done.stderr == "[map_server] error: unknown ROS argument(s) after --ros-args: ['--no-such-flag']\n"


def test_a_shared_tf_subscription_is_quiet_while_every_nodes_reaction_to_it_is():
    """TfListener(quiet=True): the process's /tf subscription asks no round of its own while each
    listening node's on_tf only files what its timers read (or it has none); one node whose on_tf
    sends makes it loud."""
    from pppbot_lockstep.protocol import Deliveries
    from pppbot_lockstep.ros.node import StepNode
    from pppbot_lockstep.ros.port import StepPort
    from pppbot_lockstep.ros.runner import Warnings
    from pppbot_lockstep.ros.tf_listener import TfListener

    class Recording(StepPort):
        def __init__(self) -> None:
            self.deliveries = Deliveries()

        def counted(self, node, topic, callback, quiet=False):
            self.deliveries.add(topic, quiet=quiet)
            return callback

    port = Recording()
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        nodes = [StepNode(name, port=port, context=context) for name in ("controller", "planner", "navigator", "slam")]
        TfListener(nodes[0], Warnings(nodes[0]), on_tf=lambda: None, quiet=True)
        TfListener(nodes[1], Warnings(nodes[1]), on_tf=lambda: None, quiet=True)
        TfListener(nodes[2], Warnings(nodes[2]))  # reads the buffer in its timers
        assert port.deliveries.topics() == ["/tf"] and port.deliveries.quiet_topics() == ["/tf"]
        TfListener(nodes[3], Warnings(nodes[3]), on_tf=lambda: None)  # it sends when a transform comes
        assert port.deliveries.topics() == ["/tf"] and port.deliveries.quiet_topics() == []
        for node in reversed(nodes):
            node.destroy_node()
    finally:
        rclpy.shutdown(context=context)
