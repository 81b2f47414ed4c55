"""The pose graph: a drifting square closed by one loop edge, edge validation, robustness to a bad loop."""
from __future__ import annotations

import math

import numpy as np
import pytest

from pppbot_common.se2 import se2_compose, se2_inverse
from pppbot_slam.pose_graph import PoseGraph, PoseGraphError

ODOM_COV = np.diag([0.02 ** 2, 0.02 ** 2, 0.01 ** 2])
LOOP_COV = np.diag([0.01 ** 2, 0.01 ** 2, 0.005 ** 2])


def square_truth(side_m: float = 4.0, per_side: int = 8) -> np.ndarray:
    """Poses every side/per_side metres around a square, counter-clockwise, back to the start."""
    poses, x, y, yaw = [], 0.0, 0.0, 0.0
    for _ in range(4):
        for _ in range(per_side):
            poses.append((x, y, yaw))
            x += side_m / per_side * math.cos(yaw)
            y += side_m / per_side * math.sin(yaw)
        yaw += math.pi / 2
    poses.append((x, y, yaw))
    array = np.array(poses)
    array[:, 2] = np.remainder(array[:, 2] + math.pi, 2 * math.pi) - math.pi
    return array


def drifting_graph(truth: np.ndarray, yaw_drift_rad: float, odom_cov: np.ndarray = ODOM_COV) -> PoseGraph:
    """Nodes at dead-reckoned poses: every step's odometry turns ``yaw_drift_rad`` too much."""
    graph = PoseGraph()
    pose = truth[0]
    graph.add_node(pose)
    for i in range(1, len(truth)):
        step = se2_compose(se2_inverse(truth[i - 1]), truth[i])
        measured = step + np.array([0.0, 0.0, yaw_drift_rad])
        pose = se2_compose(pose, measured)
        graph.add_node(pose)
        graph.add_edge(i - 1, i, measured, odom_cov)
    return graph


def position_errors(graph: PoseGraph, truth: np.ndarray) -> np.ndarray:
    return np.linalg.norm(np.array(graph.poses)[:, :2] - truth[:, :2], axis=1)


def test_a_loop_closure_corrects_a_drifting_square():
    truth = square_truth()
    graph = drifting_graph(truth, yaw_drift_rad=0.01)
    before = position_errors(graph, truth)
    assert before[-1] > 0.5  # 33 steps of 0.01 rad: the end is far off
    # The last pose sees the first: the true relation, as the matcher would find it.
    graph.add_edge(0, len(truth) - 1, se2_compose(se2_inverse(truth[0]), truth[-1]), LOOP_COV, loop=True)
    graph.optimize()
    after = position_errors(graph, truth)
    assert after.max() < 0.25 * before.max()
    assert after[-1] < 0.05
    np.testing.assert_allclose(graph.poses[0], truth[0], atol=1e-6)  # the anchor stays
    assert graph.loop_closures == 1


def test_a_consistent_graph_does_not_move():
    truth = square_truth(per_side=4)
    graph = drifting_graph(truth, yaw_drift_rad=0.0)
    graph.add_edge(0, len(truth) - 1, se2_compose(se2_inverse(truth[0]), truth[-1]), LOOP_COV, loop=True)
    error = graph.optimize()
    assert error < 1e-9
    solved = np.array(graph.poses)
    np.testing.assert_allclose(solved[:, :2], truth[:, :2], atol=1e-6)
    np.testing.assert_allclose(np.remainder(solved[:, 2] - truth[:, 2] + math.pi, 2 * math.pi) - math.pi, 0,
                               atol=1e-6)  # π and -π alike


def test_a_wrong_loop_edge_bends_the_graph_less_with_the_robust_kernel():
    truth = square_truth()
    wrong = np.array([1.5, 0.0, 0.0])  # claims the end is 1.5 m from the start: false
    stiff = np.diag([0.005 ** 2, 0.005 ** 2, 0.002 ** 2])  # good odometry: bending it costs
    robust = drifting_graph(truth, 0.0, stiff)
    robust.add_edge(0, len(truth) - 1, wrong, LOOP_COV, loop=True)
    robust.optimize()
    plain = drifting_graph(truth, 0.0, stiff)
    plain.add_edge(0, len(truth) - 1, wrong, LOOP_COV, loop=False)
    plain.optimize()
    assert position_errors(plain, truth).max() > 0.5  # least squares meets it by bending the square
    assert position_errors(robust, truth).max() < 0.05  # switched off: the odometry stands


