"""The planner server's plugins by Nav2's type name: their parameters (Nav2's names and defaults,
under the plugin's name) and the planners they make.

* ``nav2_navfn_planner::NavfnPlanner`` (:mod:`pppbot_nav.planner.navfn`), Nav2's default;
* ``nav2_smac_planner::SmacPlanner2D`` (:mod:`pppbot_nav.planner.smac_2d`), its path smoothed
  as Smac's own smoother does (Nav2's simple smoother with its ``smoother.*`` settings, kept off
  inscribed cells);
* ``pppbot_nav::GridAStar`` (:mod:`pppbot_nav.planner.grid_astar`): pppbot's A* with its
  near-obstacle band.

Each is registered in the ``pppbot_nav.planners`` entry-point group (``pppbot_nav/setup.py``), as
a user's planner is (:mod:`pppbot_nav.planner.interface`). What may change while the server runs
follows each Nav2 plugin's dynamic parameters (``LIVE_PARAMETERS``); a planner keeps nothing
between plans, so a change takes effect at the next plan.
"""
from __future__ import annotations

import dataclasses
import time
from collections.abc import Collection
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from pppbot_common.params import param
from pppbot_nav.costmap.costs import INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE
from pppbot_nav.costmap.grid import Costmap
from pppbot_nav.errors import SmootherError
from pppbot_nav.planner.grid_astar import GridPlanner, Plan, PlannerSettings
from pppbot_nav.planner.navfn import NavfnPlanner, NavfnSettings
from pppbot_nav.planner.simple_smoother import SimpleSmootherSettings, smooth_path
from pppbot_nav.planner.smac_2d import Smac2DSettings, Smac2DSmootherSettings, SmacPlanner2D
from pppbot_nav.planner.smoother import SmootherSettings

NAVFN = "nav2_navfn_planner::NavfnPlanner"
SMAC_2D = "nav2_smac_planner::SmacPlanner2D"
GRID_ASTAR = "pppbot_nav::GridAStar"


@dataclass(frozen=True)
class NavfnParameters:
    LIVE_PARAMETERS: ClassVar[Collection[str] | None] = frozenset({
        "tolerance", "use_astar", "allow_unknown", "use_final_approach_orientation"})

    tolerance: float = param(0.5, "how far (m) round an unreachable goal a reachable point is looked for")
    use_astar: bool = param(False, "propagate the potential in A* order (false: Dijkstra's)")
    allow_unknown: bool = param(True, "plan through unknown space")
    use_final_approach_orientation: bool = param(False, "the goal takes the heading of the path's last step")
    max_planning_time: float = param(2.0, "a plan taking longer fails with TIMEOUT (s; pppbot's, NavFn has none)")

    def validate(self) -> None:
        self.settings().validate()

    def settings(self) -> NavfnSettings:
        return NavfnSettings(self.tolerance, self.use_astar, self.allow_unknown, self.use_final_approach_orientation,
                             self.max_planning_time)

    def make(self) -> Any:
        return NavfnPlanner(self.settings())


@dataclass(frozen=True)
class Smac2DParameters:
    LIVE_PARAMETERS: ClassVar[Collection[str] | None] = frozenset({
        "tolerance", "cost_travel_multiplier", "use_final_approach_orientation", "allow_unknown", "max_iterations",
        "max_on_approach_iterations", "terminal_checking_interval", "max_planning_time", "downsample_costmap",
        "downsampling_factor"})

    tolerance: float = param(0.125, "how far (m) from the goal the search may end when it cannot reach it")
    downsample_costmap: bool = param(False, "plan on a coarser grid")
    downsampling_factor: int = param(1, "cells of the costmap per cell of that grid (per side)")
    allow_unknown: bool = param(True, "plan through unknown space")
    max_iterations: int = param(1000000, "expansions before the search gives up (≤ 0: no limit)")
    max_on_approach_iterations: int = param(1000, "expansions within tolerance of the goal (≤ 0: no limit)")
    terminal_checking_interval: int = param(5000, "expansions between looks at the clock")
    max_planning_time: float = param(2.0, "a plan taking longer fails (s)")
    cost_travel_multiplier: float = param(2.0, "travel cost of a cell: 1 + this · cost / 252")
    use_final_approach_orientation: bool = param(False, "the goal takes the heading of the path's last step")
    smoother_max_iterations: int = param(1000, "smoother: sweeps before it gives up", "smoother.max_iterations")
    smoother_w_smooth: float = param(0.3, "smoother: pull toward the neighbours", "smoother.w_smooth")
    smoother_w_data: float = param(0.2, "smoother: pull toward the original path", "smoother.w_data")
    smoother_tolerance: float = param(1e-10, "smoother: a sweep moving less than this ends it (m)",
                                      "smoother.tolerance")
    smoother_do_refinement: bool = param(True, "smoother: smooth the smoothed path again", "smoother.do_refinement")
    smoother_refinement_num: int = param(2, "smoother: how many times", "smoother.refinement_num")

    def validate(self) -> None:
        self.settings().validate()
        self.smoothing().validate("smoother")

    def settings(self) -> Smac2DSettings:
        names = [f.name for f in dataclasses.fields(Smac2DSettings) if f.name != "smoother"]
        smoother = Smac2DSmootherSettings(self.smoother_max_iterations, self.smoother_w_smooth, self.smoother_w_data,
                                          self.smoother_tolerance, self.smoother_do_refinement,
                                          self.smoother_refinement_num)
        return Smac2DSettings(**{name: getattr(self, name) for name in names}, smoother=smoother)

    def smoothing(self) -> SimpleSmootherSettings:
        return SimpleSmootherSettings(self.smoother_tolerance, self.smoother_max_iterations, self.smoother_w_data,
                                      self.smoother_w_smooth, self.smoother_do_refinement,
                                      self.smoother_refinement_num)

    def make(self) -> Any:
        return SmoothedSmac2D(SmacPlanner2D(self.settings()), self.smoothing(), self.max_planning_time)


