"""Loop closure: searching older keyframes for the place a new one sees, and keeping only the
closures the pose graph can agree with.

:class:`LoopSearch` is one keyframe's search as taken from the mapper (it runs without it, in a
loop-closing thread); :func:`solve_loops` adds its matches to a copy of the pose graph: those
implausible for what the graph already knows, or whose scans see through each other's walls,
are left out (:func:`plausible`); the rest must agree with each other (pairwise consistency,
:func:`consistent_set`); after the solve every loop edge, old or new, is checked again — a
closure the rest cannot agree with goes, and one accepted earlier is undone (:class:`LoopSolution`). No ROS here.
"""
from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import networkx as nx
import numpy as np

from pppbot_common.se2 import se2_apply, se2_compose, se2_inverse, wrap_angles
from pppbot_slam.matcher import ScanMatcher
from pppbot_slam.occupancy import ScanRays
from pppbot_slam.pose_graph import LOOP_OUTLIER_CHI2, Edge, PoseGraph
from pppbot_slam.visibility import View, see_through_fraction, view_of

if TYPE_CHECKING:
    from pppbot_slam.mapper import MapperSettings

#: A loop edge whose residual after optimisation exceeds this (χ² with 3 degrees of freedom,
#: the 99.9 % quantile) disagrees with the rest of the graph and is dropped: the χ² beyond which
#: the back end's switchable solve runs, too.
LOOP_CHI2_MAX = LOOP_OUTLIER_CHI2
#: A loop match must agree with what the graph knows of its two keyframes' relative pose: the
#: difference, in their relative covariance (through the chain and earlier closures) plus the
#: match's, within this χ² (3 degrees of freedom) ...
LOOP_CONSISTENCY_CHI2 = 25.0
#: The covariances that check weighs by, scaled: the matcher's (Karto's spread of good
#: candidates) are wider than its errors, and the relative covariance over a long chain adds
#: them all up. In the tune world maze_000 the running matches' errors against ground truth,
#: weighed by their covariances (NEES), average 0.06 where 3 would be calibrated: the
#: covariances are about 50 times too wide; a tenth leaves a margin for correlated errors.
LOOP_COVARIANCE_SCALE = 0.1
#: ... or be smaller than this (m, rad), whatever the covariances say.
LOOP_AGREE_M = 0.3
LOOP_AGREE_RAD = 0.15
#: A loop match that would move its keyframes more than that must also not have its scans pass
#: through each other's walls on more than this share of the surface hits both had in view
#: (:mod:`pppbot_slam.visibility`): once a long chain without closures has made the relative
#: covariance wide, the check above lets a 1.5 m alias through; this one needs no covariance.
#: Over every loop match of fourteen tune-seed worlds' drives, true closures measured at most
#: 0.8 % and 96 % of the aliases (1–3.5 m off, responses up to 0.92) more than 1 %. Real scans
#: see through people and glass (true closures of the CARMEN logs reach several %), which is
#: why corrections within LOOP_AGREE_M are taken without it.
LOOP_SEE_THROUGH_MAX = 0.01
#: Two closures' allowance grows by this share of the graph's way between their keyframes (m per m):
#: drift of the running matches stays well under 5 % of the way on the logs and worlds.
PAIR_DRIFT = 0.05
#: Two closures agree when the cycle they make through the graph (one closure, the graph from its
#: older keyframe to the other's, the other closure back, the graph to the first's newer keyframe)
#: closes within these (m, rad), plus PAIR_DRIFT of the graph's way between their keyframes.
PAIR_AGREE_M = 0.3
PAIR_AGREE_RAD = 0.1
#: Why a loop match is rejected, as the mapper's health counts it: it disagrees with what the graph
#: knows; its scans see through each other's walls; it disagrees with the other matches (PCM); the
#: solved graph could not meet it.
REJECTIONS = ("disagrees", "see_through", "inconsistent", "residual")
#: A partial-overlap match is judged on at least this many points, whatever the share.
MIN_OVERLAP_POINTS = 20
#: A global match whose good coarse candidates (Karto's covariance) spread further than this
#: (m, standard deviation along their widest direction) has a scan that does not pin where it
#: is (a corridor's length): over a window of ±7 m it could slide anywhere along it.
GLOBAL_MAX_SPREAD_M = 0.3


