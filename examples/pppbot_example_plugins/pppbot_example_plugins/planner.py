"""``pppbot_example_plugins::ShortcutPlanner``: pppbot's grid A*, then any-angle shortcuts.

The grid path turns only in 45° steps. Like Theta*'s post-processing, each kept point is joined
to the farthest later point it sees in a straight line over cells cheaper than
``line_of_sight_cost``, so the path runs straight across open space and keeps A*'s route round
obstacles. A planner plugin is a parameters class (the ``pppbot_nav.planners`` entry point):
its fields are the ROS parameters under the plugin's name, ``validate()`` refuses bad values and
``make()`` returns the planner (:mod:`pppbot_nav.planner.interface`).
"""
from __future__ import annotations

import dataclasses
from collections.abc import Collection
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from pppbot_common.params import ParameterError, check_finite_range, param
from pppbot_nav.costmap.grid import Costmap
from pppbot_nav.planner.grid_astar import GridPlanner, PlannerSettings
from pppbot_nav.planner.interface import Plan


def sees(costmap: Costmap, a: np.ndarray, b: np.ndarray, max_cost: int) -> bool:
    """Whether the segment a → b (m) crosses only cells cheaper than ``max_cost`` (sampled at a
    quarter cell; off the grid counts as blocked)."""
    steps = max(2, int(np.ceil(np.linalg.norm(b - a) / (costmap.resolution / 4))) + 1)
    t = np.linspace(0.0, 1.0, steps)[:, None]
    points = a + t * (b - a)
    return bool((costmap.cost_at(points[:, 0], points[:, 1], 255) < max_cost).all())


def shortcut(points: np.ndarray, costmap: Costmap, max_cost: int) -> np.ndarray:
    """``points`` (K, 2) with every run the straight line covers replaced by that line."""
    kept = [0]
    while kept[-1] < len(points) - 1:
        i = kept[-1]
        j = len(points) - 1
        while j > i + 1 and not sees(costmap, points[i], points[j], max_cost):
            j -= 1
        kept.append(j)
    return points[kept]


class ShortcutPlanner:
    def __init__(self, grid: GridPlanner, max_cost: int) -> None:
        self.grid = grid
        self.max_cost = max_cost
        self.costmap: Costmap | None = None

    def set_costmap(self, costmap: Costmap) -> None:
        self.costmap = costmap
        self.grid.set_costmap(costmap)

    def plan(self, start_xy: tuple[float, float], goal_xy: tuple[float, float]) -> Plan:
        plan = self.grid.plan(start_xy, goal_xy)
        assert self.costmap is not None
        corners = shortcut(plan.points_xy, self.costmap, self.max_cost)
        # The controller wants points about a cell apart, as the grid gives them.
        dense = [corners[:1]]
        for a, b in zip(corners[:-1], corners[1:], strict=True):
            n = max(1, int(np.ceil(np.linalg.norm(b - a) / self.costmap.resolution)))
            dense.append(a + np.linspace(0.0, 1.0, n + 1)[1:, None] * (b - a))
        return dataclasses.replace(plan, points_xy=np.concatenate(dense))


@dataclass(frozen=True)
class ShortcutPlannerParameters:
    #: Every parameter may change while the planner server runs (applied at the next plan).
    LIVE_PARAMETERS: ClassVar[Collection[str] | None] = None

    tolerance: float = param(0.5, "how far the goal may move to a reachable cell (m)")
    allow_unknown: bool = param(True, "plan through unknown space")
    line_of_sight_cost: int = param(128, "a shortcut crosses only cells cheaper than this (1..254)")
    max_planning_time: float = param(2.0, "a plan taking longer fails with TIMEOUT (s)")

    def validate(self) -> None:
        if not 1 <= self.line_of_sight_cost <= 254:
            raise ParameterError("line_of_sight_cost", self.line_of_sight_cost, "must be in 1..254")
        check_finite_range("tolerance", self.tolerance, 0.0, 100.0)
        self.settings().validate()

    def settings(self) -> PlannerSettings:
        return PlannerSettings(tolerance=self.tolerance, allow_unknown=self.allow_unknown,
                               max_planning_time=self.max_planning_time, smooth_path=False)

    def make(self) -> ShortcutPlanner:
        return ShortcutPlanner(GridPlanner(self.settings()), self.line_of_sight_cost)
