"""A service of pppbot's answers every request, even one its callback fails on: the caller gets
the response as it stood (its failure fields false), the node logs the failure once per kind and
serves on."""
from __future__ import annotations

from typing import Any

import pytest
from rclpy.executors import SingleThreadedExecutor
from std_srvs.srv import SetBool

from pppbot_lockstep.ros.node import StepNode

pytestmark = pytest.mark.ros


def test_a_request_the_callback_fails_on_is_answered_and_the_node_serves_on(ros_node: Any) -> None:
    node = StepNode("answering_test_node", context=ros_node.context)
    logged: list[str] = []
    node.get_logger().error = lambda text, **_: logged.append(text)

    def set_bool(request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        if not request.data:
            raise ValueError("false is not taken")
        response.success, response.message = True, "taken"
        return response

    node.create_service(SetBool, "answering_test", set_bool)
    client = ros_node.create_client(SetBool, "answering_test")
    executor = SingleThreadedExecutor(context=ros_node.context)
    executor.add_node(node)
    executor.add_node(ros_node)
    try:
        assert client.wait_for_service(timeout_sec=10)
        answers = []
        for data in (False, False, True):
            future = client.call_async(SetBool.Request(data=data))
            executor.spin_until_future_complete(future, timeout_sec=10)
            assert future.done()
            answers.append((future.result().success, future.result().message))
        assert answers == [(False, ""), (False, ""), (True, "taken")]
        # Named once for the two failures of one kind within its throttle period.
        assert logged == ["answering_test: could not handle a request (ValueError: false is not taken); "
                          "answered with an empty response"]
    finally:
        executor.remove_node(ros_node)
        executor.shutdown()
        node.destroy_node()

