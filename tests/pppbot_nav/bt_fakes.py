"""Fake action servers, services and TF for Nav2's tree nodes (:class:`pppbot_nav.bt.ports.RobotPorts`):
each goal and request is kept, answered when the test says so."""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

from pppbot_nav.bt.ports import GoalStatus, Outcome


class FakeGoal:
    def __init__(self, goal: Any, on_feedback: Callable[[Any], None] | None) -> None:
        self.goal = goal
        self.on_feedback = on_feedback
        self._accepted: bool | None = None
        self._outcome: Outcome | None = None
        self.canceled = False

    def accepted(self) -> bool | None:
        return self._accepted

    def outcome(self) -> Outcome | None:
        return self._outcome

    def cancel(self) -> None:
        self.canceled = True

    # -- the test's side -------------------------------------------------------------------------
    def accept(self) -> FakeGoal:
        self._accepted = True
        return self

    def refuse(self) -> None:
        self._accepted = False

    def end(self, status: GoalStatus, result: Any) -> None:
        self._accepted = True
        self._outcome = Outcome(status, result)


class FakeAction:
    """An action server: ``goals`` in the order sent; with ``auto_accept`` each is accepted at once,
    with ``answer`` (goal → (status, result) or None) each ends at once."""

    def __init__(self, action_type: Any, auto_accept: bool = True,
                 answer: Callable[[Any], tuple[GoalStatus, Any] | None] | None = None) -> None:
        self.action_type = action_type
        self.goals: list[FakeGoal] = []
        self.auto_accept = auto_accept
        self.answer = answer
        self.cancel_all_calls = 0
        self.up = True

    def ready(self) -> bool:
        return self.up

    def send(self, goal: Any, on_feedback: Callable[[Any], None] | None = None) -> FakeGoal:
        call = FakeGoal(goal, on_feedback)
        self.goals.append(call)
        if self.auto_accept:
            call.accept()
        if self.answer is not None:
            answered = self.answer(goal)
            if answered is not None:
                call.end(*answered)
        return call

    def cancel_all(self) -> None:
        self.cancel_all_calls += 1
        for call in self.goals:
            call.canceled = True

    @property
    def last(self) -> FakeGoal:
        return self.goals[-1]

    def result(self, **fields: Any) -> Any:
        return self.action_type.Result(**fields)


class FakeServiceCall:
    def __init__(self, request: Any) -> None:
        self.request = request
        self._response: Any = None

    def response(self) -> Any | None:
        return self._response

    def refused(self) -> bool:
        return False

    def respond(self, response: Any) -> None:
        self._response = response


class FakeService:
    def __init__(self, service_type: Any, answer: Callable[[Any], Any] | None = None) -> None:
        self.service_type = service_type
        self.calls: list[FakeServiceCall] = []
        self.answer = answer

    def ready(self) -> bool:
        return True

    def call(self, request: Any) -> FakeServiceCall:
        call = FakeServiceCall(request)
        self.calls.append(call)
        if self.answer is not None:
            call.respond(self.answer(request))
        return call


class FakePorts:
    """Servers made on first use (or given beforehand in ``actions``/``services``), the robot's pose
    in ``poses`` (frame pair → (x, y, yaw)), topics' newest messages in ``topics``
    (what was asked for in ``subscribed``: topic → latched)."""

    def __init__(self) -> None:
        self.actions: dict[str, FakeAction] = {}
        self.services: dict[str, FakeService] = {}
        self.poses: dict[tuple[str, str], tuple[float, float, float]] = {}
        self.topics: dict[str, Any] = {}
        self.subscribed: dict[str, bool] = {}  # topic → latched

    def action(self, name: str, action_type: Any) -> FakeAction:
        if name not in self.actions:
            self.actions[name] = FakeAction(action_type)
        return self.actions[name]

    def service(self, name: str, service_type: Any) -> FakeService:
        if name not in self.services:
            self.services[name] = FakeService(service_type, answer=lambda _: service_type.Response())
        return self.services[name]

    def transform(self, target_frame: str, source_frame: str) -> tuple[float, float, float] | None:
        return self.poses.get((target_frame, source_frame))

    def latest(self, topic: str, message_type: Any, *, latched: bool = False) -> Any | None:
        self.subscribed[topic] = latched
        return self.topics.get(topic)
