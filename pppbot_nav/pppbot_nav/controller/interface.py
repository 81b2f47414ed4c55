"""What the controller server's plugins are: the Protocols it asks of entry points in the
``pppbot_nav.controllers``, ``pppbot_nav.goal_checkers``, ``pppbot_nav.progress_checkers`` and
``pppbot_nav.dwb_critics`` groups (:mod:`pppbot_nav.plugins`), Nav2's ``nav2_core::Controller``,
``GoalChecker``, ``ProgressChecker`` and ``dwb_core::TrajectoryCritic``.

Each entry point names a **parameters class**: a frozen dataclass whose fields are the plugin's
parameters (declared under ``<name>.``, a critic's under ``<controller>.<critic>.``), with
``validate()`` (raises :class:`pppbot_common.params.ParameterError`) and ``make(...)``.
``LIVE_PARAMETERS`` says which fields may change while the server runs (None: all; absent: none).
"""
from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass
from enum import Enum
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import numpy as np

from pppbot_common.se2 import PoseLike
from pppbot_nav.costmap.grid import Costmap

if TYPE_CHECKING:
    from pppbot_nav.controller.dwb_critics import TrajectoryCritic


class ControlMode(Enum):
    """What a command does."""

    TRACKING = "tracking"  # following the arc to the carrot
    ROTATE_TO_PATH = "rotate_to_path"  # turning in place towards the carrot
    ROTATE_TO_GOAL = "rotate_to_goal"  # turning in place to the goal's yaw, within goal_dist_tol


@dataclass(frozen=True)
class Command:
    """One control period's output. Points are in the frame of the pose and the path (Nav2
    publishes its carrot and local plan in the robot's base frame instead)."""

    linear_mps: float
    angular_radps: float
    lookahead: tuple[float, float]  # the carrot (x, y), m
    curvature: float  # 1/m of the arc to the carrot (positive: left)
    local_plan: np.ndarray  # (M, 2) x, y of the pruned path portion used, for /local_plan
    mode: ControlMode
    lookahead_dist_m: float


class Controller(Protocol):
    """What the controller server asks of a controller plugin (RPP, DWB)."""

    def set_path(self, path: np.ndarray) -> None: ...

    def compute(self, pose: PoseLike, speed: PoseLike, path: np.ndarray, costmap: Costmap | None,
                dt_s: float, costmap_pose: PoseLike | None = None) -> Command: ...


class GoalChecker(Protocol):
    def reset(self) -> None: ...

    def is_goal_reached(self, pose: PoseLike, goal: PoseLike, speed: tuple[float, float] = (0.0, 0.0)) -> bool: ...


class ProgressChecker(Protocol):
    def reset(self) -> None: ...

    def check(self, pose_xy: PoseLike, now_s: float) -> bool: ...

    def failure(self) -> str: ...


class ControllerPlugin(Protocol):
    """An entry point of ``pppbot_nav.controllers``. ``make`` takes what the server gives every
    controller by keyword: ``robot_radius`` and ``footprint_padding`` (the local costmap's, m) and
    ``critics`` (a DWB-like controller's installed critics by name, see :class:`CriticPlugin`); a
    plugin declares the ones it takes as parameters of ``make``."""

    LIVE_PARAMETERS: ClassVar[Collection[str] | None]

    def validate(self) -> None: ...

    def make(self, **given: Any) -> Controller: ...


class GoalCheckerPlugin(Protocol):
    """An entry point of ``pppbot_nav.goal_checkers``."""

    def validate(self) -> None: ...

    def make(self) -> GoalChecker: ...


class ProgressCheckerPlugin(Protocol):
    """An entry point of ``pppbot_nav.progress_checkers``."""

    def validate(self) -> None: ...

    def make(self) -> ProgressChecker: ...


class CriticPlugin(Protocol):
    """An entry point of ``pppbot_nav.dwb_critics``: a DWB critic named in ``critics`` (DWB's own are
    registered so too). Its parameters sit under ``<controller>.<critic name>.`` (Nav2's), ``scale``
    among them; ``make(name)`` returns the critic (a :class:`pppbot_nav.controller.dwb_critics.TrajectoryCritic`),
    whose ``prepare(ctx)`` sees the controller's own settings in ``ctx.settings`` each period."""

    def validate(self) -> None: ...

    def make(self, name: str) -> TrajectoryCritic: ...
