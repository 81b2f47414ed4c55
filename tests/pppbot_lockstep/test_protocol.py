"""Lockstep's bookkeeping without ROS: the simulator's barrier and a participant's step timers."""
from __future__ import annotations

import pytest

from pppbot_lockstep.protocol import AckOutcome, Barrier, Deliveries, LockstepError, Publications, StepTimers

MS = 1_000_000


def test_time_holds_until_every_expected_participant_has_joined():
    barrier = Barrier(expected={"slam", "eval"})
    assert not barrier.may_start() and barrier.unjoined() == ["eval", "slam"]
    barrier.join("slam")
    assert not barrier.may_start() and barrier.unjoined() == ["eval"]
    barrier.join("eval")
    assert barrier.may_start()
    barrier.join("late")  # not expected: may join at any time
    assert barrier.may_start()


def test_a_step_completes_when_every_member_has_answered_and_says_who_sent():
    barrier = Barrier()
    barrier.join("a")
    barrier.join("b")
    seq, round_ = barrier.start_step(100 * MS)
    assert (seq, round_) == (1, 0) and barrier.members == {"a", "b"}
    assert barrier.ack("a", seq, sent=False, next_wakeup_ns=150 * MS) is AckOutcome.COUNTED
    assert not barrier.complete() and barrier.missing() == ["b"]
    assert barrier.ack("a", seq, sent=False, next_wakeup_ns=0) is AckOutcome.DUPLICATE
    assert barrier.ack("b", seq - 1, sent=True, next_wakeup_ns=0) is AckOutcome.STALE
    assert barrier.ack("b", seq, sent=True, next_wakeup_ns=120 * MS) is AckOutcome.COUNTED
    assert barrier.complete() and barrier.another_round() and barrier.senders() == ["b"]
    assert barrier.next_wakeup_ns() == 120 * MS
    # Another round at the same time, then time moves on: rounds count from 0 again.
    assert barrier.start_step(100 * MS) == (2, 1)
    barrier.ack("a", 2, False, 150 * MS)
    barrier.ack("b", 2, False, 0)  # b has no timer due any more
    assert not barrier.another_round() and barrier.next_wakeup_ns() == 150 * MS
    assert barrier.start_step(150 * MS) == (3, 0)


def test_a_joiner_is_waited_for_from_the_next_step_and_a_leaver_at_once():
    barrier = Barrier()
    barrier.join("a")
    seq, _ = barrier.start_step(0)
    barrier.join("b")  # mid-step: its answer to this step would be stale
    assert barrier.ack("b", seq, False, 0) is AckOutcome.STALE
    barrier.ack("a", seq, False, 0)
    assert barrier.complete()
    seq, _ = barrier.start_step(10 * MS)
    assert barrier.members == {"a", "b"}
    barrier.ack("b", seq, False, 0)
    assert barrier.missing() == ["a"]
    barrier.leave("a")  # the last one missing leaves: the step is complete
    assert barrier.complete() and barrier.members == {"b"}


def test_a_step_in_progress_or_time_going_back_is_refused():
    barrier = Barrier()
    barrier.join("a")
    barrier.start_step(50 * MS)
    with pytest.raises(LockstepError, match="still waiting for a"):
        barrier.start_step(60 * MS)
    barrier.ack("a", 1, False, 0)
    with pytest.raises(LockstepError, match="time went back"):
        barrier.start_step(40 * MS)


def test_without_members_a_step_is_complete_at_once():
    barrier = Barrier()
    barrier.start_step(0)
    assert barrier.complete() and not barrier.another_round() and barrier.next_wakeup_ns() is None


def test_step_timers_fire_in_deadline_order_once_per_step_skipping_missed_periods():
    timers = StepTimers()
    fired: list[str] = []
    fast = timers.create(0.02, lambda: fired.append("fast"))
    slow = timers.create(0.05, lambda: fired.append("slow"))
    assert timers.next_wakeup_ns() == 20 * MS
    assert [t is fast for t in timers.advance(10 * MS)] == []
    due = timers.advance(50 * MS)  # fast was due at 20 and 40, slow at 50: each fires once
    assert due == [fast, slow]
    assert fast.next_ns == 60 * MS and slow.next_ns == 100 * MS


def test_timers_due_at_the_same_time_fire_in_the_order_they_were_made():
    timers = StepTimers()
    a = timers.create(0.05, lambda: None)
    b = timers.create(0.05, lambda: None)
    assert timers.advance(50 * MS) == [a, b]


def test_canceled_timers_do_not_wake_and_reset_restarts_from_now():
    timers = StepTimers()
    tick = timers.create(0.05, lambda: None)
    lazy = timers.create(0.01, lambda: None, wakes=False)
    tick.cancel()
    assert timers.next_wakeup_ns() is None  # an idle controller makes no sync times
    assert timers.advance(100 * MS) == [lazy]  # a lazy timer fires at a step past its deadline
    tick.reset()
    assert not tick.is_canceled() and tick.next_ns == 150 * MS and timers.next_wakeup_ns() == 150 * MS
    tick.destroy()
    assert timers.advance(200 * MS) == [lazy]


def test_a_timer_period_must_be_positive():
    with pytest.raises(LockstepError, match="positive number of seconds, not 0"):
        StepTimers().create(0, lambda: None)