class SmoothedSmac2D:
    """Smac 2D's plan smoothed as its planner smooths it, never onto inscribed or lethal cells;
    a smoothing that runs out of the planning time leaves the path as planned."""

    def __init__(self, planner: SmacPlanner2D, smoothing: SimpleSmootherSettings, max_time_s: float) -> None:
        self.planner = planner
        self.smoothing = smoothing
        self.max_time_s = max_time_s

    def set_costmap(self, costmap: Costmap) -> None:
        self.planner.set_costmap(costmap)

    def plan(self, start_xy: tuple[float, float], goal_xy: tuple[float, float]) -> Plan:
        plan = self.planner.plan(start_xy, goal_xy)
        costmap = self.planner.costmap
        assert costmap is not None
        points = plan.points_xy
        d = np.diff(points, axis=0)
        yaws = np.append(np.arctan2(d[:, 1], d[:, 0]), 0.0) if len(points) > 1 else np.zeros(1)

        def blocked(xy: np.ndarray) -> np.ndarray:
            cost = costmap.cost_at(xy[:, 0], xy[:, 1], LETHAL_OBSTACLE)
            return (cost == INSCRIBED_INFLATED_OBSTACLE) | (cost == LETHAL_OBSTACLE)

        left_s = self.max_time_s - plan.planning_time_s
        try:
            smoothed = smooth_path(points, yaws, self.smoothing, clock_s=time.perf_counter,
                                   max_duration_s=max(left_s, 0.0), blocked=blocked)
        except SmootherError:
            return plan
        return dataclasses.replace(plan, points_xy=smoothed.points_xy)


@dataclass(frozen=True)
class GridAStarParameters:
    """pppbot's A* with its near-obstacle band (:mod:`pppbot_nav.planner.grid_astar`)."""

    LIVE_PARAMETERS: ClassVar[Collection[str] | None] = None

    tolerance: float = param(0.5, "how far the goal may move to a reachable cell (m)")
    allow_unknown: bool = param(True, "plan through unknown space")
    cost_travel_multiplier: float = param(2.0, "travel cost of a cell: 1 + this · cost / 252")
    max_planning_time: float = param(2.0, "a plan taking longer fails with TIMEOUT (s)")
    near_obstacle_cost: int = param(180, "cells of this cost or more (below inscribed) weigh near_obstacle_penalty "
                                    "times more")
    near_obstacle_penalty: float = param(10.0, "weight factor of the near-obstacle band (1: no band)")
    smooth_path: bool = param(True, "straighten and smooth the cell path")
    w_data: float = param(0.2, "smoother: pull toward the original path", "smoother.w_data")
    w_smooth: float = param(0.3, "smoother: pull toward the neighbours", "smoother.w_smooth")

    def validate(self) -> None:
        self.settings().validate()

    def settings(self) -> PlannerSettings:
        return PlannerSettings(self.tolerance, self.allow_unknown, self.cost_travel_multiplier,
                               self.max_planning_time, self.near_obstacle_cost, self.near_obstacle_penalty,
                               self.smooth_path, SmootherSettings(w_data=self.w_data, w_smooth=self.w_smooth))

    def make(self) -> Any:
        return GridPlanner(self.settings())


#: Nav2's default planner, for ``GridBased`` without a ``plugin``.
DEFAULT_PLANNER_TYPES = {"GridBased": NAVFN}
