"""The controller server's plugins by Nav2's type name: their parameters (Nav2's names and
defaults, under the plugin's name) and what may change while the server runs.

* controllers: ``nav2_regulated_pure_pursuit_controller::RegulatedPurePursuitController``
  (:mod:`pppbot_nav.controller.pure_pursuit`) and ``dwb_core::DWBLocalPlanner``
  (:mod:`pppbot_nav.controller.dwb`);
* goal checkers: ``nav2_controller::SimpleGoalChecker``, ``StoppedGoalChecker``,
  ``PositionGoalChecker``; progress checkers: ``nav2_controller::SimpleProgressChecker``,
  ``PoseProgressChecker`` (:mod:`pppbot_nav.controller.checkers`).

Each is registered in its entry-point group (``pppbot_nav/setup.py``), as a user's plugin is
(:mod:`pppbot_nav.controller.interface`). A parameter set applies to the running plugin (its
attributes), so a goal checker keeps its latch and a progress checker its baseline.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Collection, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, TypeVar

from pppbot_common.params import ParameterError, param
from pppbot_nav.controller.checkers import (
    PoseProgressChecker,
    PositionGoalChecker,
    SimpleGoalChecker,
    SimpleProgressChecker,
    StoppedGoalChecker,
)
from pppbot_nav.controller.dwb import DWBLocalPlanner, DWBSettings
from pppbot_nav.controller.dwb_critics import TrajectoryCritic
from pppbot_nav.controller.pure_pursuit import PurePursuit, PurePursuitSettings
from pppbot_nav.errors import ControllerError

RPP = "nav2_regulated_pure_pursuit_controller::RegulatedPurePursuitController"
DWB = "dwb_core::DWBLocalPlanner"
SIMPLE_GOAL = "nav2_controller::SimpleGoalChecker"
STOPPED_GOAL = "nav2_controller::StoppedGoalChecker"
POSITION_GOAL = "nav2_controller::PositionGoalChecker"
SIMPLE_PROGRESS = "nav2_controller::SimpleProgressChecker"
POSE_PROGRESS = "nav2_controller::PoseProgressChecker"


def _checked(make: Any) -> Any:
    """``make()``, a ControllerError turned into the ParameterError naming its parameter."""
    try:
        return make()
    except ControllerError as exc:
        raise ParameterError(exc.parameter or "", "", str(exc)) from exc


S = TypeVar("S")


def _settings_of(params: Any, settings_class: type[S], **given: Any) -> S:
    """The ``settings_class`` (a dataclass whose fields ``params`` has) of ``params``, with ``given``."""
    fields = dataclasses.fields(settings_class)  # type: ignore[arg-type]
    return settings_class(**{f.name: getattr(params, f.name) for f in fields if f.name not in given}, **given)


@dataclass(frozen=True)
class RegulatedPurePursuitParameters(PurePursuitSettings):
    """RPP's parameters: the fields of its settings (Nav2's names and defaults), each declared under
    the plugin's name. Every one may change while the server runs."""

    PARAMETERS_OF: ClassVar[str] = "regulated pure pursuit"
    LIVE_PARAMETERS: ClassVar[Collection[str] | None] = None
    FROM_COSTMAP: ClassVar[frozenset[str]] = frozenset()

    def validate(self) -> None:
        _checked(self.settings().validate)

    def settings(self) -> PurePursuitSettings:
        return _settings_of(self, PurePursuitSettings)

    def make(self) -> PurePursuit:
        return PurePursuit(self.settings())


