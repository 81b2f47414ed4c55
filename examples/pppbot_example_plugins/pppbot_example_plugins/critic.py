"""``pppbot_example_plugins::Clearance``: a DWB critic that prefers trajectories keeping away from
obstacles.

Each trajectory scores the highest cost it passes over (0–252, Nav2's costmap values), so of
two commands that both progress, DWB takes the one with more room. Named in a DWB controller's
``critics`` list as ``Clearance`` (or its full type), its parameters under
``FollowPath.Clearance.`` (Nav2's convention for a critic): ``scale``. A critic plugin is a
parameters class (the ``pppbot_nav.dwb_critics`` entry point) whose ``make(name)`` returns a
:class:`pppbot_nav.controller.dwb_critics.TrajectoryCritic`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pppbot_common.params import check_finite_range, param
from pppbot_nav.controller.dwb_critics import Context, Trajectories, TrajectoryCritic, Verdict
from pppbot_nav.costmap.costs import INSCRIBED_INFLATED_OBSTACLE
from pppbot_nav.costmap.grid import Costmap


class Clearance(TrajectoryCritic):
    def __init__(self, name: str, scale: float) -> None:
        super().__init__(name, scale)
        self._costmap: Costmap | None = None

    def prepare(self, ctx: Context) -> bool:
        self._costmap = ctx.costmap
        return True

    def score(self, traj: Trajectories) -> Verdict:
        assert self._costmap is not None, "score before prepare"
        flat, on = traj.cells(self._costmap)
        cost = np.where(on & traj.mask(), self._costmap.costs.ravel()[flat], 0).astype(float)
        # Lethal and inscribed cells are BaseObstacle's to refuse; here they count as the worst free cost.
        worst = np.minimum(cost.max(axis=1), INSCRIBED_INFLATED_OBSTACLE - 1)
        return worst, np.zeros(len(traj), dtype=int)


@dataclass(frozen=True)
class ClearanceParameters:
    scale: float = param(0.02, "weight of the highest cost a trajectory passes over")

    def validate(self) -> None:
        check_finite_range("scale", self.scale, 0.0, 1000.0)

    def make(self, name: str) -> Clearance:
        return Clearance(name, self.scale)
