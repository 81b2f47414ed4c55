"""Closures checked against each other before they go in: pairwise consistency (PCM's largest
agreeing set) and a second keyframe's match before a correction larger than the drift."""
from __future__ import annotations

import numpy as np
from test_pose_graph import drifting_graph, position_errors, square_truth
from test_robustness import match_between

from pppbot_slam.loops import (
    LOOP_EVIDENCE_KEYFRAMES,
    consistent_set,
    correction,
    needs_evidence,
    pair_consistent,
    plausible,
    solve_loops,
)
from pppbot_slam.mapper import Mapper

ALIAS = (1.6, 0.0, 0.0)  # the next identical room along: 1.6 m off
#: Odometry that can drift: the graph's relative covariances let a correction of metres through
#: :func:`plausible` (the check before these).
LOOSE = np.diag([0.05 ** 2, 0.05 ** 2, 0.03 ** 2])


def test_two_true_closures_agree_and_an_alias_agrees_with_neither():
    truth = square_truth(side_m=4.0, per_side=8)
    graph = drifting_graph(truth, yaw_drift_rad=0.003)
    a, b, alias = match_between(truth, 0, 32), match_between(truth, 2, 30), match_between(truth, 4, 28, ALIAS)
    assert pair_consistent(graph, a, b) and pair_consistent(graph, b, a)
    assert not pair_consistent(graph, a, alias) and not pair_consistent(graph, alias, b)


def test_the_largest_agreeing_set_wins_even_when_the_aliases_agree_with_each_other():
    truth = square_truth(side_m=4.0, per_side=8)
    graph = drifting_graph(truth, yaw_drift_rad=0.0, odom_cov=LOOSE)  # a 0.6 m alias is plausible alone
    true = [match_between(truth, a, b) for a, b in [(0, 32), (2, 30), (4, 28)]]
    aliases = [match_between(truth, a, b, (0.6, 0.0, 0.0)) for a, b in [(1, 31), (0, 31)]]  # the same shift
    assert plausible(graph, aliases) == [True, True]
    assert pair_consistent(graph, aliases[0], aliases[1])
    matches = [aliases[0], *true, aliases[1]]
    assert consistent_set(graph, matches, [True] * len(matches)) == [1, 2, 3]
    solution = solve_loops(graph, matches)
    assert sorted((m.source, m.target) for m in solution.accepted) == [(0, 32), (2, 30), (4, 28)]
    assert solution.rejected == 2 and solution.why == {"inconsistent": 2}
    assert position_errors(solution.graph, truth).max() < 0.05


def test_a_correction_beyond_the_drift_waits_for_a_second_keyframe_that_agrees():
    truth = square_truth(side_m=4.0, per_side=8)
    graph = drifting_graph(truth, yaw_drift_rad=0.005, odom_cov=LOOSE)  # 0.16 rad lost round the square
    first = match_between(truth, 0, 32)
    assert abs(correction(graph, first)[2]) > 0.15 and needs_evidence(graph, first, last_closed=0)
    held = solve_loops(graph.copy(), [first])
    assert not held.accepted and held.held == (first,) and held.rejected == 0
    # The next keyframe's match of the same place agrees with it: both go in, the drift is undone.
    both = solve_loops(graph.copy(), [match_between(truth, 1, 31)], held.held)
    assert sorted((m.source, m.target) for m in both.accepted) == [(0, 32), (1, 31)] and not both.held
    assert position_errors(both.graph, truth).max() < 0.1


def test_a_held_alias_is_dropped_when_a_closure_it_disagrees_with_comes():
    truth = square_truth(side_m=4.0, per_side=8)
    graph = drifting_graph(truth, yaw_drift_rad=0.0, odom_cov=LOOSE)
    alias = match_between(truth, 0, 32, (0.6, 0.0, 0.0))
    assert needs_evidence(graph, alias, last_closed=0) is False  # 16 m since the start: 0.6 m could be drift
    assert needs_evidence(graph, alias, last_closed=30)  # 1 m since the last closure: it could not
    held = solve_loops(graph.copy(), [alias], last_closed=30)
    assert held.held == (alias,) and not held.accepted
    true = match_between(truth, 1, 31)
    solution = solve_loops(graph.copy(), [true], held.held, last_closed=30)
    assert [(m.source, m.target) for m in solution.accepted] == [(1, 31)]
    assert not solution.held and solution.rejected == 1 and solution.why == {"inconsistent": 1}


def test_the_mapper_keeps_held_matches_for_a_while_then_counts_them_rejected():
    truth = square_truth(side_m=4.0, per_side=8)
    mapper = Mapper()
    mapper.graph = drifting_graph(truth, yaw_drift_rad=0.005, odom_cov=LOOSE)
    mapper.keyframes = [None] * len(truth)  # type: ignore[list-item]  # only their count matters here
    held = solve_loops(mapper.graph.copy(), [match_between(truth, 0, 32)])
    mapper.merge_loops(held)
    assert len(mapper.held_matches) == 1 and mapper.rejected_closures == 0
    mapper.keyframes += [None] * (LOOP_EVIDENCE_KEYFRAMES + 1)  # type: ignore[list-item]
    mapper.merge_loops(held)  # a later search: the match waited too long
    assert mapper.held_matches == () and mapper.rejected_closures == 1
    assert mapper.rejected_why == {"disagrees": 0, "see_through": 0, "inconsistent": 0, "unconfirmed": 1, "residual": 0}
