"""The grid planner on synthetic costmaps: optimal against Dijkstra, typed failures, smooth output."""
from __future__ import annotations

import itertools

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
    PlannerTimedOut,
    StartOccupied,
    StartOutsideMap,
)
from pppbot_nav.planner.grid_astar import GridPlanner, PlannerSettings, travel_weights
from pppbot_nav.planner.smoother import SmootherSettings

RES = 0.05


def costmap_of(lethal: np.ndarray, inflation_m: float = 0.55) -> Costmap:
    costs = np.where(lethal, LETHAL_OBSTACLE, 0).astype(np.uint8)
    cm = Costmap(costs, RES, (0.0, 0.0), "map")
    InflationLayer(inflation_m, 3.0, 0.3).update(cm)
    return cm


def random_world(seed: int, size: int = 80) -> Costmap:
    rng = np.random.default_rng(seed)
    lethal = np.zeros((size, size), dtype=bool)
    for _ in range(12):
        r, c = rng.integers(0, size, 2)
        h, w = rng.integers(2, 15, 2)
        lethal[r:r + h, c:c + w] = True
    return costmap_of(lethal)


def cell_at(cells: np.ndarray, rng: np.random.Generator) -> tuple[int, int]:
    r, c = cells[rng.integers(len(cells))]
    return int(r), int(c)


def xy(cm: Costmap, cell: tuple[int, int]) -> tuple[float, float]:
    return (cm.origin[0] + (cell[1] + 0.5) * cm.resolution, cm.origin[1] + (cell[0] + 0.5) * cm.resolution)


def dijkstra_cost(weights: np.ndarray, start: tuple[int, int], goal: tuple[int, int]) -> float:
    """The cheapest 8-connected path cost where entering a cell costs its weight."""
    h, w = weights.shape
    index = np.arange(h * w).reshape(h, w)
    rows, cols, data = [], [], []
    for dr, dc in itertools.product((-1, 0, 1), repeat=2):
        if dr == dc == 0:
            continue
        src = index[max(-dr, 0):h - max(dr, 0), max(-dc, 0):w - max(dc, 0)]
        dst = index[max(dr, 0):h - max(-dr, 0), max(dc, 0):w - max(-dc, 0)]
        cost = weights.ravel()[dst.ravel()]
        ok = np.isfinite(cost)
        rows.append(src.ravel()[ok])
        cols.append(dst.ravel()[ok])
        data.append(cost[ok])
    graph = sparse.csr_matrix((np.concatenate(data), (np.concatenate(rows), np.concatenate(cols))), shape=(h * w,) * 2)
    return float(csgraph.dijkstra(graph, indices=index[start])[index[goal]])


def raw_planner(**kwargs: object) -> GridPlanner:
    return GridPlanner(PlannerSettings(smooth_path=False, **kwargs))  # type: ignore[arg-type]


@pytest.mark.parametrize("seed", range(6))
def test_path_cost_equals_dijkstra(seed: int) -> None:
    cm = random_world(seed)
    planner = raw_planner()
    planner.set_costmap(cm)
    free = np.argwhere(cm.costs == 0)
    rng = np.random.default_rng(100 + seed)
    checked = 0
    for _ in range(10):
        a, b = cell_at(free, rng), cell_at(free, rng)
        expected = dijkstra_cost(planner.weights, a, b)
        if not np.isfinite(expected):
            with pytest.raises(NoValidPath):
                planner.plan(xy(cm, a), xy(cm, b))
            continue
        plan = planner.plan(xy(cm, a), xy(cm, b))
        assert plan.cost == pytest.approx(expected, rel=1e-5)
        checked += 1
    assert checked >= 5


def test_travel_weights_follow_costs_and_unknown_setting() -> None:
    costs = np.array([[0, 126, 252, INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE, NO_INFORMATION]], np.uint8)
    w = travel_weights(costs, 2.0, allow_unknown=True)
    assert w[0, :3] == pytest.approx([1.0, 2.0, 3.0])
    assert np.isinf(w[0, 3]) and np.isinf(w[0, 4]) and 1.0 < w[0, 5] < 3.0
    assert np.isinf(travel_weights(costs, 2.0, allow_unknown=False)[0, 5])


