"""Smac 2D's A* on synthetic costmaps: optimal against Dijkstra on the same step costs, Nav2's
tolerance and iteration limits, downsampling, typed failures."""
from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy import sparse
from scipy.sparse import csgraph

from pppbot_common.params import ParameterError
from pppbot_nav.costmap.costs import INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE, NO_INFORMATION
from pppbot_nav.costmap.grid import Costmap
from pppbot_nav.costmap.layers import InflationLayer
from pppbot_nav.planner.errors import (
    GoalOccupied,
    GoalOutsideMap,
    NoValidPath,
    PlannerError,
    PlannerTimedOut,
    StartOccupied,
    StartOutsideMap,
)
from pppbot_nav.planner.smac_2d import (
    Smac2DSettings,
    Smac2DSmootherSettings,
    SmacPlanner2D,
    astar,
    downsample,
    failure,
    step_weights,
)

RES = 0.05


def costmap_of(lethal: np.ndarray, unknown: np.ndarray | None = None, inflation_m: float = 0.55) -> Costmap:
    costs = np.where(lethal, LETHAL_OBSTACLE, 0).astype(np.uint8)
    cm = Costmap(costs, RES, (0.0, 0.0), "map")
    InflationLayer(inflation_m, 3.0, 0.3).update(cm)
    if unknown is not None:
        cm.costs[unknown & (cm.costs == 0)] = NO_INFORMATION
    return cm


def random_world(seed: int, size: int = 70) -> Costmap:
    rng = np.random.default_rng(seed)
    lethal = np.zeros((size, size), dtype=bool)
    for _ in range(10):
        r, c = rng.integers(0, size, 2)
        h, w = rng.integers(2, 12, 2)
        lethal[r:r + h, c:c + w] = True
    unknown = np.zeros_like(lethal)
    r, c = rng.integers(0, size - 15, 2)
    unknown[r:r + 15, c:c + 15] = True
    return costmap_of(lethal, unknown)


def xy(cm: Costmap, cell: tuple[int, int]) -> tuple[float, float]:
    return (cm.origin[0] + (cell[1] + 0.5) * cm.resolution, cm.origin[1] + (cell[0] + 0.5) * cm.resolution)


def pick(cells: np.ndarray, rng: np.random.Generator) -> tuple[int, int]:
    r, c = cells[rng.integers(len(cells))]
    return int(r), int(c)


def dijkstra(step: np.ndarray, start: tuple[int, int]) -> np.ndarray:
    """Cheapest costs (same shape) from ``start`` on the 8-connected grid, a move onto a cell costing
    its ``step`` times the move's length (1 or √2); inf cells cannot be entered."""
    h, w = step.shape
    index = np.arange(h * w).reshape(h, w)
    rows, cols, data = [], [], []
    for dr, dc in itertools.product((-1, 0, 1), repeat=2):
        if dr == dc == 0:
            continue
        src = index[max(-dr, 0):h - max(dr, 0), max(-dc, 0):w - max(dc, 0)]
        dst = index[max(dr, 0):h - max(-dr, 0), max(dc, 0):w - max(-dc, 0)]
        cost = step.ravel()[dst.ravel()] * math.hypot(dr, dc)
        ok = np.isfinite(cost)
        rows.append(src.ravel()[ok])
        cols.append(dst.ravel()[ok])
        data.append(cost[ok])
    graph = sparse.csr_matrix((np.concatenate(data), (np.concatenate(rows), np.concatenate(cols))), shape=(h * w,) * 2)
    return np.asarray(csgraph.dijkstra(graph, indices=index[start])).reshape(h, w)


def planner_for(cm: Costmap, **kwargs: object) -> SmacPlanner2D:
    planner = SmacPlanner2D(Smac2DSettings(**kwargs))  # type: ignore[arg-type]
    planner.set_costmap(cm)
    return planner


