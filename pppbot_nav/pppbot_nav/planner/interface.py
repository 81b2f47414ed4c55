"""What a planner plugin is: the Protocols the planner server asks of an entry point in the
``pppbot_nav.planners`` group (:mod:`pppbot_nav.plugins`), Nav2's ``nav2_core::GlobalPlanner``.

An entry point names a **parameters class** (:class:`PlannerPlugin`): a frozen dataclass whose
fields are the plugin's parameters (declared under ``<name>.`` with their defaults; a field made
with :func:`pppbot_common.params.param` carries its description and ROS name), whose
``validate()`` raises :class:`pppbot_common.params.ParameterError` on a bad value and whose
``make()`` returns the :class:`Planner`. ``LIVE_PARAMETERS`` says which fields may change while
the server runs (None: all; absent: none), as a Nav2 plugin's dynamic parameters.
"""
from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass
from typing import ClassVar, Protocol

import numpy as np

from pppbot_nav.costmap.grid import Costmap


@dataclass(frozen=True, eq=False)
class Plan:
    """``points_xy`` (K, 2) in the costmap's frame, start first and goal last; ``cost`` the search's
    path cost (cell weights); ``goal_xy`` the goal planned to (moved within tolerance if it had to be)."""

    points_xy: np.ndarray
    cost: float
    goal_xy: tuple[float, float]
    planning_time_s: float

    @property
    def length_m(self) -> float:
        return float(np.linalg.norm(np.diff(self.points_xy, axis=0), axis=1).sum())


class Planner(Protocol):
    """Plans on the global costmap the server gives it before each plan."""

    def set_costmap(self, costmap: Costmap) -> None: ...

    def plan(self, start_xy: tuple[float, float], goal_xy: tuple[float, float]) -> Plan:
        """A path from ``start_xy`` to ``goal_xy`` (m, the costmap's frame).

        Raises:
            pppbot_nav.errors.PlannerError: no path; its ``code`` is Nav2's ComputePathToPose error code.
        """
        ...


class PlannerPlugin(Protocol):
    """An entry point of ``pppbot_nav.planners``: the plugin's parameters, validated, and its planner."""

    LIVE_PARAMETERS: ClassVar[Collection[str] | None]

    def validate(self) -> None: ...

    def make(self) -> Planner: ...
