"""The retry policy on a fake client whose first answers are lost, on a fake clock: when a request
is sent again, when it is waited on, and what giving up says."""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import pytest

from pppbot_common.errors import TimeoutExpired
from pppbot_common.ros.retry import (
    AnswerLost,
    Request,
    Retry,
    Unanswered,
    Verdict,
    cancel_when_accepted,
    send_goal,
    transition_verdict,
    wait_for_answer,
)

WHAT = "service /amcl/get_state, asked by /probe"


@dataclass
class Sent:
    """One request on the wire: answered (done) once the server's answer arrives."""

    number: int
    answer: str | None = None

    def done(self) -> bool:
        return self.answer is not None

    def result(self) -> str | None:
        return self.answer


@dataclass
class LossyServer:
    """Answers every request ``delay_s`` after it was sent, but the first ``lost`` answers never
    arrive; time is a fake clock that :meth:`wait` moves on."""

    lost: int
    delay_s: float = 0.1
    now_s: float = 0.0
    sent: list[Sent] = field(default_factory=list)
    forgotten: list[int] = field(default_factory=list)
    _due: list[tuple[float, Sent]] = field(default_factory=list)

    def send(self) -> Sent:
        request = Sent(len(self.sent) + 1)
        self.sent.append(request)
        if request.number > self.lost:
            self._due.append((self.now_s + self.delay_s, request))
        return request

    def wait(self, pending: object, timeout_s: float) -> None:
        due = [at for at, request in self._due if request is pending and at <= self.now_s + timeout_s]
        self.now_s = due[0] if due else self.now_s + timeout_s
        for at, request in self._due:
            if at <= self.now_s:
                request.answer = f"answer to {request.number}"

    def forget(self, request: Sent) -> None:
        self.forgotten.append(request.number)

    def clock(self) -> float:
        return self.now_s

    def request(self, retry: Retry, check: Callable[[], Verdict] | None = None) -> Request[str]:
        return Request(self.send, retry, WHAT, check=check, forget=self.forget, clock=self.clock)


def test_an_answer_that_comes_is_taken_from_the_first_request():
    server = LossyServer(lost=0)
    assert wait_for_answer(server.request(Retry(1.0, attempts=3)), server.wait) == "answer to 1"
    assert len(server.sent) == 1 and server.forgotten == []


def test_lost_answers_are_asked_again_each_attempt_s():
    server = LossyServer(lost=2)
    assert wait_for_answer(server.request(Retry(1.0, attempts=3)), server.wait) == "answer to 3"
    assert server.forgotten == [1, 2]  # the requests given up on are dropped
    assert server.now_s == pytest.approx(2.1)  # sent at 0, 1 and 2 s; answered 0.1 s later


@pytest.mark.parametrize(("retry", "sent", "waited_s"), [(Retry(1.0, attempts=3), 3, 3.0),
                                                         (Retry(1.0, attempts=10, deadline_s=2.5), 3, 2.5)])
def test_giving_up_names_what_was_asked_how_often_and_how_long(retry, sent, waited_s):
    server = LossyServer(lost=99)
    with pytest.raises(Unanswered) as raised:
        wait_for_answer(server.request(retry), server.wait)
    assert len(server.sent) == sent and server.forgotten == list(range(1, sent + 1))
    assert str(raised.value) == f"gave up on {WHAT}: no answer ({sent} requests in {waited_s:.1f} s)"
    assert isinstance(raised.value, TimeoutExpired)


def test_a_request_in_progress_is_waited_on_and_never_sent_again():
    server = LossyServer(lost=0, delay_s=3.5)  # a slow server: answers after 3.5 s
    checks: list[float] = []

    def in_progress() -> Verdict:
        checks.append(server.now_s)
        return Verdict.IN_PROGRESS
    assert wait_for_answer(server.request(Retry(1.0, attempts=3, deadline_s=10.0), in_progress),
                           server.wait) == "answer to 1"
    assert len(server.sent) == 1 and checks == [1.0, 2.0, 3.0]


