"""Closures checked against each other before they go in: pairwise consistency (PCM's largest
agreeing set), and the rejections counted by reason."""
from __future__ import annotations

import numpy as np
from test_pose_graph import drifting_graph, position_errors, square_truth
from test_robustness import match_between

from pppbot_slam.loops import consistent_set, pair_consistent, plausible, solve_loops
from pppbot_slam.mapper import Mapper

ALIAS = (1.6, 0.0, 0.0)  # the next identical room along: 1.6 m off
#: Odometry that can drift: the graph's relative covariances let a correction of half a metre
#: through :func:`plausible` (the check before this one).
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
    assert consistent_set(graph, matches) == [1, 2, 3]
    solution = solve_loops(graph, matches)
    assert sorted((m.source, m.target) for m in solution.accepted) == [(0, 32), (2, 30), (4, 28)]
    assert solution.rejected == 2 and solution.why == {"inconsistent": 2}
    assert position_errors(solution.graph, truth).max() < 0.05


def test_the_mapper_counts_its_rejections_by_reason():
    truth = square_truth(side_m=4.0, per_side=8)
    mapper = Mapper()
    mapper.graph = drifting_graph(truth, yaw_drift_rad=0.0, odom_cov=LOOSE)
    matches = [match_between(truth, 0, 32), match_between(truth, 2, 30), match_between(truth, 1, 31, (0.6, 0.0, 0.0)),
               match_between(truth, 4, 28, (2.5, 0.0, 0.0))]  # two true, an alias they disagree with, implausible
    mapper.merge_loops(solve_loops(mapper.graph.copy(), matches))
    assert [(c.source, c.target) for c in mapper.loop_closures] == [(0, 32), (2, 30)]
    assert mapper.rejected_closures == 2
    assert mapper.rejected_why == {"disagrees": 1, "see_through": 0, "inconsistent": 1, "residual": 0}
