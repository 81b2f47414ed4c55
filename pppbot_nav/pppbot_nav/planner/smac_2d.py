"""Nav2's Smac 2D planner (``nav2_smac_planner/SmacPlanner2D``, Jazzy): cost-aware A* on the cells.

As Nav2 searches:

* the 8-connected grid (Jazzy's 2D search has the one motion model, Moore's neighbourhood);
  a cell can be entered unless it is inscribed or lethal, or unknown without ``allow_unknown``
  (``GridCollisionChecker`` with the robot's radius: the cell's own cost); the start cell is
  expanded whatever its cost;
* stepping onto a cell of cost ``c`` costs ``1 + cost_travel_multiplier·c/252``, √2 times that
  diagonally (``Node2D::getTraversalCost``); an unknown cell counts as ``c = 255``;
* the heuristic is the Euclidean distance in cells (``Node2D::getHeuristicCost``);
* ``AStarAlgorithm::createPath``: cells are expanded once each in order of cost plus heuristic,
  and the search ends on expanding the goal. Once a queued cell's heuristic is below
  ``tolerance`` (in cells), ``max_on_approach_iterations`` expansions later it returns the path
  to the queued cell of least heuristic; when the queue empties or ``max_iterations``
  expansions are done it returns that path if there is one within tolerance. Else it fails:
  after one expansion with StartOccupied, after ``max_iterations`` with PlannerTimedOut
  ("exceeded maximum iterations"), otherwise with NoValidPath. ``max_iterations`` or
  ``max_on_approach_iterations`` ≤ 0 lifts that limit. With tolerance 0 a goal that cannot be
  entered is GoalOccupied;
* ``downsample_costmap`` with ``downsampling_factor`` ``f``: the search runs on cells ``f``
  times larger, each the highest cost of the cells it covers (``CostmapDownsampler``), and the
  path goes through their centres;
* ``max_planning_time`` is looked at every ``terminal_checking_interval`` expansions.

Where it differs from Nav2:

* the heuristic measures to the goal's cell: Nav2 measures from a cell's index to the goal's
  continuous map coordinates, which puts the goal cell up to 0.7 cell from the goal and makes
  the heuristic overestimate by as much; measured to the cell it is consistent, so the path
  is the cheapest (tests check it against Dijkstra). The tolerance reads the same heuristic;
* running out of time raises PlannerTimedOut (Nav2 reports it as NoValidPath);
* a start on a lethal cell raises StartOccupied (Nav2 plans out of it, as it does here out of
  the inscribed zone); GoalOccupied is raised too when the goal and every cell within
  tolerance cannot be entered (Nav2 searches the whole region first, then says NoValidPath);
* when neither the goal nor a cell within tolerance is in the start's 8-connected region, it
  fails at once with the error Nav2's search of the region ends on (StartOccupied for a
  region of one cell, PlannerTimedOut for one of ``max_iterations`` cells or more, else
  NoValidPath);
* downsampling: a block holding an unknown and a lethal cell is lethal (Nav2's maximum makes
  it unknown, 255 > 254, so that it can be planned through with ``allow_unknown``);
* the path's first point is the start, and its last the goal when the goal's cell was reached
  (Nav2 gives cell centres); ``Plan.cost`` is the search's cost, in straight-cell steps;
* Nav2 smooths the path with its ``smoother.*`` settings: they are accepted and checked here,
  but the core does not smooth (pppbot's smoother server does);
* ``use_final_approach_orientation`` concerns orientations, which are the node's.
"""
from __future__ import annotations

import heapq
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from pppbot_common.params import ParameterError, check_finite_range
from pppbot_nav.costmap.costs import INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE, MAX_NON_OBSTACLE, NO_INFORMATION
from pppbot_nav.costmap.grid import Costmap
from pppbot_nav.planner.errors import (
    GoalOccupied,
    GoalOutsideMap,
    NoValidPath,
    PlannerError,
    PlannerTimedOut,
    StartOccupied,
    StartOutsideMap,
)
from pppbot_nav.planner.grid_astar import Plan

SQRT2 = math.sqrt(2.0)


def _check_bool(name: str, value: object) -> None:
    if not isinstance(value, bool):
        raise ParameterError(name, value, "must be true or false")


def _check_int(name: str, value: object, low: int, high: int) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise ParameterError(name, value, f"must be an integer in [{low}, {high}]")


