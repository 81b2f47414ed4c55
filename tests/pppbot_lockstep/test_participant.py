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


def answered(answers: list[Any]) -> Any:
    """The last answer, as a message (the participant sends a DONE serialized, from its template)."""
    from rclpy.serialization import deserialize_message

    from pppbot_interfaces.msg import LockstepAck
    last = answers[-1]
    return deserialize_message(last, LockstepAck) if isinstance(last, bytes) else last


def test_what_only_it_counts_goes_out_at_once_and_is_handled_before_the_answer(
        participant: tuple[Participant, Tasks, list[Any]]) -> None:
    """A chain of nodes in one process is one round: the participant's own message is handled
    before it answers; what another participant counts is held for the next round."""
    p, tasks, answers = participant
    own = p.deliveries.add("/cmd_vel_nav")  # one of its nodes (the velocity smoother) counts it
    went: list[str] = []

    def tick() -> None:
        p.outbox.send(lambda: went.append("own"), "/cmd_vel_nav")
        p.outbox.send(lambda: went.append("held"), "/tf")

    p.timers.create(0.05, tick)
    at_05 = step(1, 50_000_000, timers=True)
    at_05.topics, at_05.published, at_05.counted_by = ["/cmd_vel_nav", "/tf"], [0, 0], [1, 1]
    p._on_step(at_05)
    tasks.run()
    assert went == ["own"]  # only it counts /cmd_vel_nav; another participant counts /tf
    assert answers == []  # its own message is on its way to its own node
    own.received += 1  # it came: the smoother handled it
    p._on_delivery()
    tasks.run()
    assert len(answers) == 1 and answered(answers).sent  # the held transform asks for another round
    assert list(answered(answers).published) == [1, 1]  # both counted
    again = step(2, 50_000_000, timers=False)
    again.topics, again.published, again.counted_by = ["/cmd_vel_nav", "/tf"], [1, 1], [1, 1]
    p._on_step(again)
    assert went == ["own", "held"]  # the next step sends what was held
    tasks.run()
    assert len(answers) == 2 and not answered(answers).sent