def test_unknown_space_blocks_only_when_not_allowed() -> None:
    costs = np.zeros((40, 40), np.uint8)
    costs[:, 20] = NO_INFORMATION
    cm = Costmap(costs, RES, (0.0, 0.0))
    allowed = raw_planner(allow_unknown=True)
    allowed.set_costmap(cm)
    assert allowed.plan(xy(cm, (20, 5)), xy(cm, (20, 35))).length_m > 1.4
    refused = raw_planner(allow_unknown=False)
    refused.set_costmap(cm)
    with pytest.raises(NoValidPath, match="walled off"):
        refused.plan(xy(cm, (20, 5)), xy(cm, (20, 35)))


def test_failures_are_typed() -> None:
    lethal = np.zeros((60, 60), dtype=bool)
    lethal[:, 30] = True  # a wall splitting the map
    lethal[10, 10] = True
    cm = costmap_of(lethal)
    planner = GridPlanner(PlannerSettings(tolerance=0.0))
    planner.set_costmap(cm)
    with pytest.raises(StartOutsideMap, match="outside the costmap"):
        planner.plan((-1.0, 0.5), (1.0, 1.0))
    with pytest.raises(GoalOutsideMap, match="outside the costmap"):
        planner.plan((0.5, 0.5), (5.0, 1.0))
    with pytest.raises(StartOccupied, match="on an obstacle"):
        planner.plan(xy(cm, (10, 10)), xy(cm, (50, 20)))
    with pytest.raises(GoalOccupied, match="inscribed"):
        planner.plan(xy(cm, (50, 20)), xy(cm, (10, 11)))
    with pytest.raises(NoValidPath):
        planner.plan(xy(cm, (50, 5)), xy(cm, (50, 55)))
    with pytest.raises(StartOutsideMap, match="finite"):
        planner.plan((float("nan"), 0.0), (1.0, 1.0))


def test_timeout_is_typed() -> None:
    ticks = iter(np.arange(0.0, 100.0, 5.0))
    planner = GridPlanner(PlannerSettings(max_planning_time=1.0), clock=lambda: float(next(ticks)))
    cm = costmap_of(np.zeros((30, 30), dtype=bool))
    planner.set_costmap(cm)
    with pytest.raises(PlannerTimedOut, match="max_planning_time"):
        planner.plan((0.2, 0.2), (1.2, 1.2))


def test_start_inside_inflation_leaves_by_the_nearest_free_cell() -> None:
    lethal = np.zeros((60, 60), dtype=bool)
    lethal[:, 30] = True
    cm = costmap_of(lethal)
    start = xy(cm, (20, 27))  # 0.15 m from the wall: inscribed
    assert cm.cost_at(*start, outside=0) == INSCRIBED_INFLATED_OBSTACLE
    planner = GridPlanner()
    planner.set_costmap(cm)
    result = planner.plan(start, xy(cm, (20, 5)))
    assert tuple(result.points_xy[0]) == pytest.approx(start)
    # After the first step the path stays out of the inscribed zone.
    costs = cm.cost_at(result.points_xy[2:, 0], result.points_xy[2:, 1], outside=0)
    assert (costs < INSCRIBED_INFLATED_OBSTACLE).all()


def test_goal_in_inflation_moves_within_tolerance() -> None:
    lethal = np.zeros((60, 60), dtype=bool)
    lethal[:, 30] = True
    cm = costmap_of(lethal)
    goal = xy(cm, (20, 28))
    planner = GridPlanner(PlannerSettings(tolerance=0.5))
    planner.set_costmap(cm)
    plan = planner.plan(xy(cm, (20, 5)), goal)
    assert np.hypot(plan.goal_xy[0] - goal[0], plan.goal_xy[1] - goal[1]) <= 0.5
    assert cm.cost_at(*plan.goal_xy, outside=255) < INSCRIBED_INFLATED_OBSTACLE
    assert tuple(plan.points_xy[-1]) == pytest.approx(plan.goal_xy)