def test_a_request_in_progress_past_the_deadline_is_given_up_on_saying_so():
    server = LossyServer(lost=1)
    with pytest.raises(Unanswered, match=r"no answer, still under way \(1 request in 3\.0 s\)"):
        wait_for_answer(server.request(Retry(1.0, attempts=3), lambda: Verdict.IN_PROGRESS), server.wait)
    assert len(server.sent) == 1 and server.forgotten == [1]


def test_a_settled_request_stops_the_wait_without_another_send():
    server = LossyServer(lost=1)
    with pytest.raises(AnswerLost, match="it took effect but its answer was lost"):
        wait_for_answer(server.request(Retry(1.0, attempts=3), lambda: Verdict.SETTLED), server.wait)
    assert len(server.sent) == 1


def test_an_answer_that_comes_while_the_check_asks_is_taken():
    server = LossyServer(lost=0, delay_s=1.5)

    def slow_check() -> Verdict:
        server.wait(server.sent[0], 1.0)  # the check's own request takes a while: the answer comes
        return Verdict.LOST
    assert wait_for_answer(server.request(Retry(1.0, attempts=3), slow_check), server.wait) == "answer to 1"
    assert len(server.sent) == 1


@pytest.mark.parametrize(("now_id", "began", "verdict"), [
    (1, False, Verdict.LOST),  # unconfigured still, nothing began: the request never arrived
    (10, True, Verdict.IN_PROGRESS),  # configuring
    (None, True, Verdict.IN_PROGRESS),  # too busy configuring to answer get_state
    (2, True, Verdict.SETTLED),  # inactive: configured, its answer lost
    (1, True, Verdict.SETTLED),  # configure began and failed back to unconfigured
])
def test_a_lifecycle_transition_is_sent_again_only_when_lost(now_id, began, verdict):
    assert transition_verdict(1, now_id, began) is verdict


@pytest.mark.parametrize(("kwargs", "message"), [({"attempt_s": 0.0}, "Retry.attempt_s = 0.0: must be > 0 s"),
                                                  ({"attempt_s": 1.0, "attempts": 0}, "Retry.attempts = 0"),
                                                  ({"attempt_s": 1.0, "deadline_s": -1.0}, "Retry.deadline_s = -1.0")])
def test_a_bad_retry_names_the_field_and_its_value(kwargs, message):
    with pytest.raises(ValueError, match=message):
        Retry(**kwargs)


@dataclass
class GoalHandle:
    accepted: bool
    canceled: bool = False

    def cancel_goal_async(self) -> None:
        self.canceled = True


@dataclass
class GoalSent(Sent):
    """A goal's send future, as rclpy's: callbacks run once its acceptance arrives."""

    handle: GoalHandle | None = None
    callbacks: list[Callable[[GoalSent], None]] = field(default_factory=list)

    def result(self) -> GoalHandle | None:  # type: ignore[override]
        return self.handle

    def arrive(self, accepted: bool) -> None:
        self.handle, self.answer = GoalHandle(accepted), "answered"
        for callback in self.callbacks:
            callback(self)

    def add_done_callback(self, callback: Callable[[GoalSent], None]) -> None:
        if self.done():
            callback(self)
        else:
            self.callbacks.append(callback)


def test_a_goal_given_up_on_and_accepted_late_is_canceled_and_the_one_answered_is_kept():
    sent: list[GoalSent] = []

    class Client:
        _action_name = "/navigate_to_pose"

        def send_goal_async(self, goal: object, feedback_callback: object = None) -> GoalSent:
            sent.append(GoalSent(len(sent) + 1))
            return sent[-1]

    def wait(pending: GoalSent, timeout_s: float) -> None:
        if pending.number == 2:  # the second goal's acceptance comes in time, the first's after it
            pending.arrive(accepted=True)
            sent[0].arrive(accepted=True)

    handle = send_goal(Client(), object(), Retry(0.01, attempts=2, deadline_s=60.0), wait)
    assert handle is sent[1].handle
    assert handle is not None and not handle.canceled
    first = sent[0].handle
    assert first is not None and first.canceled


def test_a_goal_given_up_on_and_refused_late_is_left_alone():
    late = GoalSent(1)
    cancel_when_accepted(late)
    late.arrive(accepted=False)
    assert late.handle is not None and not late.handle.canceled
