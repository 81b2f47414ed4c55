"""rclpy's ActionClient, for pppbot's nodes: its requests go through the node's step port, and it is
safe to send from threads other than the executor's.

Requests (a goal, a cancel, a result request) go through the node's step port
(:mod:`pppbot_lockstep.ros.port`): counted on the server's key and, in lockstep, held until the
next step. rclpy's client sends a cancel and a result request from ``_cancel_goal_async`` and
``_get_result_async`` (a goal handle's ``cancel_goal_async`` and ``get_result_async`` call them):
they are overridden here, in this subclass only (tests/pppbot_lockstep/test_seam.py checks that
rclpy still has them).

In rclpy (Jazzy) ``send_goal_async``, and the cancel and result requests, send the request
first and only then register its sequence number. When the server answers fast and an
executor thread takes the answer in between, the client drops it ("Ignoring unexpected
goal response. There may be more than one action server ...") and the future never
completes. That happens to a node that sends from a goal's worker thread while a
multi-threaded executor spins. Here each send holds a lock until its request is registered,
and each answer waits for that lock before it is looked up.
"""
from __future__ import annotations

import threading
from typing import Any

from rclpy.action import ActionClient as _RclpyActionClient
from rclpy.node import Node

from pppbot_lockstep.ros.node import port_of
from pppbot_lockstep.ros.requests import action_key


class ActionClient(_RclpyActionClient):
    """Drop-in for :class:`rclpy.action.ActionClient` (same arguments)."""

    def __init__(self, node: Node, action_type: Any, action_name: str, *args: Any, **kwargs: Any) -> None:
        super().__init__(node, action_type, action_name, *args, **kwargs)
        self._send_lock = threading.Lock()
        self._step_port = port_of(node)
        self._step_key = action_key(node, action_name)

    def send_goal_async(self, goal: Any, feedback_callback: Any = None, goal_uuid: Any = None) -> Any:
        return self._step_port.request(self._send_goal, self._step_key, goal, feedback_callback, goal_uuid)

    def _send_goal(self, goal: Any, feedback_callback: Any, goal_uuid: Any) -> Any:
        with self._send_lock:
            return super().send_goal_async(goal, feedback_callback=feedback_callback, goal_uuid=goal_uuid)

    def _cancel_goal_async(self, goal_handle: Any) -> Any:
        return self._step_port.request(self._cancel_goal, self._step_key, goal_handle)

    def _cancel_goal(self, goal_handle: Any) -> Any:
        with self._send_lock:
            return super()._cancel_goal_async(goal_handle)

    def _get_result_async(self, goal_handle: Any) -> Any:
        return self._step_port.request(self._get_result, self._step_key, goal_handle)

    def _get_result(self, goal_handle: Any) -> Any:
        with self._send_lock:
            return super()._get_result_async(goal_handle)

    async def execute(self, taken_data: Any) -> None:
        with self._send_lock:
            pass  # every request sent before these answers were taken is registered by now
        await super().execute(taken_data)
