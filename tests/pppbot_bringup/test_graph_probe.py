"""Readiness from the ROS graph: a node's endpoints as another process's graph sees them."""
from __future__ import annotations

import time

import pytest

pytestmark = pytest.mark.ros


def wait_for(probe, timeout_s: float = 20.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if probe():
            return True
        time.sleep(0.05)
    return False


def test_a_node_is_ready_once_it_has_every_endpoint_asked_for(ros_node):
    from nav2_msgs.action import NavigateToPose
    from rclpy.action import ActionServer
    from std_msgs.msg import String

    from pppbot_bringup.ros.graph_probe import GraphProbe

    probe = GraphProbe()
    try:
        name = ros_node.get_name()
        complete = probe.endpoints(name, publishes=("/probe_out",), subscribes=("/probe_in",),
                                   action_servers=("/probe_action",))
        missing = probe.endpoints(name, publishes=("/probe_out",), subscribes=("/never_subscribed",))
        stranger = probe.endpoints("no_such_node", publishes=("/probe_out",))
        assert not complete() and not stranger()  # nothing yet: the node has no endpoints
        ros_node.create_publisher(String, "probe_out", 1)
        ros_node.create_subscription(String, "probe_in", lambda _m: None, 1)
        assert not wait_for(complete, 2.0)  # the action server is still missing
        server = ActionServer(ros_node, NavigateToPose, "probe_action", execute_callback=lambda _h: None)
        assert wait_for(complete)
        assert not missing() and not stranger()
        probe.close()
        assert complete() and not missing()  # what it saw stays after close
        server.destroy()
    finally:
        probe.close()