def test_step_weights_are_node2d_travel_costs() -> None:
    costs = np.array([[0, 126, 252, INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE, NO_INFORMATION]], np.uint8)
    w = step_weights(costs, 2.0, allow_unknown=True)
    assert w[0, :3] == pytest.approx([1.0, 2.0, 3.0])
    assert np.isinf(w[0, 3]) and np.isinf(w[0, 4])
    assert w[0, 5] == pytest.approx(1.0 + 2.0 * 255 / 252)  # unknown weighs its raw 255
    assert np.isinf(step_weights(costs, 2.0, allow_unknown=False)[0, 5])


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("multiplier", [0.0, 2.0, 7.5])
def test_path_cost_is_dijkstra_optimal(seed: int, multiplier: float) -> None:
    # The heuristic (Euclidean distance in cells) never exceeds the cost of a step (≥ its length),
    # so A* is exact: its cost equals Dijkstra's to float rounding.
    cm = random_world(seed)
    planner = planner_for(cm, cost_travel_multiplier=multiplier, tolerance=0.0)
    free = np.argwhere(cm.costs < INSCRIBED_INFLATED_OBSTACLE)
    rng = np.random.default_rng(seed)
    checked = 0
    for _ in range(6):
        a, b = pick(free, rng), pick(free, rng)
        expected = dijkstra(planner.weights, a)[b]
        if not np.isfinite(expected):
            with pytest.raises(NoValidPath):
                planner.plan(xy(cm, a), xy(cm, b))
            continue
        plan = planner.plan(xy(cm, a), xy(cm, b))
        assert plan.cost == pytest.approx(expected, rel=1e-9, abs=1e-9)
        cells = np.asarray(cm.cell_of(plan.points_xy[:, 0], plan.points_xy[:, 1])).T
        steps = np.abs(np.diff(cells, axis=0))
        assert steps.max() == 1  # 8-connected moves
        lengths = np.hypot(steps[:, 0], steps[:, 1])
        assert float((lengths * planner.weights[cells[1:, 0], cells[1:, 1]]).sum()) == pytest.approx(plan.cost)
        assert (cm.costs[cells[1:, 0], cells[1:, 1]] < INSCRIBED_INFLATED_OBSTACLE).all()
        checked += 1
    assert checked >= 3


def test_path_starts_at_the_start_and_ends_at_the_goal() -> None:
    cm = costmap_of(np.zeros((40, 40), dtype=bool))
    planner = planner_for(cm)
    plan = planner.plan((0.32, 0.41), (1.63, 1.22))
    assert tuple(plan.points_xy[0]) == (0.32, 0.41) and tuple(plan.points_xy[-1]) == (1.63, 1.22)
    assert plan.goal_xy == (1.63, 1.22)
    # In between: the centres of the cells.
    inner = (plan.points_xy[1:-1] / RES) % 1.0
    assert inner == pytest.approx(np.full_like(inner, 0.5))


def test_start_and_goal_in_one_cell() -> None:
    planner = planner_for(costmap_of(np.zeros((20, 20), dtype=bool)))
    plan = planner.plan((0.51, 0.52), (0.53, 0.54))
    assert plan.points_xy.tolist() == [[0.51, 0.52], [0.53, 0.54]] and plan.cost == 0.0


def walled_gap(gap: int) -> np.ndarray:
    """A 60 × 60 map with a lethal wall along row 30 and an unknown stretch (columns 25 … 34)."""
    costs = np.zeros((60, 60), np.uint8)
    costs[30, :] = LETHAL_OBSTACLE
    costs[30, 25:35] = NO_INFORMATION
    costs[30, 50:50 + gap] = 0  # a free gap round the side
    return costs


def test_unknown_cells_are_crossed_only_when_allowed() -> None:
    cm = Costmap(walled_gap(5), RES, (0.0, 0.0))
    start, goal = xy(cm, (10, 30)), xy(cm, (50, 30))
    through = planner_for(cm, allow_unknown=True).plan(start, goal).points_xy
    around = planner_for(cm, allow_unknown=False).plan(start, goal).points_xy
    assert (cm.cost_at(through[:, 0], through[:, 1], 0) == NO_INFORMATION).any()
    assert (cm.cost_at(around[:, 0], around[:, 1], 0) != NO_INFORMATION).all()
    closed = Costmap(walled_gap(0), RES, (0.0, 0.0))
    with pytest.raises(NoValidPath):
        planner_for(closed, allow_unknown=False).plan(start, goal)


def test_blocked_goal_moves_within_tolerance() -> None:
    lethal = np.zeros((60, 60), dtype=bool)
    lethal[25:35, 40:50] = True
    cm = costmap_of(lethal, inflation_m=0.0)
    goal = xy(cm, (30, 44))  # 4 cells inside the block's left side
    plan = planner_for(cm, tolerance=0.3).plan(xy(cm, (30, 5)), goal)
    end = np.asarray(cm.cell_of(*plan.goal_xy))
    assert np.hypot(*(end - (30, 44))) < 0.3 / RES
    assert cm.costs[end[0], end[1]] == 0
    assert tuple(plan.points_xy[-1]) == pytest.approx(plan.goal_xy)
    with pytest.raises(GoalOccupied, match="tolerance of 0.0 m"):
        planner_for(cm, tolerance=0.0).plan(xy(cm, (30, 5)), goal)
    with pytest.raises(GoalOccupied, match="tolerance of 0.15 m"):
        planner_for(cm, tolerance=0.15).plan(xy(cm, (30, 5)), goal)


