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
from collections.abc import Callable, Collection
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol, TypeVar

from pppbot_common.params import ParameterError, param
from pppbot_nav.controller.checkers import (
    PoseProgressChecker,
    PositionGoalChecker,
    SimpleGoalChecker,
    SimpleProgressChecker,
    StoppedGoalChecker,
)
from pppbot_nav.controller.dwb import DWBLocalPlanner, DWBSettings
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


SettingsT_co = TypeVar("SettingsT_co", covariant=True)
PluginT_co = TypeVar("PluginT_co", covariant=True)
S = TypeVar("S")
P = TypeVar("P")


class SettingsParameters(Protocol[SettingsT_co, PluginT_co]):
    """What a parameters class made from a settings dataclass gives (:func:`settings_parameters`): its
    fields are the settings' (declared as ROS parameters), the rest is typed here."""

    LIVE_PARAMETERS: ClassVar[Collection[str] | None]
    FROM_COSTMAP: ClassVar[frozenset[str]]

    def validate(self) -> None: ...

    def settings(self, **given: Any) -> SettingsT_co: ...

    def make(self, critics: Any = None, **given: Any) -> PluginT_co: ...


def settings_parameters(settings_class: type[S], name: str, description: str,
                        make: Callable[..., P], exclude: frozenset[str] = frozenset(),
                        live: frozenset[str] | None = None) -> type[SettingsParameters[S, P]]:
    """A parameter dataclass with the fields of the frozen ``settings`` dataclass but ``exclude`` (same
    names and defaults; ROS names relative to the plugin: a field's ``ros`` metadata, else its
    name), whose ``validate()`` builds the settings (``settings()``) and the plugin (``make()``, as
    ``make(settings)``). ``settings(**given)`` and ``make(**given)`` take the excluded fields
    (what the plugin reads from elsewhere, the costmap's robot radius: ``FROM_COSTMAP``), and
    ``make(critics=...)`` a DWB's plugin critics. ``live``: its ``LIVE_PARAMETERS``."""
    settings: Any = settings_class  # a frozen dataclass
    fields = []
    for f in dataclasses.fields(settings):
        if f.name in exclude:
            continue
        factory: Any = f.default_factory
        default = f.default if f.default is not dataclasses.MISSING else factory()
        if isinstance(default, tuple):
            default = list(default)
        fields.append((f.name, f.type, param(default, f"{description}: {f.name}", f.metadata.get("ros"))))

    def to_settings(self: Any, **given: Any) -> Any:
        values = {f.name: getattr(self, f.name) for f in dataclasses.fields(settings) if f.name not in exclude}
        values = {k: tuple(v) if isinstance(v, list) else v for k, v in values.items()}
        return settings(**values, **given)

    def validate(self: Any) -> None:
        _checked(lambda: to_settings(self).validate())

    def make_plugin(self: Any, critics: Any = None, **given: Any) -> Any:
        return make(to_settings(self, **given)) if critics is None else make(to_settings(self, **given), critics)

    made: Any = dataclasses.make_dataclass(name, fields, frozen=True, namespace={
        "validate": validate, "settings": to_settings, "make": make_plugin, "LIVE_PARAMETERS": live,
        "FROM_COSTMAP": exclude})
    return made  # the fields are made at run time; what is used of the class is typed by the Protocol


#: RPP's every parameter may change at run time.
RegulatedPurePursuitParameters = settings_parameters(PurePursuitSettings, "RegulatedPurePursuitParameters",
                                                     "regulated pure pursuit", PurePursuit)
#: DWB's footprint is the local costmap's (its robot_radius and footprint_padding), as in Nav2.
DWB_FROM_COSTMAP = frozenset({"robot_radius", "footprint_padding"})
#: DWB's kinematic limits may change at run time (Nav2's KinematicsHandler).
DWB_LIVE = frozenset({"min_vel_x", "min_vel_y", "max_vel_x", "max_vel_y", "max_vel_theta", "min_speed_xy",
                      "max_speed_xy", "min_speed_theta", "acc_lim_x", "acc_lim_y", "acc_lim_theta", "decel_lim_x",
                      "decel_lim_y", "decel_lim_theta"})
DWBParameters = settings_parameters(DWBSettings, "DWBParameters", "DWB", DWBLocalPlanner, DWB_FROM_COSTMAP,
                                    live=DWB_LIVE)
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
