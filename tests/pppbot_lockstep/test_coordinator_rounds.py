"""The simulator's rounds at one sync time: readings and timers in one step, more while anyone sends."""
from __future__ import annotations

import time
from typing import Any

import pytest
from rclpy.serialization import deserialize_message

import pppbot_lockstep.ros.coordinator as coordinator_module
from pppbot_interfaces.msg import LockstepAck, LockstepStep
from pppbot_lockstep.ros.coordinator import Coordinator, CoordinatorPort
from pppbot_lockstep.ros.participant import time_msg

pytestmark = pytest.mark.ros


class Replies:
    """Stands in for the step publisher: every step is recorded and answered at once by the
    participants, each saying it sent something while its script says so."""

    def __init__(self, coordinator: Coordinator, sends: dict[str, list[bool]]) -> None:
        self.coordinator = coordinator
        self.sends = sends
        self.steps: list[LockstepStep] = []

    def publish(self, wire: Any) -> None:
        step = wire if isinstance(wire, LockstepStep) else deserialize_message(bytes(wire), LockstepStep)
        self.steps.append(step)
        for name, script in self.sends.items():
            sent = script.pop(0) if script else False
            self.coordinator._on_ack(LockstepAck(kind=LockstepAck.DONE, participant=name, seq=step.seq, sent=sent,
                                                 next_wakeup=time_msg(step.stamp.sec * 10**9 + 50_000_000)))


class Running:
    def running(self) -> bool:
        return True

    def spin_once(self, timeout_s: float = 0.0) -> None:
        pass


def coordinator_with(ros_node: Any, sends: dict[str, list[bool]]) -> tuple[Coordinator, Replies]:
    coordinator = Coordinator(ros_node, expected=list(sends), timeout_s=5.0, log=lambda text: None,
                              port=CoordinatorPort())
    for name in sends:
        coordinator._on_ack(LockstepAck(kind=LockstepAck.JOIN, participant=name))
    replies = Replies(coordinator, sends)
    coordinator.step_pub = replies  # type: ignore[assignment]
    return coordinator, replies


def test_readings_and_timers_share_one_round_when_nobody_sends(ros_node: Any) -> None:
    coordinator, replies = coordinator_with(ros_node, {"slam": [], "twist_mux": []})
    coordinator.sync(Running(), 1_000_000_000, readings=True, timers=True)  # type: ignore[arg-type]
    assert [(s.round, s.timers) for s in replies.steps] == [(0, True)]
    assert (replies.steps[0].stamp.sec, replies.steps[0].stamp.nanosec) == (1, 0)
    assert coordinator.rounds == 1 and coordinator.steps == 1


def test_rounds_follow_while_anyone_sends_and_only_the_first_runs_timers(ros_node: Any) -> None:
    # The driver's timer sends a command (round 0), twist_mux forwards it (round 1), nobody then.
    coordinator, replies = coordinator_with(ros_node, {"eval": [True], "twist_mux": [False, True]})
    coordinator.sync(Running(), 2_000_000_000, readings=True, timers=True)  # type: ignore[arg-type]
    assert [(s.round, s.timers) for s in replies.steps] == [(0, True), (1, False), (2, False)]
    assert len({s.seq for s in replies.steps}) == 3
    assert coordinator.next_wakeup_ns() == 2_050_000_000


def test_a_time_without_timers_due_handles_its_readings_alone(ros_node: Any) -> None:
    coordinator, replies = coordinator_with(ros_node, {"slam": [True]})
    coordinator.sync(Running(), 3_000_000_000, readings=True, timers=False)  # type: ignore[arg-type]
    assert [(s.round, s.timers) for s in replies.steps] == [(0, False), (1, False)]


def test_a_step_a_participant_missed_is_repeated_until_it_answers(ros_node: Any,
                                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    # The simulator sends a step only to the readers it has discovered: a joiner's may be unknown yet.
    coordinator, replies = coordinator_with(ros_node, {"navigation": []})
    published = replies.publish
    lost: list[Any] = []
    first = [True]

    def lose_the_first(wire: Any) -> None:  # the first goes to no reader; its repeat reaches one
        if first:
            first.clear()
            lost.append(wire)
        else:
            published(wire)

    replies.publish = lose_the_first  # type: ignore[method-assign]
    monkeypatch.setattr(coordinator_module, "STEP_REPEAT_S", 0.01)

    class Waiting(Running):
        def spin_once(self, timeout_s: float = 0.0) -> None:
            time.sleep(0.005)

    coordinator.sync(Waiting(), 0, readings=True, timers=False)  # type: ignore[arg-type]
    assert len(lost) == 1 and coordinator.repeats >= 1
    assert [s.seq for s in replies.steps] == [1] and coordinator.barrier.complete()