def spread(covariance: np.ndarray) -> float:
    """The standard deviation (m) of a pose covariance's position along its widest direction."""
    return float(math.sqrt(max(np.linalg.eigvalsh(covariance[:2, :2]).max(), 0.0)))


@dataclass(frozen=True)
class LoopChain:
    indices: np.ndarray  # (C,) consecutive older keyframes
    poses: np.ndarray  # (C, 3) their map poses when the search was taken
    points: np.ndarray  # their hits in the map
    normals: np.ndarray  # and the hits' surface normals
    views: tuple[View, ...] = ()  # their scans where they were taken (empty: not checked for see-through)
    remote: bool = True  # not on the path that led to the search's keyframe (see Mapper.walked_from)
    global_search: bool = False  # matched over the global window (see Mapper.global_loop_search)


@dataclass(frozen=True)
class LoopMatch:
    source: int  # the chain's keyframe nearest the match
    target: int  # the searching keyframe
    relative: np.ndarray  # target's pose in the source's frame
    covariance: np.ndarray  # in the source's frame
    response: float
    see_through: float = 0.0  # the share of hits in view that the other side's beams passed (see LOOP_SEE_THROUGH_MAX)
    partial: bool = False  # taken on the part of the scan the chain saw (see LoopSearch.overlap_response)
    global_search: bool = False  # found over the global window (see Mapper.global_loop_search)


