"""DWB's critics as plugins: each of Nav2's ``dwb_critics`` is a parameters class registered in the
entry-point group ``pppbot_nav.dwb_critics`` (``pppbot_nav/setup.py``) under Nav2's type name, as a
user's critic is (:class:`pppbot_nav.controller.interface.CriticPlugin`).

A DWB controller's ``critics`` list names them as Nav2's ``resolveCriticClassName`` does:
``PathDist``, ``PathDistCritic`` and ``dwb_critics::PathDistCritic`` are one; a short name is looked
up in Nav2's default critic namespace ``dwb_critics`` first, then in every installed package. Each
critic's parameters sit under ``<controller>.<its name in critics>.`` (``FollowPath.PathAlign.scale``)
with Nav2's names and defaults; what a critic reads of the controller itself (RotateToGoal's
``xy_goal_tolerance``, the footprint) it takes from :attr:`Context.settings` each period.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from pppbot_common.params import ParameterError, check_finite_range, from_values, param
from pppbot_nav.controller.dwb_critics import (
    BaseObstacle,
    GoalAlign,
    GoalDist,
    ObstacleFootprint,
    Oscillation,
    PathAlign,
    PathDist,
    PreferForward,
    RotateToGoal,
    TrajectoryCritic,
    Twirling,
)
from pppbot_nav.errors import ControllerError
from pppbot_nav.plugins import PluginError, canonical, plugins

#: Nav2 DWB's ``default_critic_namespaces``: where a short critic name is looked up first.
DEFAULT_CRITIC_NAMESPACE = "dwb_critics"
AGGREGATION_TYPES = ("last", "sum", "product")


def _scale(value: float) -> None:
    check_finite_range("scale", value, 0.0)


@dataclass(frozen=True)
class RotateToGoalParameters:
    scale: float = param(1.0, "weight of the yaw left to the goal's once within xy_goal_tolerance")
    slowing_factor: float = param(5.0, "weight of the speed while still slowing down near the goal")
    lookahead_time: float = param(-1.0, "score the yaw this far (s) along the trajectory; negative: at its end")

    def validate(self) -> None:
        _scale(self.scale)
        check_finite_range("slowing_factor", self.slowing_factor, 0.0)
        check_finite_range("lookahead_time", self.lookahead_time)

    def make(self, name: str) -> RotateToGoal:
        return RotateToGoal(name, self.scale, self.slowing_factor, self.lookahead_time)


@dataclass(frozen=True)
class OscillationParameters:
    scale: float = param(1.0, "weight (the critic only forbids: its score is 0)")
    oscillation_reset_dist: float = param(0.05, "a sign change is forgotten once the robot moved this far (m); "
                                                "negative: never")
    oscillation_reset_angle: float = param(0.2, "… or turned this far (rad); negative: never")
    oscillation_reset_time: float = param(-1.0, "… or this long passed (s); negative: never")
    x_only_threshold: float = param(0.05, "above this |vx| (m/s) only vx's sign is watched; negative: all")

    def validate(self) -> None:
        _scale(self.scale)
        for name in ("oscillation_reset_dist", "oscillation_reset_angle", "oscillation_reset_time",
                     "x_only_threshold"):
            check_finite_range(name, getattr(self, name))

    def make(self, name: str) -> Oscillation:
        return Oscillation(name, self.scale, self.oscillation_reset_dist, self.oscillation_reset_angle,
                           self.oscillation_reset_time, self.x_only_threshold)


@dataclass(frozen=True)
class BaseObstacleParameters:
    scale: float = param(1.0, "weight of the costmap's cost under the trajectory")
    sum_scores: bool = param(False, "the sum over the trajectory's poses instead of the last pose's")

    def validate(self) -> None:
        _scale(self.scale)

    def make(self, name: str) -> BaseObstacle:
        return BaseObstacle(name, self.scale, self.sum_scores)


@dataclass(frozen=True)
class ObstacleFootprintParameters(BaseObstacleParameters):
    def make(self, name: str) -> ObstacleFootprint:
        return ObstacleFootprint(name, self.scale, self.sum_scores)


@dataclass(frozen=True)
class _MapGridParameters:
    scale: float = param(1.0, "weight (half a cell per unit, as Nav2's map-grid critics)")
    aggregation_type: str = param("last", "how the trajectory's cell distances add up: last, sum or product")

    def validate(self) -> None:
        _scale(self.scale)
        if self.aggregation_type.lower() not in AGGREGATION_TYPES:
            raise ParameterError("aggregation_type", self.aggregation_type,
                                 f"must be one of {', '.join(AGGREGATION_TYPES)}")


@dataclass(frozen=True)
class PathDistParameters(_MapGridParameters):
    def make(self, name: str) -> PathDist:
        return PathDist(name, self.scale, self.aggregation_type)


@dataclass(frozen=True)
class GoalDistParameters(_MapGridParameters):
    def make(self, name: str) -> GoalDist:
        return GoalDist(name, self.scale, self.aggregation_type)


@dataclass(frozen=True)
class _AlignParameters(_MapGridParameters):
    forward_point_distance: float = param(0.325, "the point scored is this far (m) ahead of each pose")

    def validate(self) -> None:
        super().validate()
        check_finite_range("forward_point_distance", self.forward_point_distance, 0.0)


@dataclass(frozen=True)
class PathAlignParameters(_AlignParameters):
    def make(self, name: str) -> PathAlign:
        return PathAlign(name, self.scale, self.aggregation_type, self.forward_point_distance)


@dataclass(frozen=True)
class GoalAlignParameters(_AlignParameters):
    def make(self, name: str) -> GoalAlign:
        return GoalAlign(name, self.scale, self.aggregation_type, self.forward_point_distance)


@dataclass(frozen=True)
class PreferForwardParameters:
    scale: float = param(1.0, "weight")
    penalty: float = param(1.0, "the score of backing up or strafing")
    strafe_x: float = param(0.1, "below this vx (m/s) …")
    strafe_theta: float = param(0.2, "… and this |ω| (rad/s) a command counts as strafing")
    theta_scale: float = param(10.0, "otherwise the score is theta_scale·|ω|")

    def validate(self) -> None:
        _scale(self.scale)
        for name in ("penalty", "strafe_x", "strafe_theta", "theta_scale"):
            check_finite_range(name, getattr(self, name))

    def make(self, name: str) -> PreferForward:
        return PreferForward(name, self.scale, self.penalty, self.strafe_x, self.strafe_theta, self.theta_scale)


@dataclass(frozen=True)
class TwirlingParameters:
    scale: float = param(1.0, "weight of |ω|")

    def validate(self) -> None:
        _scale(self.scale)

    def make(self, name: str) -> Twirling:
        return Twirling(name, self.scale)


def critic_type(name: str) -> str | None:
    """The installed critic (entry-point group ``pppbot_nav.dwb_critics``) a ``critics`` entry names,
    or None: its full type (``dwb_critics::PathDistCritic``, ``my_pkg::Clearance``), or, as Nav2
    resolves a short name, the type in ``dwb_critics`` whose class is the name with or without
    ``Critic``, else such a type in any installed package."""
    group = plugins("DWB critic")
    exact = group.name_of(name)
    if exact is not None:
        return exact
    classes = (name, f"{name}Critic")
    for namespace in (DEFAULT_CRITIC_NAMESPACE, None):
        for type_name in group:
            where, _, cls = canonical(type_name).rpartition("/")
            if cls in classes and (namespace is None or where == namespace):
                return type_name
    return None


def unknown_critic(name: str) -> str:
    """Why ``name`` is no critic: what is installed."""
    return f"unknown critic {name!r} in critics: {plugins('DWB critic').unknown(name)}"


def make_critics(names: Sequence[str], values: Mapping[str, Mapping[str, Any]] | None = None
                 ) -> dict[str, TrajectoryCritic]:
    """The critics ``names`` lists (a DWB's ``critics``), by name, each made from its parameters:
    ``values[name]`` (ROS names relative to the critic, ``{"scale": 32.0}``) over its defaults.
    The controller server makes them from its ROS parameters instead.

    Raises:
        ControllerError: an unknown critic, or a value its parameters refuse (named ``<critic>.<name>``).
    """
    made: dict[str, TrajectoryCritic] = {}
    for name in names:
        type_name = critic_type(name)
        if type_name is None:
            raise ControllerError(unknown_critic(name), "critics")
        try:
            made[name] = from_values(plugins("DWB critic")[type_name], dict((values or {}).get(name, {}))).make(name)
        except PluginError as exc:
            raise ControllerError(str(exc), "critics") from exc
        except ParameterError as exc:
            raise ControllerError(str(ParameterError(f"{name}.{exc.name}", exc.value, exc.allowed)),
                                  f"{name}.{exc.name}") from exc
    return made
