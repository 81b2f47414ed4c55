"""Loop closures judged against ground truth: a right one, a wrong one the graph took, one it shrugged off."""
from __future__ import annotations

import math

import numpy as np
import pytest

from pppbot_common.se2 import se2_compose, se2_inverse
from pppbot_eval.closures import FALSE_CLOSURE_M, FALSE_CLOSURE_RAD, closure_errors, closure_figures
from pppbot_slam.pose_graph import Edge

#: A square driven once: the true poses of four keyframes, and the same seen from a map frame
#: elsewhere (only relative poses count).
TRUTH = np.array([[0.0, 0.0, 0.0], [4.0, 0.0, math.pi / 2], [4.0, 4.0, math.pi], [0.1, 4.0, -math.pi / 2]])
MAP_IN_WORLD = np.array([2.0, -1.0, 0.7])


def in_map(poses: np.ndarray) -> np.ndarray:
    return np.array([se2_compose(se2_inverse(MAP_IN_WORLD), p) for p in poses])


def edge(source: int, target: int, relative) -> Edge:
    return Edge(source, target, np.asarray(relative, dtype=float), np.eye(3) * 0.01, loop=True)


def true_relative(source: int, target: int) -> np.ndarray:
    return np.asarray(se2_compose(se2_inverse(TRUTH[source]), TRUTH[target]))


def test_a_closure_is_false_when_the_solved_keyframes_are_off_by_half_a_metre_or_five_degrees():
    solved = in_map(TRUTH)
    solved[3] = se2_compose(solved[3], (0.0, 0.6, 0.0))  # pulled 0.6 m sideways by a wrong closure
    right = edge(0, 2, true_relative(0, 2))
    wrong = edge(0, 3, se2_compose(true_relative(0, 3), (0.0, 1.5, 0.0)))  # claimed 1.5 m off
    errors = closure_errors(solved, TRUTH, [right, wrong])
    assert [e.false for e in errors] == [False, True]
    assert errors[0].position_m == pytest.approx(0.0, abs=1e-9) and errors[0].claimed_position_m < 1e-9
    assert errors[1].position_m == pytest.approx(0.6) and errors[1].claimed_position_m == pytest.approx(1.5)
    figures = closure_figures(errors)
    assert figures == {"closures": 2, "false_closures": 1, "false_claims": 1, "closure_max_error_m": 0.6,
                       "closure_max_claim_error_m": 1.5, "false_closure_keyframes": [[0, 3]]}


def test_a_wrong_claim_the_graph_did_not_follow_is_not_a_false_closure_and_turns_count_too():
    solved = in_map(TRUTH)
    shrugged = edge(1, 3, se2_compose(true_relative(1, 3), (2.0, 0.0, 0.0)))
    [error] = closure_errors(solved, TRUTH, [shrugged])
    assert not error.false and error.false_claim and error.claimed_position_m == pytest.approx(2.0)
    turned = solved.copy()
    turned[2] = se2_compose(turned[2], (0.0, 0.0, FALSE_CLOSURE_RAD * 1.2))
    [error] = closure_errors(turned, TRUTH, [edge(0, 2, true_relative(0, 2))])
    assert error.false and error.position_m < FALSE_CLOSURE_M
    assert closure_figures([]) == {"closures": 0, "false_closures": 0, "false_claims": 0, "closure_max_error_m": None,
                                   "closure_max_claim_error_m": None, "false_closure_keyframes": []}


def test_mismatched_inputs_are_refused_naming_them():
    with pytest.raises(ValueError, match=r"poses \(4, 3\) and truth \(3, 3\)"):
        closure_errors(TRUTH, TRUTH[:3], [])
    with pytest.raises(ValueError, match="closure 0 -> 9: the run has 4 keyframes"):
        closure_errors(TRUTH, TRUTH, [edge(0, 9, (0.0, 0.0, 0.0))])