@dataclass(frozen=True)
class Smac2DSmootherSettings:
    """Nav2's ``smoother.*`` of Smac 2D: checked, not used by the core (see the module doc)."""

    max_iterations: int = 1000
    w_smooth: float = 0.3
    w_data: float = 0.2
    tolerance: float = 1e-10
    do_refinement: bool = True
    refinement_num: int = 2

    def validate(self) -> None:
        _check_int("smoother.max_iterations", self.max_iterations, 0, 10**9)
        check_finite_range("smoother.w_smooth", self.w_smooth, 0.0, 0.5)
        check_finite_range("smoother.w_data", self.w_data, 0.0, 1.0)
        check_finite_range("smoother.tolerance", self.tolerance, 0.0, 1.0)
        _check_bool("smoother.do_refinement", self.do_refinement)
        _check_int("smoother.refinement_num", self.refinement_num, 1, 1000)


@dataclass(frozen=True)
class Smac2DSettings:
    tolerance: float = 0.125  # m
    downsample_costmap: bool = False
    downsampling_factor: int = 1
    allow_unknown: bool = True
    max_iterations: int = 1000000  # ≤ 0: no limit
    max_on_approach_iterations: int = 1000  # ≤ 0: no limit
    terminal_checking_interval: int = 5000  # expansions between looks at the clock
    max_planning_time: float = 2.0  # s
    cost_travel_multiplier: float = 2.0
    use_final_approach_orientation: bool = False  # the node's: orientations are not the core's
    smoother: Smac2DSmootherSettings = field(default_factory=Smac2DSmootherSettings)

    def validate(self) -> None:
        """Raises ParameterError naming a bad value."""
        check_finite_range("tolerance", self.tolerance, 0.0, 100.0)
        _check_bool("downsample_costmap", self.downsample_costmap)
        _check_int("downsampling_factor", self.downsampling_factor, 1, 100)
        _check_bool("allow_unknown", self.allow_unknown)
        _check_int("max_iterations", self.max_iterations, -(2**31), 2**31 - 1)
        _check_int("max_on_approach_iterations", self.max_on_approach_iterations, -(2**31), 2**31 - 1)
        _check_int("terminal_checking_interval", self.terminal_checking_interval, 1, 2**31 - 1)
        check_finite_range("max_planning_time", self.max_planning_time, 0.0, 3600.0, low_open=True)
        check_finite_range("cost_travel_multiplier", self.cost_travel_multiplier, 0.0, 1000.0)
        _check_bool("use_final_approach_orientation", self.use_final_approach_orientation)
        self.smoother.validate()