def test_a_wrong_loop_beside_true_ones_is_switched_off_and_the_true_ones_still_correct_the_drift():
    truth = square_truth()
    graph = drifting_graph(truth, yaw_drift_rad=0.01)
    last = len(truth) - 1
    for source, target in ((0, last), (1, last - 1)):  # the end sees the start: true
        graph.add_edge(source, target, se2_compose(se2_inverse(truth[source]), truth[target]), LOOP_COV, loop=True)
    wrong = se2_compose(se2_compose(se2_inverse(truth[8]), truth[24]), (1.5, 0.0, 0.2))  # an alias 1.5 m off
    graph.add_edge(8, 24, wrong, LOOP_COV, loop=True)
    graph.optimize()
    assert position_errors(graph, truth).max() < 0.1
    loops = [e for e in graph.edges if e.loop]
    assert [graph.residual_chi2(e) > 16.3 for e in loops] == [False, False, True]


def test_loops_that_all_agree_are_solved_by_the_huber_step_alone(monkeypatch):
    truth = square_truth()
    graph = drifting_graph(truth, yaw_drift_rad=0.01)
    graph.add_edge(0, len(truth) - 1, se2_compose(se2_inverse(truth[0]), truth[-1]), LOOP_COV, loop=True)
    kernels = []
    original = PoseGraph._factors

    def spy(self, switchable=False):
        kernels.append(switchable)
        return original(self, switchable)
    monkeypatch.setattr(PoseGraph, "_factors", spy)
    graph.optimize()
    assert kernels == [False]  # no outlier: no switchable step
    graph.add_edge(8, 24, se2_compose(se2_compose(se2_inverse(truth[8]), truth[24]), (1.5, 0.0, 0.2)), LOOP_COV,
                   loop=True)
    kernels.clear()
    graph.optimize()
    assert kernels == [False, True]
    kernels.clear()
    graph.relative_covariances([(8, 24)])
    assert kernels == [False]  # how well poses are known: linearised with Huber's loops, none switched off


def test_relative_is_the_current_estimate():
    graph = PoseGraph()
    graph.add_node((1.0, 0.0, math.pi / 2))
    graph.add_node((1.0, 1.0, math.pi / 2))
    np.testing.assert_allclose(graph.relative(0, 1), [1.0, 0.0, 0.0], atol=1e-12)


def test_bad_edges_and_nodes_name_the_value():
    graph = PoseGraph()
    graph.add_node((0, 0, 0))
    graph.add_node((1, 0, 0))
    with pytest.raises(PoseGraphError, match="edge target 5 is not a node"):
        graph.add_edge(0, 5, (1, 0, 0), ODOM_COV)
    with pytest.raises(PoseGraphError, match="two different nodes"):
        graph.add_edge(1, 1, (0, 0, 0), ODOM_COV)
    with pytest.raises(PoseGraphError, match="positive definite"):
        graph.add_edge(0, 1, (1, 0, 0), np.zeros((3, 3)))
    with pytest.raises(PoseGraphError, match="three finite numbers \\(x, y, yaw\\)"):
        graph.add_node((0, math.nan, 0))



def test_residual_tells_a_true_loop_edge_from_a_wrong_one():
    # The mapper drops a loop edge whose residual after optimising is beyond χ² 16.3: once
    # true closures hold the graph, a wrong one cannot be met.
    truth = square_truth()
    graph = drifting_graph(truth, yaw_drift_rad=0.01)
    true_edges = [graph.add_edge(a, b, se2_compose(se2_inverse(truth[a]), truth[b]), LOOP_COV, loop=True)
                  for a, b in [(0, 32), (2, 30), (4, 28), (8, 24)]]
    graph.optimize()
    assert all(graph.residual_chi2(e) < 16.3 for e in true_edges)
    wrong = se2_compose(se2_compose(se2_inverse(truth[12]), truth[20]), [0.6, -0.4, 0.2])
    false_edge = graph.add_edge(12, 20, wrong, LOOP_COV, loop=True)
    graph.optimize()
    assert graph.residual_chi2(false_edge) > 16.3
