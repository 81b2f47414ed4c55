"""The SLAM pose graph: keyframe poses, odometry/matching and loop-closure edges, optimised by GTSAM.

GTSAM (Georgia Tech Smoothing and Mapping) is a well-kept factor-graph library
with Python wheels: each edge is a ``BetweenFactorPose2`` with the matcher's
covariance, the first keyframe is anchored by a tight prior (the map frame is
where mapping started), and Levenberg–Marquardt solves the graph, as
slam_toolbox's Ceres back end does. Loop-closure edges are switchable, in two
graduated steps: a solve with a Huber kernel on them (convex: a true loop far from
the drifted estimate still pulls the graph all the way), then, when a loop edge is
an outlier in that solution, from there a solve with dynamic covariance scaling
(Agarwal et al., ICRA 2013, the closed form of
Sünderhauf and Protzel's switchable constraints), in which a loop the rest of the
graph cannot meet loses its weight instead of bending the graph; odometry and
matching edges are never switched off (docs/slam.md).
No ROS here.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import gtsam
import numpy as np

from pppbot_common.se2 import PoseLike, finite_pose, se2_compose, se2_inverse
from pppbot_slam.errors import PoseGraphError

#: Standard deviation of the anchor on the first keyframe (m, m, rad).
ANCHOR_SIGMAS = (1e-6, 1e-6, 1e-8)
#: Huber threshold on loop-closure edges in the first solve, in standard deviations.
LOOP_HUBER_K = 1.345
#: Dynamic covariance scaling's Φ on loop-closure edges (χ² units): a loop whose χ² at the current
#: estimate is χ² > Φ keeps s = 2Φ / (Φ + χ²) of its standard-deviation weight (its information
#: scaled by s²). Agarwal et al. found Φ from 1 to 10 alike on their benchmarks and recommend 1.
LOOP_DCS_PHI = 1.0
#: The switchable solve runs when, after the Huber solve, a loop edge's χ² (3 degrees of freedom)
#: is beyond this (the 99.9 % quantile; :mod:`pppbot_slam.loops` drops such an edge after the solve): a graph whose
#: loops all agree is solved as before, one with an outlier has it switched off.
LOOP_OUTLIER_CHI2 = 16.3


@dataclass(frozen=True)
class Edge:
    source: int
    target: int
    relative: np.ndarray  # target's pose in the source's frame (x, y, yaw)
    covariance: np.ndarray  # (3, 3) in x, y, yaw
    loop: bool = False


def edge_chi2(edge: Edge, source: np.ndarray, target: np.ndarray) -> float:
    """How far ``target``'s pose relative to ``source``'s is from ``edge``'s measurement, in its
    covariance (χ², 3 degrees of freedom)."""
    error = se2_compose(se2_inverse(edge.relative), se2_compose(se2_inverse(source), target))
    error = np.array([error[0], error[1], math.remainder(float(error[2]), 2 * math.pi)])
    return float(error @ np.linalg.solve(edge.covariance, error))


def _pose(value: PoseLike, what: str) -> np.ndarray:
    return finite_pose(value, what, PoseGraphError)


def _covariance(value: np.ndarray, what: str) -> np.ndarray:
    array = np.asarray(value, dtype=float)
    if array.shape != (3, 3) or not np.isfinite(array).all() or not np.allclose(array, array.T):
        raise PoseGraphError(f"{what} covariance must be a finite symmetric 3×3 matrix, not {value!r}")
    if np.linalg.eigvalsh(array).min() <= 0:
        raise PoseGraphError(f"{what} covariance must be positive definite (eigenvalues "
                             f"{np.linalg.eigvalsh(array).round(12).tolist()})")
    return array


class PoseGraph:
    def __init__(self) -> None:
        self.poses: list[np.ndarray] = []  # current estimate of every node, map frame
        self.edges: list[Edge] = []

    def __len__(self) -> int:
        return len(self.poses)

    def copy(self) -> PoseGraph:
        """A snapshot: later nodes, edges and optimisations of either do not show in the other."""
        other = PoseGraph()
        other.poses = [p.copy() for p in self.poses]
        other.edges = list(self.edges)  # edges are frozen
        return other

    @property
    def loop_closures(self) -> int:
        return sum(e.loop for e in self.edges)

    def add_node(self, pose: PoseLike) -> int:
        """A keyframe at ``pose`` (its initial estimate); returns its index."""
        self.poses.append(_pose(pose, f"node {len(self.poses)}'s pose").copy())
        return len(self.poses) - 1

    def add_edge(self, source: int, target: int, relative: PoseLike, covariance: np.ndarray,
                 loop: bool = False) -> Edge:
        """A constraint: ``target``'s pose seen from ``source`` is ``relative``, with ``covariance``.

        Raises:
            PoseGraphError: unknown node, a self-edge, or a bad pose or covariance.
        """
        for name, index in (("source", source), ("target", target)):
            if not 0 <= index < len(self.poses):
                raise PoseGraphError(f"edge {name} {index} is not a node (the graph has {len(self.poses)})")
        if source == target:
            raise PoseGraphError(f"an edge needs two different nodes, not {source} and {target}")
        edge = Edge(source, target, _pose(relative, "edge relative pose"), _covariance(covariance, "edge"), loop)
        self.edges.append(edge)
        return edge

    def residual_chi2(self, edge: Edge) -> float:
        """How far the current poses are from ``edge``'s measurement, in its covariance (χ²)."""
        return edge_chi2(edge, self.poses[edge.source], self.poses[edge.target])

    def relative(self, source: int, target: int) -> np.ndarray:
        """``target``'s current pose in ``source``'s frame."""
        return np.asarray(se2_compose(se2_inverse(self.poses[source]), self.poses[target]))

    def _factors(self, switchable: bool = False) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values]:
        """The graph as GTSAM factors (anchor, one between-factor per edge) and its current poses;
        loop edges under dynamic covariance scaling, or Huber's kernel when not ``switchable``."""
        graph = gtsam.NonlinearFactorGraph()
        anchor = gtsam.noiseModel.Diagonal.Sigmas(np.array(ANCHOR_SIGMAS))
        graph.add(gtsam.PriorFactorPose2(0, gtsam.Pose2(*self.poses[0]), anchor))
        kernel = gtsam.noiseModel.mEstimator.DCS.Create(LOOP_DCS_PHI) if switchable \
            else gtsam.noiseModel.mEstimator.Huber.Create(LOOP_HUBER_K)
        for edge in self.edges:
            noise: gtsam.noiseModel.Base = gtsam.noiseModel.Gaussian.Covariance(edge.covariance)
            if edge.loop:
                noise = gtsam.noiseModel.Robust.Create(kernel, noise)
            graph.add(gtsam.BetweenFactorPose2(edge.source, edge.target, gtsam.Pose2(*edge.relative), noise))
        values = gtsam.Values()
        for i, pose in enumerate(self.poses):
            values.insert(i, gtsam.Pose2(*pose))
        return graph, values

    def relative_covariances(self, pairs: list[tuple[int, int]]) -> list[np.ndarray]:
        """How well the graph knows each ``target``'s pose relative to its ``source`` (3×3, in
        the relative pose's tangent space, x, y, yaw): from the joint marginal of the two poses
        at the current estimate, through every edge between them (the chain and earlier loops)."""
        if not pairs:
            return []
        graph, values = self._factors()
        marginals = gtsam.Marginals(graph, values)
        covariances = []
        for source, target in pairs:
            joint = gtsam.KeyVector()
            joint.append(source)
            joint.append(target)
            full = marginals.jointMarginalCovariance(joint).fullMatrix()
            between = gtsam.Pose2(*self.poses[source]).between(gtsam.Pose2(*self.poses[target]))
            jacobian = np.hstack([-between.inverse().AdjointMap(), np.eye(3)])
            covariances.append(jacobian @ full @ jacobian.T)
        return covariances

    def _outlier_loop(self, values: gtsam.Values) -> bool:
        """Whether a loop edge is beyond χ² :data:`LOOP_OUTLIER_CHI2` at ``values``."""
        def pose(key: int) -> np.ndarray:
            solved = values.atPose2(key)
            return np.array([solved.x(), solved.y(), solved.theta()])

        return any(edge_chi2(edge, pose(edge.source), pose(edge.target)) > LOOP_OUTLIER_CHI2
                   for edge in self.edges if edge.loop)

    def optimize(self, max_iterations: int = 100) -> float:
        """Solve the graph (Levenberg–Marquardt with Huber's loops, then, when a loop edge is an
        outlier there, with switchable ones from that solution) and update :attr:`poses`; returns
        the final error. The first node stays where it is (anchored).
        """
        if len(self.poses) < 2 or not self.edges:
            return 0.0
        params = gtsam.LevenbergMarquardtParams()
        params.setMaxIterations(max_iterations)
        graph, initial = self._factors()
        result = gtsam.LevenbergMarquardtOptimizer(graph, initial, params).optimize()
        if self._outlier_loop(result):
            graph, _ = self._factors(switchable=True)
            result = gtsam.LevenbergMarquardtOptimizer(graph, result, params).optimize()
        for i in range(len(self.poses)):
            solved = result.atPose2(i)
            self.poses[i] = np.array([solved.x(), solved.y(), math.remainder(solved.theta(), 2 * math.pi)])
        return float(graph.error(result))
