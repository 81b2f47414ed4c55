"""Throttle repeated warnings per distinct reason (rclpy throttles per call site only)."""
from __future__ import annotations


class Throttle:
    """``allow(key, now_s)`` is true at most once per ``period_s`` for each key."""

    def __init__(self, period_s: float) -> None:
        self.period_s = period_s
        self._last: dict[str, float] = {}

    def allow(self, key: str, now_s: float) -> bool:
        last = self._last.get(key)
        if last is not None and now_s - last < self.period_s:
            return False
        self._last[key] = now_s
        return True
