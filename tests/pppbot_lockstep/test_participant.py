"""A participant's step: the readings' work (a worker thread's too) before the timers, then the answer."""
from __future__ import annotations

import contextlib
import inspect
import threading
from collections.abc import Callable, Iterator
from typing import Any

import pytest
from builtin_interfaces.msg import Time as TimeMsg

from pppbot_interfaces.msg import LockstepStatus, LockstepStep
from pppbot_lockstep.ros.participant import Participant

pytestmark = pytest.mark.ros


class Tasks:
    """Stands in for the executor: tasks wait until :meth:`run` (the executor's turn)."""

    def __init__(self) -> None:
        self.queue: list[Callable[[], None]] = []
        self.lock = threading.Lock()

    def create_task(self, work: Callable[[], None]) -> None:
        with self.lock:
            self.queue.append(work)

    def run(self) -> None:
        while True:
            with self.lock:
                if not self.queue:
                    return
                work = self.queue.pop(0)
            result = work()
            if inspect.iscoroutine(result):  # a kept request's task: it awaits nothing pending
                with contextlib.suppress(StopIteration):
                    result.send(None)


class Answers(list[Any]):
    """Stands in for the participant's /lockstep/ack publisher: what it answered."""

    def publish(self, msg: Any) -> None:
        self.append(msg)

    def get_subscription_count(self) -> int:
        return 0  # no simulator listens: no JOIN is sent (the tests take the participant as joined)


@pytest.fixture
def participant(ros_node: Any) -> Iterator[tuple[Participant, Tasks, list[Any]]]:
    answers = Answers()
    p = Participant("p", ros_node)
    p.ack_pub = answers  # type: ignore[assignment]
    tasks = Tasks()
    p.start(tasks, [])
    p._joined = True
    try:
        yield p, tasks, answers
    finally:
        p.outbox.send_all()


def step(seq: int, t_ns: int, timers: bool) -> LockstepStep:
    return LockstepStep(seq=seq, stamp=TimeMsg(sec=t_ns // 10**9, nanosec=t_ns % 10**9), round=0, timers=timers)


def test_timers_wait_for_the_work_a_reading_handed_to_a_worker_thread(
        participant: tuple[Participant, Tasks, list[Any]]) -> None:
    p, tasks, answers = participant
    matched: list[str] = []
    seen_by_timer: list[list[str]] = []
    p.timers.create(0.05, lambda: seen_by_timer.append(list(matched)))

    def match() -> None:  # SLAM's worker thread
        matched.append("scan at 0.05 s")
        p.release()

    def scan_arrived() -> None:  # what SLAM's scan callback does at the step: hand the scan to its worker
        p.hold()
        threading.Timer(0.05, match).start()

    p.defer(scan_arrived)
    p._on_step(step(1, 50_000_000, timers=True))
    tasks.run()
    assert seen_by_timer == [] and answers == []  # the worker still has the scan: no timer, no answer
    for _ in range(100):
        if matched:
            break
        threading.Event().wait(0.01)
    tasks.run()  # the worker's release asked the executor's thread to run the timers, then to answer
    assert seen_by_timer == [["scan at 0.05 s"]]
    assert len(answers) == 1


def test_without_timers_due_the_step_is_answered_once_the_work_is_done(
        participant: tuple[Participant, Tasks, list[Any]]) -> None:
    p, tasks, answers = participant
    fired: list[int] = []
    p.timers.create(0.05, lambda: fired.append(1))
    p._on_step(step(1, 50_000_000, timers=False))
    tasks.run()
    assert fired == [] and len(answers) == 1
    p._on_step(step(2, 50_000_000, timers=True))  # the timers' round at the same time
    tasks.run()
    assert fired == [1] and len(answers) == 2
    p._on_step(step(3, 50_000_000, timers=True))  # never twice at one time
    tasks.run()
    assert fired == [1] and len(answers) == 3


def test_a_repeated_step_is_taken_once_and_a_new_simulator_counts_from_one(
        participant: tuple[Participant, Tasks, list[Any]]) -> None:
    p, tasks, answers = participant
    p._on_step(step(1, 0, timers=False))
    p._on_step(step(1, 0, timers=False))  # the simulator repeats a step until all have answered
    tasks.run()
    assert p.steps == 1 and len(answers) == 1
    p._on_status(LockstepStatus(participants=[]))  # the simulator went; a new one lists us again
    p._on_status(LockstepStatus(participants=["p"]))
    p._on_step(step(1, 0, timers=False))
    tasks.run()
    assert p.steps == 2 and len(answers) == 2


def test_a_step_before_the_listing_is_taken_when_the_listing_comes(
        participant: tuple[Participant, Tasks, list[Any]]) -> None:
    p, tasks, answers = participant
    p._joined = False
    p._on_step(step(1, 0, timers=False))  # steps and the status come on different topics
    tasks.run()
    assert answers == []
    p._on_status(LockstepStatus(participants=["p"]))
    tasks.run()
    assert p.joined and len(answers) == 1


def test_a_request_kept_between_steps_is_handled_at_the_next_step_before_its_answer(
        participant: tuple[Participant, Tasks, list[Any]]) -> None:
    p, tasks, answers = participant
    handled: list[int] = []

    async def request() -> None:  # a service's or an action server's handling of one request
        handled.append(p.steps)

    p._on_step(step(1, 50_000_000, timers=False))
    tasks.run()
    assert len(answers) == 1
    assert p.requests.keep("/planner#requests", request)  # taken after the answer: kept
    tasks.run()
    assert handled == []
    p._on_step(step(2, 100_000_000, timers=False))
    assert not p.requests.keep("/planner#requests", request)  # while a step is handled: at once
    tasks.run()
    assert handled == [2] and len(answers) == 2  # handled at step 2, then step 2 answered