@dataclass(frozen=True)
class DWBParameters(DWBSettings):
    """DWB's parameters: the fields of its settings (Nav2's names and defaults, a critic's under its
    name: ``BaseObstacle.scale``) but the footprint, which is the local costmap's (its robot_radius
    and footprint_padding, as in Nav2). Its kinematic limits may change while the server runs
    (Nav2's KinematicsHandler)."""

    PARAMETERS_OF: ClassVar[str] = "DWB"
    FROM_COSTMAP: ClassVar[frozenset[str]] = frozenset({"robot_radius", "footprint_padding"})
    NOT_PARAMETERS: ClassVar[frozenset[str]] = FROM_COSTMAP
    LIVE_PARAMETERS: ClassVar[Collection[str] | None] = frozenset({
        "min_vel_x", "min_vel_y", "max_vel_x", "max_vel_y", "max_vel_theta", "min_speed_xy", "max_speed_xy",
        "min_speed_theta", "acc_lim_x", "acc_lim_y", "acc_lim_theta", "decel_lim_x", "decel_lim_y",
        "decel_lim_theta"})

    def validate(self) -> None:
        _checked(self.settings().validate)

    def settings(self, robot_radius: float = DWBSettings.robot_radius,
                 footprint_padding: float = DWBSettings.footprint_padding) -> DWBSettings:
        return _settings_of(self, DWBSettings, robot_radius=robot_radius, footprint_padding=footprint_padding)

    def make(self, critics: Mapping[str, TrajectoryCritic] | None = None,
             robot_radius: float = DWBSettings.robot_radius,
             footprint_padding: float = DWBSettings.footprint_padding) -> DWBLocalPlanner:
        return DWBLocalPlanner(self.settings(robot_radius, footprint_padding), critics)


#: Nav2's default controller, for ``FollowPath`` without a ``plugin``.
DEFAULT_CONTROLLER_TYPES = {"FollowPath": DWB}


@dataclass(frozen=True)
class SimpleGoalCheckerParameters:
    LIVE_PARAMETERS: ClassVar[Collection[str] | None] = None

    xy_goal_tolerance: float = param(0.25, "distance to the goal (m)")
    yaw_goal_tolerance: float = param(0.25, "heading to the goal's (rad)")
    stateful: bool = param(True, "once within xy, only the heading is checked")

    def validate(self) -> None:
        _checked(self.make)

    def make(self) -> Any:
        return SimpleGoalChecker(self.xy_goal_tolerance, self.yaw_goal_tolerance, self.stateful)


@dataclass(frozen=True)
class StoppedGoalCheckerParameters(SimpleGoalCheckerParameters):
    trans_stopped_velocity: float = param(0.25, "the robot counts as stopped below this speed (m/s)")
    rot_stopped_velocity: float = param(0.25, "… and below this turn rate (rad/s)")

    def make(self) -> Any:
        return StoppedGoalChecker(self.xy_goal_tolerance, self.yaw_goal_tolerance, self.stateful,
                                  self.trans_stopped_velocity, self.rot_stopped_velocity)


@dataclass(frozen=True)
class PositionGoalCheckerParameters:
    LIVE_PARAMETERS: ClassVar[Collection[str] | None] = None

    xy_goal_tolerance: float = param(0.25, "distance to the goal (m)")
    stateful: bool = param(True, "once within xy, the goal stays reached")

    def validate(self) -> None:
        _checked(self.make)

    def make(self) -> Any:
        return PositionGoalChecker(self.xy_goal_tolerance, self.stateful)


@dataclass(frozen=True)
class SimpleProgressCheckerParameters:
    LIVE_PARAMETERS: ClassVar[Collection[str] | None] = None

    required_movement_radius: float = param(0.5, "move this far (m) ...")
    movement_time_allowance: float = param(10.0, "... within this time (s)")

    def validate(self) -> None:
        _checked(self.make)

    def make(self) -> Any:
        return SimpleProgressChecker(self.required_movement_radius, self.movement_time_allowance)


@dataclass(frozen=True)
class PoseProgressCheckerParameters(SimpleProgressCheckerParameters):
    required_movement_angle: float = param(0.5, "or turn this far (rad)")

    def make(self) -> Any:
        return PoseProgressChecker(self.required_movement_radius, self.movement_time_allowance,
                                   self.required_movement_angle)


#: Nav2's default checker names (and ppp_bot's) and their types when no ``plugin`` is given.
DEFAULT_CHECKER_TYPES = {"goal_checker": SIMPLE_GOAL, "general_goal_checker": SIMPLE_GOAL,
                         "precise_goal_checker": SIMPLE_GOAL, "progress_checker": SIMPLE_PROGRESS}
