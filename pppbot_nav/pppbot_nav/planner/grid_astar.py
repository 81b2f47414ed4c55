"""A cost-aware A* on a costmap, in the place of Nav2's NavFn / Smac 2D planners.

Each cell is a node of the 8-connected grid; stepping onto a cell costs its weight
``1 + cost_travel_multiplier · cost / 252`` (Smac 2D's travel cost: free space 1, the edge
of the inscribed zone ``1 + cost_travel_multiplier``), inscribed and lethal cells cannot
be entered, and unknown cells weigh as a cost of 128 when ``allow_unknown`` (else they are
walls). Cells of cost ``near_obstacle_cost`` or more (a thin band round the inscribed zone:
180 is about 0.11 m beyond it with Nav2's cost_scaling_factor of 3) weigh
``near_obstacle_penalty`` times more: where there is room the path keeps that band's width
off the inscribed zone, which is what the controller's collision check and localization
error need; where there is not (a narrow door), it still goes through. Smac 2D and NavFn have
no such band, and their paths graze the inscribed zone round every corner. The search itself
is pyastar2d's C++ A* (a diagonal step costs as much as a straight one, which its L∞
heuristic keeps admissible); :mod:`pppbot_nav.planner.smoother` then
straightens the cell path into an any-angle one under the same travel cost, and rounds it.

Around the search:

* the traversable cells' 8-connected components are labelled once per costmap, so a goal
  that cannot be reached fails at once instead of after a search of the whole map;
* a start inside the inscribed zone (the robot has drifted close to a wall) leaves by the
  nearest traversable cell within ``ESCAPE_RADIUS_M``; a start on a lethal cell fails;
* a goal that cannot be entered is moved to the nearest reachable cell within ``tolerance``
  (Nav2's NavFn ``tolerance``).
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pyastar2d
from scipy import ndimage

from pppbot_common.params import check_finite_range
from pppbot_nav.costmap.costs import INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE, MAX_NON_OBSTACLE, NO_INFORMATION
from pppbot_nav.costmap.grid import Costmap
from pppbot_nav.planner.errors import (
    GoalOccupied,
    GoalOutsideMap,
    NoValidPath,
    PlannerTimedOut,
    StartOccupied,
    StartOutsideMap,
)
from pppbot_nav.planner.interface import Plan
from pppbot_nav.planner.smoother import SmootherSettings, shortcut, smooth

#: How far (m) a start inside the inscribed zone may move to reach a traversable cell.
ESCAPE_RADIUS_M = 0.5
#: The cost an unknown cell weighs as, when unknown space may be planned through.
UNKNOWN_AS_COST = 128


@dataclass(frozen=True)
class PlannerSettings:
    tolerance: float = 0.5  # m: how far the goal may move to a reachable cell
    allow_unknown: bool = True
    cost_travel_multiplier: float = 2.0
    max_planning_time: float = 2.0  # s
    near_obstacle_cost: int = 180
    near_obstacle_penalty: float = 10.0
    smooth_path: bool = True
    smoother: SmootherSettings = SmootherSettings()

    def validate(self) -> None:
        """Raises ParameterError naming a bad value."""
        check_finite_range("tolerance", self.tolerance, 0.0, 100.0)
        check_finite_range("cost_travel_multiplier", self.cost_travel_multiplier, 0.0, 1000.0)
        check_finite_range("max_planning_time", self.max_planning_time, 0.0, 3600.0, low_open=True)
        check_finite_range("near_obstacle_cost", self.near_obstacle_cost, 1, INSCRIBED_INFLATED_OBSTACLE)
        check_finite_range("near_obstacle_penalty", self.near_obstacle_penalty, 1.0, 1000.0)
        self.smoother.validate()




def travel_weights(costs: np.ndarray, cost_travel_multiplier: float, allow_unknown: bool,
                   near_obstacle_cost: int = INSCRIBED_INFLATED_OBSTACLE,
                   near_obstacle_penalty: float = 1.0) -> np.ndarray:
    """float32 weight of stepping onto each cell (inf: cannot be entered); see the module doc."""
    c = np.asarray(costs, dtype=np.uint8)
    known = c.astype(np.float32)
    if allow_unknown:
        known = np.where(c == NO_INFORMATION, np.float32(UNKNOWN_AS_COST), known)
    weights = 1.0 + cost_travel_multiplier * known / MAX_NON_OBSTACLE
    near = (c >= near_obstacle_cost) & (c < INSCRIBED_INFLATED_OBSTACLE)
    weights = np.where(near, weights * np.float32(near_obstacle_penalty), weights)
    blocked = (c == INSCRIBED_INFLATED_OBSTACLE) | (c == LETHAL_OBSTACLE)
    if not allow_unknown:
        blocked |= c == NO_INFORMATION
    return np.where(blocked, np.inf, weights).astype(np.float32)


class GridPlanner:
    def __init__(self, settings: PlannerSettings = PlannerSettings(),
                 clock: Callable[[], float] = time.perf_counter) -> None:
        settings.validate()
        self.settings = settings
        self._clock = clock
        self.costmap: Costmap | None = None
        self.weights = np.zeros((1, 1), np.float32)
        self.components = np.zeros((1, 1), np.int32)

    def set_costmap(self, costmap: Costmap) -> None:
        """Take a new costmap: its weights and its traversable components."""
        s = self.settings
        self.costmap = costmap
        self.weights = travel_weights(costmap.costs, s.cost_travel_multiplier, s.allow_unknown,
                                      s.near_obstacle_cost, s.near_obstacle_penalty)
        labels, _ = ndimage.label(np.isfinite(self.weights), structure=np.ones((3, 3), dtype=bool))
        self.components = np.asarray(labels, dtype=np.int32)

    def _cell(self, xy: tuple[float, float], what: str) -> tuple[int, int]:
        assert self.costmap is not None
        if not all(math.isfinite(v) for v in xy):
            raise (StartOutsideMap if what == "start" else GoalOutsideMap)(f"the {what} {xy} is not a finite point")
        row, col = self.costmap.cell_of(xy[0], xy[1])
        if not self.costmap.inside(row, col):
            c = self.costmap
            raise (StartOutsideMap if what == "start" else GoalOutsideMap)(
                f"the {what} ({xy[0]:.2f}, {xy[1]:.2f}) is outside the costmap "
                f"(x {c.origin[0]:.2f} … {c.origin[0] + c.width * c.resolution:.2f}, "
                f"y {c.origin[1]:.2f} … {c.origin[1] + c.height * c.resolution:.2f} in '{c.frame_id}')")
        return int(row), int(col)

    def _nearest(self, cell: tuple[int, int], radius_m: float,
                 allowed: np.ndarray | None = None) -> tuple[int, int] | None:
        """The nearest traversable cell (in ``allowed``, if given) within ``radius_m`` of ``cell``."""
        assert self.costmap is not None
        r = int(math.ceil(radius_m / self.costmap.resolution))
        r0, c0 = max(cell[0] - r, 0), max(cell[1] - r, 0)
        window = np.isfinite(self.weights[r0:cell[0] + r + 1, c0:cell[1] + r + 1])
        if allowed is not None:
            window &= allowed[r0:cell[0] + r + 1, c0:cell[1] + r + 1]
        rows, cols = np.nonzero(window)
        if rows.size == 0:
            return None
        d2 = (rows + r0 - cell[0]) ** 2 + (cols + c0 - cell[1]) ** 2
        best = int(np.argmin(d2))
        if d2[best] > r * r:
            return None
        return int(rows[best] + r0), int(cols[best] + c0)

    def _centre(self, cell: tuple[int, int]) -> tuple[float, float]:
        assert self.costmap is not None
        res = self.costmap.resolution
        return (self.costmap.origin[0] + (cell[1] + 0.5) * res, self.costmap.origin[1] + (cell[0] + 0.5) * res)

    def plan(self, start_xy: tuple[float, float], goal_xy: tuple[float, float]) -> Plan:
        """A path from ``start_xy`` to ``goal_xy`` (m, in the costmap's frame).

        Raises:
            StartOutsideMap, GoalOutsideMap: a point off the costmap.
            StartOccupied: the start is on a lethal cell, or inscribed with no way out nearby.
            GoalOccupied: no traversable cell within ``tolerance`` of the goal.
            NoValidPath: the goal (or every cell within tolerance) cannot be reached.
            PlannerTimedOut: the search took longer than ``max_planning_time``.
            RuntimeError: no costmap yet.
        """
        if self.costmap is None:
            raise RuntimeError("the planner has no costmap yet")
        t0 = self._clock()
        s = self.settings
        start = self._cell(start_xy, "start")
        goal = self._cell(goal_xy, "goal")
        costs = self.costmap.costs
        leave = start
        if not np.isfinite(self.weights[start]):
            if costs[start] == LETHAL_OBSTACLE:
                raise StartOccupied(f"the start ({start_xy[0]:.2f}, {start_xy[1]:.2f}) is on an obstacle")
            escape = self._nearest(start, ESCAPE_RADIUS_M)
            if escape is None:
                raise StartOccupied(f"the start ({start_xy[0]:.2f}, {start_xy[1]:.2f}) is inside the inflation "
                                    f"with no free cell within {ESCAPE_RADIUS_M} m")
            leave = escape
        component = self.components == self.components[leave]
        target = goal
        if not (np.isfinite(self.weights[goal]) and component[goal]):
            blocked = not np.isfinite(self.weights[goal])
            near = self._nearest(goal, s.tolerance, component)
            if near is None:
                where = f"({goal_xy[0]:.2f}, {goal_xy[1]:.2f})"
                if blocked and self._nearest(goal, s.tolerance) is None:
                    raise GoalOccupied(f"the goal {where} is in an obstacle or its inscribed zone, with no free "
                                       f"cell within the tolerance of {s.tolerance} m")
                raise NoValidPath(f"no path from ({start_xy[0]:.2f}, {start_xy[1]:.2f}) to {where}: the goal "
                                  f"cannot be reached (walled off from the start)")
            target = near
        cells = pyastar2d.astar_path(self.weights, leave, target, allow_diagonal=True)
        elapsed = self._clock() - t0
        if elapsed > s.max_planning_time:
            raise PlannerTimedOut(f"planning took {elapsed:.3f} s, more than max_planning_time "
                                  f"{s.max_planning_time} s")
        if cells is None:  # the components say it is reachable; kept as a safeguard
            raise NoValidPath(f"no path from ({start_xy[0]:.2f}, {start_xy[1]:.2f}) to "
                              f"({goal_xy[0]:.2f}, {goal_xy[1]:.2f})")
        cells = np.asarray(cells, dtype=int)
        cost = float(self.weights[cells[1:, 0], cells[1:, 1]].sum())
        res = self.costmap.resolution
        centres = np.column_stack([self.costmap.origin[0] + (cells[:, 1] + 0.5) * res,
                                   self.costmap.origin[1] + (cells[:, 0] + 0.5) * res])
        goal_point = goal_xy if target == goal else self._centre(target)
        points = np.vstack([start_xy, centres[1:-1], goal_point]) if len(centres) > 1 else \
            np.array([start_xy, goal_point], dtype=float)
        if leave != start:
            points = np.vstack([start_xy, centres[:1], points[1:]]) if len(centres) > 1 else points
        if s.smooth_path:
            points = shortcut(points, self.costmap, self.weights)
            points = smooth(points, self.costmap, s.smoother)
        return Plan(points, cost, (float(goal_point[0]), float(goal_point[1])), self._clock() - t0)