@dataclass(frozen=True)
class LoopSearch:
    """One keyframe's loop search as taken from the mapper: it runs without the mapper (so
    a loop-closing thread can run it while scans go on)."""

    index: int
    pose: np.ndarray  # the keyframe's map pose when the search was taken
    points: np.ndarray  # its hits in the base frame
    normals: np.ndarray
    chains: tuple[LoopChain, ...]
    rays: ScanRays | None = None  # its scan (None: matches are not checked for see-through)
    sensor_offset: np.ndarray = field(default_factory=lambda: np.zeros(3))  # the lidar in the base frame

    def run(self, settings: MapperSettings) -> list[LoopMatch]:
        """Each chain matched in the large window (variance ≤ ``loop_match_maximum_variance_coarse``),
        then finely, unpolished: a closure keeps the pose the search found, on which its checks
        were measured (polished, on the real logs, the closures that got in changed, and no better).

        A chain within ``loop_search_maximum_distance`` is taken as slam_toolbox takes it: coarse
        response ≥ ``loop_match_minimum_response_coarse`` and fine ≥
        ``loop_match_minimum_response_fine``, over the whole scan. A place revisited a few metres
        off (a wide hall crossed on another line) shares only part of what either scan saw, and
        scores low over the whole scan however right the match: a remote chain (within
        ``loop_search_overlap_distance`` when that is above 0, not on the path that led here)
        is also taken when the part of the scan its keyframes had in view is at least
        ``loop_match_minimum_overlap`` of it and scores at least
        ``loop_match_minimum_response_overlap`` (:meth:`overlap_response`).

        A global chain (:meth:`pppbot_slam.mapper.Mapper.global_loop_search`) is matched over
        ``global_loop_matcher``'s window, centred on the keyframe's pose however far its keyframes
        are, and taken at coarse response ≥ ``loop_match_minimum_response_coarse`` and fine ≥
        ``loop_match_minimum_response_global``; a match it cannot pin along some direction (a
        corridor: good poses spread along it, :data:`GLOBAL_MAX_SPREAD_M`) is not taken."""
        matches = []
        wide, near, whole_window = (replace(m, polish_iterations=0) for m in (
            settings.loop_matcher, settings.matcher, settings.global_loop_matcher))
        chains = list(self.chains)
        local = [c for c in chains if not c.global_search]
        if len(local) > 1:  # every pass near here at once: more of what this scan sees (see overlap_response)
            chains.append(LoopChain(np.concatenate([c.indices for c in local]),
                                    np.vstack([c.poses for c in local]), np.vstack([c.points for c in local]),
                                    np.vstack([c.normals for c in local]),
                                    tuple(v for c in local for v in c.views), all(c.remote for c in local)))
        for chain in chains:
            coarse = ScanMatcher(chain.points, whole_window if chain.global_search else wide,
                                 chain.normals).match(self.points, self.pose, self.normals)
            variance = max(coarse.covariance[0, 0], coarse.covariance[1, 1])
            if variance > settings.loop_match_maximum_variance_coarse:
                continue
            if chain.global_search and spread(coarse.covariance) > GLOBAL_MAX_SPREAD_M:
                continue
            close = chain.global_search or float(np.hypot(*(chain.poses[:, :2] - self.pose[:2]).T).min()) \
                <= settings.loop_search_maximum_distance
            fine_matcher = ScanMatcher(chain.points, near, chain.normals)
            fine = fine_matcher.match(self.points, coarse.pose, self.normals)
            required = settings.loop_match_minimum_response_global if chain.global_search \
                else settings.loop_match_minimum_response_fine
            whole = close and coarse.response >= settings.loop_match_minimum_response_coarse \
                and fine.response >= required
            partial = not whole and chain.remote and not chain.global_search \
                and settings.loop_search_overlap_distance > 0
            if not whole and not (partial and self.overlap_response(fine_matcher, chain, fine.pose, settings)
                                  >= settings.loop_match_minimum_response_overlap):
                continue
            k = int(np.argmin(np.hypot(*(chain.poses[:, :2] - fine.pose[:2]).T)))
            matches.append(LoopMatch(int(chain.indices[k]), self.index,
                                     np.asarray(se2_compose(se2_inverse(chain.poses[k]), fine.pose)),
                                     in_frame_of(fine.covariance, float(chain.poses[k][2])), fine.response,
                                     self.see_through(chain, fine.pose, settings.max_laser_range), not whole,
                                     chain.global_search))
        return matches

    def overlap_response(self, matcher: ScanMatcher, chain: LoopChain, pose: np.ndarray,
                         settings: MapperSettings) -> float:
        """The mean likelihood, at ``pose``, of the scan's points the chain's keyframes had in view
        (:meth:`pppbot_slam.visibility.View.in_view`): what both could have seen. 0 when that is
        less than ``loop_match_minimum_overlap`` of the scan (too little to judge by), or when
        the chain's scans are not known."""
        if self.rays is None or not chain.views or not len(self.points):
            return 0.0
        placed = np.asarray(se2_apply(pose, self.points))
        seen = np.zeros(len(placed), dtype=bool)
        for view in chain.views:
            seen |= view.in_view(placed, settings.max_laser_range)[1]
        if seen.sum() < max(MIN_OVERLAP_POINTS, settings.loop_match_minimum_overlap * len(placed)):
            return 0.0
        return float(matcher.likelihoods(self.points[seen], pose, self.normals[seen]).mean())

    def see_through(self, chain: LoopChain, pose: np.ndarray, limit_m: float) -> float:
        """How much this keyframe's scan, at ``pose``, and the chain's scans pass through each other's walls."""
        if self.rays is None or not chain.views:
            return 0.0
        return see_through_fraction(view_of(pose, self.sensor_offset, self.rays), chain.views, limit_m)


@dataclass(frozen=True)
class LoopSolution:
    """What :func:`solve_loops` made of a copy of the mapper's graph and some loop matches."""

    graph: PoseGraph  # solved: the copy's edges (less those undone) and the accepted matches' edges
    accepted: list[LoopMatch]
    rejected: int  # matches left out: implausible for their chain, or disagreeing with the graph
    undone: frozenset[tuple[int, int]]  # earlier closures (source, target) the graph no longer agrees with
    copied_edges: tuple[Edge, ...]  # the copy's edges before the matches (edges added to the mapper since are not)
    #: why the rejected were (REJECTIONS' keys): the counts add up to ``rejected``
    why: dict[str, int] = field(default_factory=dict)