def test_publications_sum_what_each_process_published_on_the_counted_topics():
    pubs = Publications()
    pubs.joined("amcl", ["/scan", "/tf"])
    pubs.joined("controller", ["/tf"])
    assert pubs.next_topics() == ("/scan", "/tf")
    pubs.report("amcl", [0, 3])
    pubs.report("controller", [0, 2])
    assert pubs.totals({"/scan": 10, "/tf": 5}) == [10, 10]  # the simulator's own 10 scans and 5 transforms
    pubs.report("amcl", [0, 4])  # cumulative: one more
    pubs.report("amcl", [0, 4])  # the same answer again changes nothing
    assert pubs.totals({}) == [0, 6]
    pubs.joined("amcl", ["/scan"])  # restarted: counts from zero again, the sent ones stay sent
    pubs.report("amcl", [0, 1])
    assert pubs.totals({}) == [0, 7]
    pubs.want(["/odom"])
    assert pubs.topics == ("/scan", "/tf")  # a new topic counts from the next step on
    assert pubs.next_topics() == ("/odom", "/scan", "/tf")
    assert pubs.totals({"/odom": 1}) == [1, 0, 7]


def test_deliveries_wait_for_what_was_published_after_they_listened():
    deliveries = Deliveries()
    scan, tf = deliveries.add("/scan"), deliveries.add("/tf")
    tf.received = 2
    deliveries.expect(["/scan", "/tf"], [5, 4])  # first totals: what came before is taken as given
    assert deliveries.lacking() == []
    deliveries.expect(["/scan", "/tf"], [6, 5])  # one scan and one transform published since
    tf.received += 1
    assert deliveries.lacking() == [("/scan", 0, 1)]
    scan.received += 1
    assert deliveries.lacking() == []
    assert deliveries.topics() == ["/scan", "/tf"]


def test_deliveries_rebase_gives_up_on_lost_messages_and_extras_never_block():
    deliveries = Deliveries()
    scan = deliveries.add("/scan")
    deliveries.expect(["/scan"], [0])
    deliveries.expect(["/scan"], [3])
    scan.received = 1
    assert deliveries.lacking() == [("/scan", 1, 3)]
    deliveries.rebase()  # two were lost: waited for no more
    assert deliveries.lacking() == []
    scan.received += 5  # from a publisher outside lockstep
    deliveries.expect(["/scan"], [4])
    assert deliveries.lacking() == []


def test_counted_by_says_who_else_counts_a_topic_so_a_sender_knows_what_to_hold():
    pubs = Publications()
    pubs.joined("navigation", ["/cmd_vel_nav", "/tf"])
    pubs.joined("eval", ["/tf"])
    pubs.want(["/cmd_vel", "/joint_states"])  # the simulator's own nodes (twist_mux, robot_state_publisher)
    assert pubs.next_topics() == ("/cmd_vel", "/cmd_vel_nav", "/joint_states", "/tf")
    # /cmd_vel and /joint_states: only the simulator's process counts them (nobody holds them);
    # /cmd_vel_nav: navigation alone (it handles its own at once); /tf: two participants.
    assert pubs.counted_by({"/cmd_vel", "/joint_states"}) == [0, 1, 0, 2]
    # A topic the simulator's process counts besides a participant: that participant holds it too.
    assert pubs.counted_by({"/cmd_vel_nav"}) == [0, 2, 0, 2]
    pubs.left("eval")
    assert pubs.counted_by() == [0, 1, 0, 1]
    pubs.counting("navigation", ["/tf"])  # its counted topics as its answer last said them
    counts = pubs.counted_by()
    assert counts == [0, 0, 0, 1]
    counts[3] = 9  # the caller's list: what is kept between rounds is not changed through it
    pubs.want(["/scan"])
    assert pubs.counted_by() == [0, 0, 0, 1]  # a topic counts from the next step on
    assert pubs.next_topics() == ("/cmd_vel", "/cmd_vel_nav", "/joint_states", "/scan", "/tf")
    assert pubs.counted_by() == [0, 0, 0, 0, 1]


def test_reacted_by_leaves_out_who_only_records_a_topic():
    """A quiet subscription (an evaluation recording /tf) counts a topic without reacting to it: a
    send there is held for the next step but asks for no round of its own."""
    pubs = Publications()
    pubs.joined("navigation", ["/cmd_vel_nav", "/tf"])
    pubs.joined("eval", ["/amcl_pose", "/tf"], quiet=["/amcl_pose", "/tf"])
    pubs.want(["/cmd_vel"])
    assert pubs.next_topics() == ("/amcl_pose", "/cmd_vel", "/cmd_vel_nav", "/tf")
    assert pubs.counted_by({"/cmd_vel"}) == [1, 0, 1, 2]
    assert pubs.reacted_by({"/cmd_vel"}) == [0, 0, 1, 1]  # the eval only records /amcl_pose and /tf
    pubs.counting("eval", ["/amcl_pose", "/tf"], quiet=["/amcl_pose"])  # now something of it reacts to /tf
    assert pubs.reacted_by() == [0, 0, 1, 2]
    pubs.left("navigation")
    assert pubs.reacted_by() == [0, 0, 0, 1]


def test_a_topic_is_quiet_only_where_every_subscription_of_the_process_is():
    deliveries = Deliveries()
    deliveries.add("/tf", quiet=True)
    deliveries.add("/amcl_pose", quiet=True)
    deliveries.add("/tf")  # a transform listener of another node of the process, which reacts
    assert deliveries.topics() == ["/amcl_pose", "/tf"]
    assert deliveries.quiet_topics() == ["/amcl_pose"]


def test_a_subscriptions_quietness_may_be_asked_each_time_the_topics_are_told():
    """A listener shared by a process's nodes is quiet while every node's reaction to it is."""
    reactions = {"costmap": True}
    deliveries = Deliveries()
    deliveries.add("/tf", quiet=lambda: all(reactions.values()))
    assert deliveries.quiet_topics() == ["/tf"]
    reactions["slam"] = False  # a node that sends when a transform comes listens too
    assert deliveries.quiet_topics() == []