def test_walled_off_goal_within_tolerance_of_reachable_cells() -> None:
    lethal = np.zeros((60, 60), dtype=bool)
    lethal[20:41, 20] = lethal[20:41, 40] = lethal[20, 20:41] = lethal[40, 20:41] = True
    cm = costmap_of(lethal, inflation_m=0.0)
    goal = xy(cm, (30, 38))  # free, inside the box
    with pytest.raises(NoValidPath, match="searched every reachable cell"):
        planner_for(cm, tolerance=0.05).plan(xy(cm, (5, 5)), goal)
    plan = planner_for(cm, tolerance=0.2).plan(xy(cm, (5, 5)), goal)
    end = np.asarray(cm.cell_of(*plan.goal_xy))
    assert tuple(end) == (30, 41)  # the nearest reachable cell, just outside the wall


def test_walled_in_start_is_occupied() -> None:
    lethal = np.zeros((30, 30), dtype=bool)
    lethal[9:12, 9:12] = True
    lethal[10, 10] = False
    cm = costmap_of(lethal, inflation_m=0.0)
    with pytest.raises(StartOccupied, match="walled in"):
        planner_for(cm).plan(xy(cm, (10, 10)), xy(cm, (25, 25)))
    # Nav2's own search ends so: one expansion, nothing queued.
    cells, _, iterations = astar(step_weights(cm.costs, 2.0, True), (10, 10), (25, 25), 0.0, 10**6, 1000, 5000)
    assert cells is None and iterations == 1


def test_max_iterations_exhausted_times_out() -> None:
    cm = costmap_of(np.zeros((60, 60), dtype=bool))
    planner = planner_for(cm, max_iterations=20)
    with pytest.raises(PlannerTimedOut, match="exceeded maximum iterations"):
        planner.plan(xy(cm, (5, 5)), xy(cm, (55, 55)))
    # A limit the search stays within: no effect; ≤ 0 lifts the limit.
    assert planner_for(cm, max_iterations=60).plan(xy(cm, (5, 5)), xy(cm, (55, 55))).cost > 0
    assert planner_for(cm, max_iterations=-1).plan(xy(cm, (5, 5)), xy(cm, (55, 55))).cost > 0


@pytest.mark.parametrize("max_iterations", [10, 100000])
def test_unreachable_goal_fails_as_a_full_search_does(max_iterations: int) -> None:
    lethal = np.zeros((40, 40), dtype=bool)
    lethal[:, 20] = True
    cm = costmap_of(lethal, inflation_m=0.0)
    start, goal = (10, 5), (10, 35)
    _, _, iterations = astar(step_weights(cm.costs, 2.0, True), start, goal, 0.125 / RES, max_iterations, 1000, 5000)
    expected = type(failure(iterations, max_iterations, ""))
    with pytest.raises(expected):
        planner_for(cm, max_iterations=max_iterations).plan(xy(cm, start), xy(cm, goal))
    assert expected is (PlannerTimedOut if max_iterations == 10 else NoValidPath)


def test_on_approach_iterations_end_the_search_near_a_blocked_goal() -> None:
    lethal = np.zeros((60, 60), dtype=bool)
    lethal[25:35, 40:50] = True
    w = step_weights(costmap_of(lethal, inflation_m=0.0).costs, 2.0, True)
    full = astar(w, (30, 5), (30, 44), 6.0, 10**6, 10**6, 5000)
    early = astar(w, (30, 5), (30, 44), 6.0, 10**6, 3, 5000)
    assert full[0] is not None and early[0] is not None
    assert early[2] < full[2]
    assert math.hypot(early[0][-1][0] - 30, early[0][-1][1] - 44) < 6.0


def test_planning_time_limit() -> None:
    ticks = iter(np.arange(0.0, 100.0, 5.0))
    planner = SmacPlanner2D(Smac2DSettings(max_planning_time=1.0), clock=lambda: float(next(ticks)))
    planner.set_costmap(costmap_of(np.zeros((30, 30), dtype=bool)))
    with pytest.raises(PlannerTimedOut, match="max_planning_time"):
        planner.plan((0.2, 0.2), (1.2, 1.2))