def correction(graph: PoseGraph, match: LoopMatch) -> np.ndarray:
    """How far ``match`` would move its newer keyframe relative to the older one from where the
    graph has it (x, y, yaw in the older keyframe's frame; yaw wrapped)."""
    error = np.asarray(se2_compose(se2_inverse(match.relative), graph.relative(match.source, match.target)))
    error[2] = float(wrap_angles(error[2]))
    return error


def way(graph: PoseGraph, first: int, last: int) -> float:
    """The length (m) of the graph's path of keyframes from ``first`` to ``last`` (either order)."""
    low, high = sorted((first, last))
    poses = np.asarray(graph.poses[low:high + 1])
    return float(np.hypot(*np.diff(poses[:, :2], axis=0).T).sum()) if len(poses) > 1 else 0.0


def pair_consistent(graph: PoseGraph, a: LoopMatch, b: LoopMatch) -> bool:
    """Whether two closures agree (Mangelson et al.'s pairwise consistency, ICRA 2018): ``a``'s
    newer keyframe reached from its older one through ``a`` equals the way round through the
    graph to ``b``'s older keyframe, ``b``, and the graph back to ``a``'s newer one, within
    :data:`PAIR_AGREE_M` / :data:`PAIR_AGREE_RAD` and the drift of those stretches of graph."""
    cycle = se2_compose(se2_compose(se2_inverse(a.relative), graph.relative(a.source, b.source)),
                        se2_compose(b.relative, graph.relative(b.target, a.target)))
    allowed = PAIR_AGREE_M + PAIR_DRIFT * (way(graph, a.source, b.source) + way(graph, b.target, a.target))
    return bool(math.hypot(cycle[0], cycle[1]) <= allowed and abs(float(wrap_angles(cycle[2]))) <= PAIR_AGREE_RAD)


def consistent_set(graph: PoseGraph, matches: Sequence[LoopMatch]) -> list[int]:
    """The indices of the largest set of ``matches`` that all agree pairwise (PCM's maximum clique,
    networkx's branch and bound)."""
    if len(matches) < 2:
        return list(range(len(matches)))
    pairs = nx.Graph()
    pairs.add_nodes_from(range(len(matches)))
    for i in range(len(matches)):
        for j in range(i + 1, len(matches)):
            if pair_consistent(graph, matches[i], matches[j]):
                pairs.add_edge(i, j)
    clique, _ = nx.max_weight_clique(pairs, weight=None)
    return sorted(clique)


def plausible(graph: PoseGraph, matches: list[LoopMatch]) -> list[bool]:
    """Whether each match is plausible (:func:`implausible_why` says nothing against it)."""
    return [why is None for why in implausible_why(graph, matches)]


def implausible_why(graph: PoseGraph, matches: list[LoopMatch]) -> list[str | None]:
    """Whether each match agrees with what the graph already knows (:data:`LOOP_CONSISTENCY_CHI2`,
    :data:`LOOP_AGREE_M`): how far the match would move the newer keyframe relative to the
    older one, weighed by how well the running matches and earlier closures between them pin
    that (their joint marginal covariance). A place that looks the same a few metres away (an
    identical room, the next corridor of a maze) is not taken for a loop the map could not
    have got that wrong. Beyond LOOP_AGREE_M, the match's scans must also not see through
    each other (:data:`LOOP_SEE_THROUGH_MAX`). None for a plausible match, else why not:
    ``"disagrees"`` (with the graph) or ``"see_through"``."""
    covariances = graph.relative_covariances([(m.source, m.target) for m in matches])
    verdicts: list[str | None] = []
    for match, covariance in zip(matches, covariances, strict=True):
        error = correction(graph, match)
        small = math.hypot(error[0], error[1]) <= LOOP_AGREE_M and abs(error[2]) <= LOOP_AGREE_RAD
        weight = LOOP_COVARIANCE_SCALE * (covariance + match.covariance)
        if small:
            verdicts.append(None)
        elif error @ np.linalg.solve(weight, error) > LOOP_CONSISTENCY_CHI2:
            verdicts.append("disagrees")
        else:
            verdicts.append("see_through" if match.see_through > LOOP_SEE_THROUGH_MAX else None)
    return verdicts


