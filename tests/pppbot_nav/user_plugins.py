"""A user's plugin package for the tests, "installed" into a folder of the test's own: its
``<name>-0.dist-info`` (METADATA and entry_points.txt, what pip writes) and its modules, that
folder put first on ``sys.path``, as a user's site is. The package's types are then found by
name through the entry points as pppbot's own are (:mod:`pppbot_nav.plugins`).

:data:`BEHAVIORS`, :data:`SMOOTHERS` and :data:`CRITICS` are the modules of such a package: a
behaviour that turns on the spot for a Wait goal's ``time``, a smoother that lays a path's inner
poses on the straight line between its ends, and a DWB critic whose scale may change live.
"""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

import pppbot_nav.plugins

#: ``pppbot_test_plugins::Turn`` (group ``pppbot_nav.behaviors``): nav2_msgs' Wait action with its
#: own meaning: turn at ``<name>.yaw_rate`` for the goal's ``time``; a time ≤ 0 is refused.
BEHAVIORS = '''
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

from nav2_msgs.action import Wait
from rclpy.duration import Duration

from pppbot_common.params import ParameterError, param
from pppbot_nav.behaviors import Outcome
from pppbot_nav.ros.behavior_interface import InvalidInput


class TurnRun:
    def __init__(self, duration_s: float, yaw_rate: float) -> None:
        self.duration_s, self.yaw_rate = duration_s, yaw_rate
        self.start_s = self.now_s = 0.0

    def start(self, pose, now_s):
        self.start_s = self.now_s = now_s

    def step(self, pose, now_s):
        self.now_s = now_s
        return Outcome.DONE if now_s - self.start_s >= self.duration_s else (0.0, self.yaw_rate)

    def collision_ahead(self, costmap, pose, command):
        return None

    def feedback(self, feedback, elapsed_s):
        feedback.time_left = Duration(seconds=max(0.0, self.duration_s - (self.now_s - self.start_s))).to_msg()


class Turn:
    def __init__(self, yaw_rate: float) -> None:
        self.yaw_rate = yaw_rate

    def begin(self, request, time_allowance_s):
        duration_s = request.time.sec + request.time.nanosec * 1e-9
        if duration_s <= 0.0:
            raise InvalidInput(f"a turn of {duration_s:g} s: the time must be positive")
        return TurnRun(duration_s, self.yaw_rate)


@dataclass(frozen=True)
class TurnParameters:
    ACTION: ClassVar[Any] = Wait

    yaw_rate: float = param(0.2, "how fast it turns (rad/s)")

    def validate(self) -> None:
        if not 0.0 < abs(self.yaw_rate) <= 2.0:
            raise ParameterError("yaw_rate", self.yaw_rate, "must be within (0, 2] rad/s in size")

    def make(self, context):
        return Turn(self.yaw_rate)
'''

#: ``pppbot_test_plugins::Straighten`` (group ``pppbot_nav.smoothers``): the inner poses evenly on
#: the line from the first to the last, facing along it; more than ``<name>.max_poses`` is refused.
SMOOTHERS = '''
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pppbot_common.params import param
from pppbot_nav.errors import SmootherError
from pppbot_nav.planner.smoother_interface import SmoothedPath


class Straighten:
    def __init__(self, max_poses: int) -> None:
        self.max_poses = max_poses

    def smooth(self, points_xy, yaws_rad, costmap, *, clock_s, max_duration_s):
        if len(points_xy) > self.max_poses:
            raise SmootherError(f"{len(points_xy)} poses: more than the {self.max_poses} it straightens")
        t = np.linspace(0.0, 1.0, len(points_xy))[:, None]
        points = points_xy[0] + t * (points_xy[-1] - points_xy[0])
        dx, dy = points_xy[-1] - points_xy[0]
        yaws = np.full(len(points), math.atan2(dy, dx))
        yaws[-1] = yaws_rad[-1]
        return SmoothedPath(points, yaws, True)


@dataclass(frozen=True)
class StraightenParameters:
    max_poses: int = param(100, "the longest path it straightens (poses)")

    def validate(self) -> None:
        pass

    def make(self):
        return Straighten(self.max_poses)
'''

#: The package's entry points, by group: type name → "module:attribute".
#: ``pppbot_test_plugins::Lean`` (group ``pppbot_nav.dwb_critics``): scores |ω|; its ``scale`` may
#: change while the controller runs (``LIVE_PARAMETERS`` None: all).
CRITICS = '''
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from pppbot_common.params import check_finite_range, param
from pppbot_nav.controller.dwb_critics import TrajectoryCritic


class Lean(TrajectoryCritic):
    def score(self, traj):
        return np.abs(traj.velocity[:, 2]), np.zeros(len(traj), dtype=int)


@dataclass(frozen=True)
class LeanParameters:
    LIVE_PARAMETERS: ClassVar[Any] = None

    scale: float = param(1.0, "weight of |ω|")

    def validate(self) -> None:
        check_finite_range("scale", self.scale, 0.0)

    def make(self, name: str) -> Lean:
        return Lean(name, self.scale)
'''

ENTRY_POINTS = {
    "pppbot_nav.behaviors": {"pppbot_test_plugins::Turn": "pppbot_test_behaviors:TurnParameters"},
    "pppbot_nav.smoothers": {"pppbot_test_plugins::Straighten": "pppbot_test_smoothers:StraightenParameters"},
    "pppbot_nav.dwb_critics": {"pppbot_test_plugins::Lean": "pppbot_test_critics:LeanParameters"},
}
MODULES = {"pppbot_test_behaviors": BEHAVIORS, "pppbot_test_smoothers": SMOOTHERS, "pppbot_test_critics": CRITICS}


def install_user_plugins(site: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Install the test's plugin package into ``site`` and make this process see it: ``site`` on
    ``sys.path`` and the plugin groups read afresh (:func:`pppbot_nav.plugins.plugins` keeps them per
    process); both undone by ``monkeypatch`` after the test."""
    dist = site / "pppbot_test_plugins-0.dist-info"
    dist.mkdir(parents=True)
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: pppbot-test-plugins\nVersion: 0\n")
    (dist / "entry_points.txt").write_text("".join(
        f"[{group}]\n" + "".join(f"{name} = {target}\n" for name, target in entries.items()) + "\n"
        for group, entries in ENTRY_POINTS.items()))
    for module, source in MODULES.items():
        (site / f"{module}.py").write_text(source)
        monkeypatch.delitem(sys.modules, module, raising=False)
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.setattr(pppbot_nav.plugins, "_groups", {})