def test_smoothed_path_is_shorter_than_the_cells_and_stays_out_of_the_inscribed_zone() -> None:
    for seed in range(4):
        cm = random_world(seed)
        raw, smooth = raw_planner(), GridPlanner()
        raw.set_costmap(cm)
        smooth.set_costmap(cm)
        free = np.argwhere(cm.costs == 0)
        rng = np.random.default_rng(seed)
        for _ in range(5):
            a, b = xy(cm, cell_at(free, rng)), xy(cm, cell_at(free, rng))
            try:
                cells = raw.plan(a, b)
            except NoValidPath:
                continue
            path = smooth.plan(a, b)
            assert path.length_m <= cells.length_m + 1e-9
            assert path.length_m >= np.hypot(b[0] - a[0], b[1] - a[1]) - 1e-9
            costs = cm.cost_at(path.points_xy[:, 0], path.points_xy[:, 1], outside=LETHAL_OBSTACLE)
            assert (costs < INSCRIBED_INFLATED_OBSTACLE).all()
            assert tuple(path.points_xy[0]) == pytest.approx(a) and tuple(path.points_xy[-1]) == pytest.approx(b)
            steps = np.linalg.norm(np.diff(path.points_xy, axis=0), axis=1)
            assert steps.max() <= 0.1 + 1e-9  # dense for the controller


def test_open_space_path_is_straight() -> None:
    cm = costmap_of(np.zeros((60, 60), dtype=bool))
    planner = GridPlanner()
    planner.set_costmap(cm)
    a, b = (0.3, 0.4), (2.6, 1.9)
    path = planner.plan(a, b).points_xy
    # Every point on the straight segment: the 8-connected staircase is gone.
    d = np.array(b) - np.array(a)
    rel = path - np.array(a)
    off = np.abs(d[0] * rel[:, 1] - d[1] * rel[:, 0]) / np.linalg.norm(d)
    assert off.max() < 1e-6


@pytest.mark.parametrize("settings, name", [
    (PlannerSettings(tolerance=-1.0), "tolerance"),
    (PlannerSettings(cost_travel_multiplier=float("nan")), "cost_travel_multiplier"),
    (PlannerSettings(max_planning_time=0.0), "max_planning_time"),
    (PlannerSettings(smoother=SmootherSettings(w_smooth=0.9)), "smoother.w_smooth"),
    (PlannerSettings(smoother=SmootherSettings(max_its=-1)), "smoother.max_its"),
])
def test_bad_settings_name_the_parameter(settings: PlannerSettings, name: str) -> None:
    with pytest.raises(ParameterError, match=name.replace(".", r"\.")):
        GridPlanner(settings)


def test_near_obstacle_band_weighs_more_and_keeps_paths_off_the_inscribed_zone() -> None:
    costs = np.array([[0, 179, 180, 252, INSCRIBED_INFLATED_OBSTACLE]], np.uint8)
    w = travel_weights(costs, 2.0, allow_unknown=True, near_obstacle_cost=180, near_obstacle_penalty=10.0)
    assert w[0, :2] == pytest.approx([1.0, 1.0 + 2.0 * 179 / 252])
    assert w[0, 2:4] == pytest.approx([10.0 * (1.0 + 2.0 * 180 / 252), 30.0]) and np.isinf(w[0, 4])
    # A 1.1 m door in a wall at x = 2 m, a block just beyond it (x ≥ 2.5, y ≥ 2.1 m): the path from
    # (1, 2) to (3.5, 0.5) turns hard round the door's lower jamb. Without the band it passes
    # 0.35 m from the wall cells' centres; with it, beyond the band (cost 180: about 0.41 m).
    lethal = np.zeros((80, 80), dtype=bool)
    lethal[:, 39:41] = True
    lethal[29:51, 39:41] = False
    lethal[42:, 50:] = True
    cm = costmap_of(lethal)
    wall = np.argwhere(lethal) * RES + RES / 2  # (row, col) centres as (y, x)
    nearest = {}
    for penalty in (1.0, 10.0):
        planner = GridPlanner(PlannerSettings(near_obstacle_penalty=penalty))
        planner.set_costmap(cm)
        points = planner.plan((1.0, 2.0), (3.5, 0.5)).points_xy
        dense = np.vstack([np.linspace(a, b, 10) for a, b in zip(points[:-1], points[1:], strict=True)])
        nearest[penalty] = np.min(np.hypot(dense[:, None, 0] - wall[None, :, 1], dense[:, None, 1] - wall[None, :, 0]))
    assert nearest[1.0] < 0.38 and nearest[10.0] >= 0.40, nearest