def solve_loops(graph: PoseGraph, matches: list[LoopMatch]) -> LoopSolution:
    """Add the plausible matches that agree with each other (:func:`consistent_set`) to ``graph``
    (a copy of the mapper's) as loop edges and optimise it.

    A closure the rest of the graph cannot agree with is a wrong one (an alias of the place):
    after optimising, its residual is far outside its covariance (χ² beyond
    :data:`LOOP_CHI2_MAX`). The loop edge worst by that measure goes, new or accepted
    earlier (a closure that looked right alone can prove wrong once later loops pin the
    graph: it is undone), and the graph is solved again from where it was; until every
    loop edge agrees.
    """
    copied_edges = tuple(graph.edges)
    before = [pose.copy() for pose in graph.poses]
    verdicts = implausible_why(graph, matches)
    why = Counter(v for v in verdicts if v is not None)
    plausible_ones = [m for m, v in zip(matches, verdicts, strict=True) if v is None]
    kept = [plausible_ones[i] for i in consistent_set(graph, plausible_ones)]
    why["inconsistent"] += len(plausible_ones) - len(kept)
    rejected = len(matches) - len(kept)
    added = [(graph.add_edge(m.source, m.target, m.relative, m.covariance, loop=True), m) for m in kept]
    undone: set[tuple[int, int]] = set()

    def drop(edge: Edge) -> None:
        nonlocal added, rejected
        graph.edges = [e for e in graph.edges if e is not edge]
        if any(edge is e for e, _ in added):
            added = [(e, m) for e, m in added if e is not edge]
            rejected += 1
            why["residual"] += 1
        else:
            undone.add((edge.source, edge.target))

    graph.optimize()
    while True:
        loops = [e for e in graph.edges if e.loop]
        chi2 = [graph.residual_chi2(e) for e in loops]
        if chi2 and max(chi2) > LOOP_CHI2_MAX:
            drop(loops[int(np.argmax(chi2))])
        else:
            # A tight closure can be met by straining the chain instead: a chain edge far outside
            # its covariance, between closures. The closure whose removal lets every edge agree goes.
            culprit = _straining_closure(graph, before)
            if culprit is None:
                break
            drop(culprit)
        graph.poses = [pose.copy() for pose in before]
        graph.optimize()
    return LoopSolution(graph, [m for _, m in added], rejected, frozenset(undone), copied_edges,
                        {k: v for k, v in why.items() if v})


def _straining_closure(graph: PoseGraph, start: list[np.ndarray]) -> Edge | None:
    """The loop edge to drop when a chain edge of the solved ``graph`` is strained beyond
    :data:`LOOP_CHI2_MAX`: of the loop edges spanning it, the one without which the graph
    (solved again from ``start``) has every edge within that bound. None when no chain edge is
    strained, fewer than two closures span it (nothing to tell a wrong closure from a slipped
    chain) or no single closure explains it."""
    strained = [e for e in graph.edges if not e.loop and graph.residual_chi2(e) > LOOP_CHI2_MAX]
    if not strained:
        return None
    worst = max(strained, key=graph.residual_chi2)
    low, high = min(worst.source, worst.target), max(worst.source, worst.target)
    spanning = [e for e in graph.edges if e.loop and min(e.source, e.target) <= low and max(e.source, e.target) >= high]
    if len(spanning) < 2:
        return None
    best, best_chi2 = None, LOOP_CHI2_MAX
    for candidate in spanning:
        trial = PoseGraph()
        trial.poses = [pose.copy() for pose in start]
        trial.edges = [e for e in graph.edges if e is not candidate]
        trial.optimize()
        chi2 = max(trial.residual_chi2(e) for e in trial.edges)
        if chi2 <= best_chi2:
            best, best_chi2 = candidate, chi2
    return best


def in_frame_of(covariance: np.ndarray, yaw: float) -> np.ndarray:
    """A map-frame (x, y, yaw) covariance expressed in a frame rotated by ``yaw``."""
    c, s = math.cos(yaw), math.sin(yaw)
    rotation = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    return np.asarray(rotation @ covariance @ rotation.T)
