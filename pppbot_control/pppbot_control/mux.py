"""twist_mux's arbitration: the freshest highest-priority input wins unless a lock forbids it.

An input is *active* while its last message is younger than its timeout (0: for
ever, once heard from). A lock
is *locked* while its last Bool was true, or, when its timeout is positive, when
no message came within the timeout (twist_mux's rule: a silent watchdog locks).
The output follows the highest-priority active input whose priority is not
below the highest locked lock. Unlike upstream twist_mux, when the winning input
goes quiet the mux emits one zero twist, so the robot stops even when nothing
downstream has a timeout of its own.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from pppbot_control.errors import MuxConfigError


@dataclass(frozen=True)
class InputSpec:
    name: str
    topic: str
    timeout_s: float
    priority: int


@dataclass(frozen=True)
class LockSpec:
    name: str
    topic: str
    timeout_s: float
    priority: int


@dataclass
class _InputState:
    spec: InputSpec
    last_s: float | None = None
    value: Any = None


@dataclass
class _LockState:
    spec: LockSpec
    last_s: float | None = None
    locked_flag: bool = False


def _entry(kind: str, name: str, entry: Any) -> tuple[str, float, int]:
    if not isinstance(entry, dict):
        raise MuxConfigError(f"{kind}.{name}: expected topic, timeout and priority, not {entry!r}")
    missing = [k for k in ("topic", "timeout", "priority") if k not in entry]
    if missing:
        raise MuxConfigError(f"{kind}.{name}: missing {', '.join(missing)}")
    topic, timeout, priority = entry["topic"], entry["timeout"], entry["priority"]
    if not isinstance(topic, str) or not topic:
        raise MuxConfigError(f"{kind}.{name}.topic = {topic!r}: must be a topic name")
    if isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or timeout < 0:
        raise MuxConfigError(f"{kind}.{name}.timeout = {timeout!r}: must be a number of seconds >= 0")
    if isinstance(priority, bool) or not isinstance(priority, int) or not 0 <= priority <= 255:
        raise MuxConfigError(f"{kind}.{name}.priority = {priority!r}: must be an integer in [0, 255]")
    return topic, float(timeout), priority


def parse_config(topics: dict[str, Any], locks: dict[str, Any]) -> tuple[list[InputSpec], list[LockSpec]]:
    """twist_mux's ``topics`` and ``locks`` mappings (name → {topic, timeout, priority}).

    Raises:
        MuxConfigError: a bad entry, or two entries on one topic.
    """
    inputs = [InputSpec(name, *_entry("topics", name, entry)) for name, entry in sorted(topics.items())]
    lock_specs = [LockSpec(name, *_entry("locks", name, entry)) for name, entry in sorted(locks.items())]
    seen: dict[str, str] = {}
    specs: list[InputSpec | LockSpec] = [*inputs, *lock_specs]
    for spec in specs:
        if spec.topic in seen:
            raise MuxConfigError(f"'{spec.name}' and '{seen[spec.topic]}' both use topic '{spec.topic}'")
        seen[spec.topic] = spec.name
    if not inputs:
        raise MuxConfigError("no input topics configured (topics.<name>.topic/timeout/priority)")
    return inputs, lock_specs


@dataclass
class TwistMux:
    inputs: list[InputSpec]
    locks: list[LockSpec] = field(default_factory=list)

    def __post_init__(self) -> None:
        self._inputs = {s.name: _InputState(s) for s in self.inputs}
        self._locks = {s.name: _LockState(s) for s in self.locks}
        self._winner: str | None = None

    def _active(self, state: _InputState, now_s: float) -> bool:
        """Heard from within its timeout; a timeout of 0 never expires (as upstream)."""
        if state.last_s is None:
            return False
        return state.spec.timeout_s == 0 or now_s - state.last_s <= state.spec.timeout_s

    def _locked(self, state: _LockState, now_s: float) -> bool:
        if state.spec.timeout_s > 0 and (state.last_s is None or now_s - state.last_s > state.spec.timeout_s):
            return True
        return state.locked_flag

    def lock_priority(self, now_s: float) -> int:
        """The highest priority of the locked locks (-1 when none is locked)."""
        return max((s.spec.priority for s in self._locks.values() if self._locked(s, now_s)), default=-1)

    def winner(self, now_s: float) -> str | None:
        floor = self.lock_priority(now_s)
        candidates = [s for s in self._inputs.values() if self._active(s, now_s) and s.spec.priority >= floor]
        if not candidates:
            return None
        return max(candidates, key=lambda s: s.spec.priority).spec.name

    def on_input(self, name: str, value: Any, now_s: float) -> Any | None:
        """Record a message; return it when it is to be published now (its input wins)."""
        state = self._inputs[name]
        state.last_s, state.value = now_s, value
        if self.winner(now_s) == name:
            self._winner = name
            return value
        return None

    def on_lock(self, name: str, locked: bool, now_s: float) -> None:
        state = self._locks[name]
        state.last_s, state.locked_flag = now_s, locked

    def check_timeouts(self, now_s: float) -> bool:
        """True exactly once when the input being followed went quiet (or was locked out)
        and no other input is active: the caller then publishes a zero twist. When
        another input is active, its next message takes over."""
        if self._winner is None:
            return False
        current = self.winner(now_s)
        if current == self._winner:
            return False
        self._winner = current
        return current is None