def test_downsample_takes_the_highest_cost_lethal_over_unknown() -> None:
    costs = np.array([[0, 10, 0, NO_INFORMATION, 5],
                      [20, 0, LETHAL_OBSTACLE, NO_INFORMATION, 7],
                      [0, 0, 0, 0, 0]], np.uint8)
    assert downsample(costs, 2).tolist() == [[20, LETHAL_OBSTACLE, 7], [0, 0, 0]]
    assert downsample(costs, 1).tolist() == costs.tolist()
    assert downsample(np.array([[0, NO_INFORMATION]], np.uint8), 2).tolist() == [[NO_INFORMATION]]


def test_downsampled_search_runs_on_the_coarse_cells() -> None:
    cm = random_world(3, size=80)
    planner = planner_for(cm, downsample_costmap=True, downsampling_factor=2, tolerance=0.0)
    assert planner.grid is not None and planner.grid.costs.shape == (40, 40)
    assert planner.grid.resolution == pytest.approx(2 * RES)
    free = np.argwhere(planner.grid.costs < INSCRIBED_INFLATED_OBSTACLE)
    rng = np.random.default_rng(3)
    a, b = pick(free, rng), pick(free, rng)
    expected = dijkstra(planner.weights, a)[b]
    assert np.isfinite(expected)
    plan = planner.plan(xy(planner.grid, a), xy(planner.grid, b))
    assert plan.cost == pytest.approx(expected, rel=1e-9)
    inner = (plan.points_xy[1:-1] / (2 * RES)) % 1.0
    assert inner == pytest.approx(np.full_like(inner, 0.5))


def test_failures_are_typed() -> None:
    lethal = np.zeros((60, 60), dtype=bool)
    lethal[10, 10] = True
    cm = costmap_of(lethal)
    planner = planner_for(cm)
    with pytest.raises(StartOutsideMap, match="outside the costmap"):
        planner.plan((-1.0, 0.5), (1.0, 1.0))
    with pytest.raises(GoalOutsideMap, match="outside the costmap"):
        planner.plan((0.5, 0.5), (5.0, 1.0))
    with pytest.raises(StartOutsideMap, match="finite"):
        planner.plan((float("nan"), 0.0), (1.0, 1.0))
    with pytest.raises(StartOccupied, match=r"\(0.53, 0.53\) is on an obstacle"):
        planner.plan(xy(cm, (10, 10)), xy(cm, (50, 20)))
    with pytest.raises(GoalOccupied, match=r"\(0.53, 0.53\)"):
        planner.plan(xy(cm, (50, 20)), xy(cm, (10, 10)))
    with pytest.raises(RuntimeError, match="no costmap"):
        SmacPlanner2D().plan((0.0, 0.0), (1.0, 1.0))
    assert issubclass(PlannerTimedOut, PlannerError)


@pytest.mark.parametrize("settings, name", [
    (Smac2DSettings(tolerance=-0.1), "tolerance"),
    (Smac2DSettings(downsampling_factor=0), "downsampling_factor"),
    (Smac2DSettings(downsampling_factor=2.0), "downsampling_factor"),  # type: ignore[arg-type]
    (Smac2DSettings(downsample_costmap=1), "downsample_costmap"),  # type: ignore[arg-type]
    (Smac2DSettings(allow_unknown="yes"), "allow_unknown"),  # type: ignore[arg-type]
    (Smac2DSettings(max_iterations=1.5), "max_iterations"),  # type: ignore[arg-type]
    (Smac2DSettings(max_on_approach_iterations=True), "max_on_approach_iterations"),
    (Smac2DSettings(terminal_checking_interval=0), "terminal_checking_interval"),
    (Smac2DSettings(max_planning_time=0.0), "max_planning_time"),
    (Smac2DSettings(cost_travel_multiplier=-1.0), "cost_travel_multiplier"),
    (Smac2DSettings(use_final_approach_orientation=None), "use_final_approach_orientation"),  # type: ignore[arg-type]
    (Smac2DSettings(smoother=Smac2DSmootherSettings(w_smooth=0.9)), "smoother.w_smooth"),
    (Smac2DSettings(smoother=Smac2DSmootherSettings(refinement_num=0)), "smoother.refinement_num"),
])
def test_bad_settings_name_the_parameter(settings: Smac2DSettings, name: str) -> None:
    with pytest.raises(ParameterError) as raised:
        SmacPlanner2D(settings)
    assert raised.value.name == name


def test_defaults_are_nav2s() -> None:
    s = Smac2DSettings()
    assert (s.tolerance, s.downsample_costmap, s.downsampling_factor, s.allow_unknown) == (0.125, False, 1, True)
    assert (s.max_iterations, s.max_on_approach_iterations, s.terminal_checking_interval) == (1000000, 1000, 5000)
    assert (s.max_planning_time, s.cost_travel_multiplier, s.use_final_approach_orientation) == (2.0, 2.0, False)
