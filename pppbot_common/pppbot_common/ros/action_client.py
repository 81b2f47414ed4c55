"""rclpy's ActionClient, safe to send requests from threads other than the executor's.

In rclpy (Jazzy) ``send_goal_async``, and the cancel and result requests, send the request
first and only then register its sequence number. When the server answers fast and an
executor thread takes the answer in between, the client drops it ("Ignoring unexpected
goal response. There may be more than one action server ...") and the future never
completes. That happens to a node that sends from a goal's worker thread while a
multi-threaded executor spins, as the navigator does. Here each send holds a lock until
its request is registered, and each answer waits for that lock before it is looked up.
"""
from __future__ import annotations

import threading
from typing import Any

from rclpy.action import ActionClient as _RclpyActionClient


class ActionClient(_RclpyActionClient):
    """Drop-in for :class:`rclpy.action.ActionClient` (same arguments)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._send_lock = threading.Lock()

    def send_goal_async(self, *args: Any, **kwargs: Any) -> Any:
        with self._send_lock:
            return super().send_goal_async(*args, **kwargs)

    def _cancel_goal_async(self, goal_handle: Any) -> Any:
        with self._send_lock:
            return super()._cancel_goal_async(goal_handle)

    def _get_result_async(self, goal_handle: Any) -> Any:
        with self._send_lock:
            return super()._get_result_async(goal_handle)

    async def execute(self, taken_data: Any) -> None:
        with self._send_lock:
            pass  # every request sent before these answers were taken is registered by now
        await super().execute(taken_data)