def downsample(costs: np.ndarray, factor: int) -> np.ndarray:
    """Costs of cells ``factor`` times larger (rounded up at the far edges): the highest cost of
    the cells each covers, lethal and inscribed above unknown."""
    c = np.asarray(costs, dtype=np.uint8)
    if factor == 1:
        return c.copy()
    h, w = c.shape
    hh, ww = -(-h // factor), -(-w // factor)
    known = np.zeros((hh * factor, ww * factor), dtype=np.int16)
    unknown = np.zeros_like(known, dtype=bool)
    known[:h, :w] = np.where(c == NO_INFORMATION, 0, c)
    unknown[:h, :w] = c == NO_INFORMATION
    top = known.reshape(hh, factor, ww, factor).max(axis=(1, 3))
    any_unknown = unknown.reshape(hh, factor, ww, factor).any(axis=(1, 3))
    out = np.where(any_unknown & (top < INSCRIBED_INFLATED_OBSTACLE), NO_INFORMATION, top)
    return out.astype(np.uint8)


def step_weights(costs: np.ndarray, cost_travel_multiplier: float, allow_unknown: bool) -> np.ndarray:
    """The cost (float64, inf: cannot be entered) of a straight step onto each cell."""
    c = np.asarray(costs, dtype=np.uint8)
    blocked = (c == INSCRIBED_INFLATED_OBSTACLE) | (c == LETHAL_OBSTACLE)
    if not allow_unknown:
        blocked |= c == NO_INFORMATION
    weights = 1.0 + cost_travel_multiplier * c.astype(np.float64) / MAX_NON_OBSTACLE
    return np.where(blocked, np.inf, weights)


def failure(iterations: int, max_iterations: int, where: str) -> PlannerError:
    """The error Nav2's SmacPlanner2D raises for a search that failed after ``iterations``."""
    if iterations == 1:
        return StartOccupied(f"no path {where}: the start is walled in")
    if iterations >= max_iterations:
        return PlannerTimedOut(f"no path {where}: exceeded maximum iterations ({max_iterations})")
    return NoValidPath(f"no path {where}: searched every reachable cell ({iterations})")


def astar(weights: np.ndarray, start: tuple[int, int], goal: tuple[int, int], tolerance_cells: float,
          max_iterations: int, max_on_approach: int, check_every: int,
          out_of_time: Callable[[], bool] = lambda: False) -> tuple[list[tuple[int, int]] | None, float, int]:
    """AStarAlgorithm<Node2D>::createPath on ``weights`` (see :func:`step_weights`).

    Returns:
        The cells (row, col) from the start to the goal or to the cell within tolerance (None
        when it failed), their cost, and the number of expansions.

    Raises:
        PlannerTimedOut: ``out_of_time()`` said so (asked every ``check_every`` expansions).
    """
    h, w = weights.shape
    wp = w + 2  # a border of cells that cannot be entered spares the bounds checks
    padded = np.full((h + 2, wp), np.inf)
    padded[1:-1, 1:-1] = weights
    flat = padded.ravel()
    straight, diagonal = flat.tolist(), (flat * SQRT2).tolist()
    g = np.where(np.isfinite(flat), np.inf, -np.inf).tolist()  # -inf: never improved, so never entered
    rows, cols = np.divmod(np.arange(flat.size), wp)
    heuristic = np.hypot(rows - (goal[0] + 1), cols - (goal[1] + 1)).tolist()
    s, t = (start[0] + 1) * wp + start[1] + 1, (goal[0] + 1) * wp + goal[1] + 1
    moves = ((-1, straight), (1, straight), (-wp, straight), (wp, straight),
             (-wp - 1, diagonal), (-wp + 1, diagonal), (wp - 1, diagonal), (wp + 1, diagonal))
    parent = [0] * flat.size
    visited = bytearray(flat.size)
    g[s] = 0.0
    heap: list[tuple[float, int]] = [(0.0, s)]
    pop, push = heapq.heappop, heapq.heappush
    best_h, best = math.inf, -1
    iterations = approach = 0
    end = -1
    while heap and iterations < max_iterations:
        if iterations % check_every == 0 and out_of_time():
            raise PlannerTimedOut(f"the search took longer than max_planning_time ({iterations} expansions)")
        i = pop(heap)[1]
        if visited[i]:
            continue
        iterations += 1
        visited[i] = 1
        if i == t:
            end = i
            break
        if best_h < tolerance_cells:
            approach += 1
            if approach >= max_on_approach:
                end = best
                break
        gi = g[i]
        for off, step in moves:
            j = i + off
            ng = gi + step[j]
            if ng < g[j] and not visited[j]:
                g[j] = ng
                parent[j] = i
                hj = heuristic[j]
                push(heap, (ng + hj, j))
                if hj < best_h:
                    best_h, best = hj, j
    if end < 0 and best_h < tolerance_cells:
        end = best
    if end < 0:
        return None, math.inf, iterations
    cells = [end]
    while cells[-1] != s:
        cells.append(parent[cells[-1]])
    return [(k // wp - 1, k % wp - 1) for k in reversed(cells)], float(g[end]), iterations


class SmacPlanner2D:
    """Plans on the last costmap given; see the module doc."""

    plugin = "nav2_smac_planner::SmacPlanner2D"

    def __init__(self, settings: Smac2DSettings | None = None,
                 clock: Callable[[], float] = time.perf_counter) -> None:
        self.settings = settings if settings is not None else Smac2DSettings()
        self.settings.validate()
        self._clock = clock
        self.costmap: Costmap | None = None
        self.grid: Costmap | None = None  # the costmap searched (downsampled, or a copy)
        self.weights = np.zeros((1, 1))
        self.labels = np.zeros((1, 1), np.int32)

    def set_costmap(self, costmap: Costmap) -> None:
        """Take a new costmap: the searched grid, its step weights and its 8-connected regions."""
        s = self.settings
        factor = s.downsampling_factor if s.downsample_costmap else 1
        self.costmap = costmap
        self.grid = Costmap(downsample(costmap.costs, factor), costmap.resolution * factor, costmap.origin,
                            costmap.frame_id)
        self.weights = step_weights(self.grid.costs, s.cost_travel_multiplier, s.allow_unknown)
        labels, _ = ndimage.label(np.isfinite(self.weights), structure=np.ones((3, 3), dtype=bool))
        self.labels = np.asarray(labels, dtype=np.int32)

    def _check_inside(self, xy: tuple[float, float], what: str) -> None:
        c = self.costmap
        assert c is not None
        error = StartOutsideMap if what == "start" else GoalOutsideMap
        if not all(math.isfinite(v) for v in xy):
            raise error(f"the {what} {xy} is not a finite point")
        if not c.inside(*c.cell_of(xy[0], xy[1])):
            raise error(f"the {what} ({xy[0]:.2f}, {xy[1]:.2f}) is outside the costmap "
                        f"(x {c.origin[0]:.2f} … {c.origin[0] + c.width * c.resolution:.2f}, "
                        f"y {c.origin[1]:.2f} … {c.origin[1] + c.height * c.resolution:.2f} in '{c.frame_id}')")

    def _region(self, start: tuple[int, int]) -> np.ndarray:
        """The cells the search can expand from ``start``: it and its neighbours' regions."""
        h, w = self.labels.shape
        r0, c0 = start
        ids = {int(self.labels[r, c]) for r in range(max(r0 - 1, 0), min(r0 + 2, h))
               for c in range(max(c0 - 1, 0), min(c0 + 2, w)) if self.labels[r, c] > 0}
        region = np.isin(self.labels, list(ids)) if ids else np.zeros(self.labels.shape, dtype=bool)
        region[start] = True
        return region

    def plan(self, start_xy: tuple[float, float], goal_xy: tuple[float, float]) -> Plan:
        """A path from ``start_xy`` to ``goal_xy`` (m, in the costmap's frame).

        Raises:
            StartOutsideMap, GoalOutsideMap: a point off the costmap.
            StartOccupied: the start is on a lethal cell, or walled in.
            GoalOccupied: neither the goal nor a cell within tolerance can be entered.
            NoValidPath: neither the goal nor a cell within tolerance can be reached.
            PlannerTimedOut: ``max_iterations`` expansions, or more than ``max_planning_time``.
            RuntimeError: no costmap yet.
        """
        if self.costmap is None or self.grid is None:
            raise RuntimeError("the planner has no costmap yet")
        t0 = self._clock()
        s, grid = self.settings, self.grid
        self._check_inside(start_xy, "start")
        self._check_inside(goal_xy, "goal")
        if self.costmap.cost_at(start_xy[0], start_xy[1], LETHAL_OBSTACLE) == LETHAL_OBSTACLE:
            raise StartOccupied(f"the start ({start_xy[0]:.2f}, {start_xy[1]:.2f}) is on an obstacle")
        (sr, sc), (gr, gc) = grid.cell_of(start_xy[0], start_xy[1]), grid.cell_of(goal_xy[0], goal_xy[1])
        start, goal = (int(sr), int(sc)), (int(gr), int(gc))
        if start == goal:
            return Plan(np.array([start_xy, goal_xy], dtype=float), 0.0, goal_xy, self._clock() - t0)
        where = f"from ({start_xy[0]:.2f}, {start_xy[1]:.2f}) to ({goal_xy[0]:.2f}, {goal_xy[1]:.2f})"
        tol = s.tolerance / grid.resolution
        max_iterations = s.max_iterations if s.max_iterations > 0 else 2**31 - 1
        rows, cols = np.indices(grid.costs.shape)
        near = np.hypot(rows - goal[0], cols - goal[1]) < tol
        enterable = np.isfinite(self.weights)
        if not enterable[goal] and not bool(np.any(near & enterable)):
            raise GoalOccupied(f"the goal ({goal_xy[0]:.2f}, {goal_xy[1]:.2f}) and every cell within the "
                               f"tolerance of {s.tolerance} m are obstacles or inscribed")
        region = self._region(start)
        near[start] = False
        if not ((region[goal] and enterable[goal]) or bool(np.any(region & near & enterable))):
            raise failure(min(int(region.sum()), max_iterations), max_iterations, where)

        def out_of_time() -> bool:
            return self._clock() - t0 > s.max_planning_time

        cells, cost, iterations = astar(
            self.weights, start, goal, tol, max_iterations,
            s.max_on_approach_iterations if s.max_on_approach_iterations > 0 else 2**31 - 1,
            s.terminal_checking_interval, out_of_time)
        if cells is None:
            raise failure(iterations, max_iterations, where)
        path = np.asarray(cells, dtype=float)
        xy = np.asarray(grid.origin) + (path[:, ::-1] + 0.5) * grid.resolution
        xy[0] = start_xy
        end_xy = goal_xy
        if cells[-1] == goal:
            xy[-1] = goal_xy
        else:
            end_xy = (float(xy[-1, 0]), float(xy[-1, 1]))
        elapsed = self._clock() - t0
        if elapsed > s.max_planning_time:
            raise PlannerTimedOut(f"planning took {elapsed:.3f} s, more than max_planning_time "
                                  f"{s.max_planning_time} s")
        return Plan(xy, cost, end_xy, elapsed)
