"""One evaluation run's settings, checked: what ``pppbot eval``'s flags say, as a frozen value.

:meth:`EvalConfig.checked` is where every flag's rule lives: each broken rule is one
:class:`~pppbot_common.errors.ArgumentError` naming the flag, its value and what is
allowed. It also resolves the one default that depends on others (the real-time factor).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from pppbot_common.errors import ArgumentError, ParameterFileError
from pppbot_common.param_files import check_parameter_file, is_static_layer, node_parameters
from pppbot_eval.scenarios import Scenario
from pppbot_nav.controller.dwb import DWBSettings
from pppbot_nav.controller.plugin_settings import DEFAULT_CONTROLLER_TYPES, DWB, RPP
from pppbot_nav.controller.pure_pursuit import PurePursuitSettings

#: The default real-time factor of each scenario without lockstep (``--real-time-factor``):
#: what the nodes keep up with on 2 cores.
DEFAULT_REAL_TIME_FACTOR = {Scenario.NAVIGATION: 1.0}
FALLBACK_REAL_TIME_FACTOR = 3.0
#: Scenarios that take ``--map``.
MAP_SCENARIOS = (Scenario.MAP, Scenario.LOCALIZATION, Scenario.NAVIGATION)
#: The controller's speed limit, which ``--speed`` may not exceed (m/s).
MAX_ROUTE_SPEED_MPS = 2.0

Triple = tuple[float, float, float]


@dataclass(frozen=True)
class EvalConfig:
    """The flags of ``pppbot eval`` (see its ``--help``), checked and with defaults resolved."""

    scenario: Scenario
    world: str = "maze"
    route: str | None = None
    route_file: Path | None = None
    lockstep: bool = True
    real_time_factor: float | None = None  # None: the scenario's default (0 in lockstep)
    seed: int = 0
    wheel_slip: float = 0.01
    speed: float = 0.3
    timeout: float | None = None
    out: Path | None = None
    map: Path | None = None
    params_file: Path | None = None
    map_pose: Triple = (0.0, 0.0, 0.0)
    initial_offset: Triple = (0.35, 0.35, 0.3)
    global_localization: bool = False
    goals: int = 50
    goal_distance: float = 2.0
    start: Triple = (0.0, 0.0, 0.0)
    min_success_rate: float = 0.98
    goal: Triple | None = None
    no_map: bool = False
    through_poses: bool = False
    view: bool = False
    json: bool = False
    log_level: str = "info"

    @classmethod
    def from_flags(cls, flags: object, max_wheel_slip: float) -> EvalConfig:
        """The config of parsed flags (an argparse namespace with these fields' names), checked."""
        values = {f.name: getattr(flags, f.name) for f in dataclasses.fields(cls) if hasattr(flags, f.name)}
        values["scenario"] = Scenario(values["scenario"])
        for name in ("map_pose", "initial_offset", "start", "goal"):
            if values.get(name) is not None:
                values[name] = tuple(float(v) for v in values[name])
        return cls(**values).checked(max_wheel_slip)

    @property
    def target_real_time_factor(self) -> float:
        """The real-time factor to run at: ``real_time_factor``, or the scenario's default."""
        if self.real_time_factor is not None:
            return self.real_time_factor
        return 0.0 if self.lockstep else DEFAULT_REAL_TIME_FACTOR.get(self.scenario, FALLBACK_REAL_TIME_FACTOR)

    def checked(self, max_wheel_slip: float) -> EvalConfig:
        """This config with ``real_time_factor`` resolved.

        Raises:
            ArgumentError: the first flag that breaks its rule, named with its value.
        """
        rtf = self.target_real_time_factor
        if not (math.isfinite(rtf) and 0.0 <= rtf <= 1000.0):
            raise ArgumentError(f"--real-time-factor {rtf}: must be in [0, 1000]")
        if not (math.isfinite(self.speed) and 0.0 < self.speed <= MAX_ROUTE_SPEED_MPS):
            raise ArgumentError(f"--speed {self.speed}: must be in (0, {MAX_ROUTE_SPEED_MPS:g}] m/s "
                                "(the controller's limit)")
        if not (math.isfinite(self.wheel_slip) and 0.0 <= self.wheel_slip <= max_wheel_slip):
            raise ArgumentError(f"--wheel-slip {self.wheel_slip}: must be in [0, {max_wheel_slip}]")
        for flag, triple in (("--map-pose", self.map_pose), ("--start", self.start),
                             ("--initial-offset", self.initial_offset), ("--goal", self.goal or (0.0, 0.0, 0.0))):
            if not all(math.isfinite(v) for v in triple):
                raise ArgumentError(f"{flag} {' '.join(map(str, triple))}: must be three finite numbers")
        if self.scenario is Scenario.MAP and self.map is None:
            raise ArgumentError("--map: the map scenario needs it")
        if self.map is not None and self.scenario not in MAP_SCENARIOS:
            raise ArgumentError(f"--map: only the map, localization and navigation scenarios take it, "
                                f"not {self.scenario.value}")
        if self.params_file is not None and not self.params_file.is_file():
            raise ArgumentError(f"--params-file {self.params_file}: no such file")
        self._check_navigation()
        if self.seed < 0:
            raise ArgumentError(f"--seed {self.seed}: must be a non-negative integer")
        if self.timeout is not None and not (math.isfinite(self.timeout) and self.timeout > 0):
            raise ArgumentError(f"--timeout {self.timeout}: must be a positive number of sim seconds")
        return dataclasses.replace(self, real_time_factor=rtf)

    def _check_navigation(self) -> None:
        if self.goals < 1:
            raise ArgumentError(f"--goals {self.goals}: must be at least 1")
        if not (math.isfinite(self.goal_distance) and self.goal_distance >= 0):
            raise ArgumentError(f"--goal-distance {self.goal_distance}: must be a non-negative number of metres")
        if not (0.0 <= self.min_success_rate <= 1.0):
            raise ArgumentError(f"--min-success-rate {self.min_success_rate}: must be in [0, 1]")
        if self.scenario is not Scenario.NAVIGATION and self.through_poses:
            raise ArgumentError("--through-poses: only the navigation scenario takes it")
        if self.scenario is not Scenario.NAVIGATION and (self.no_map or self.goal is not None):
            raise ArgumentError(f"{'--no-map' if self.no_map else '--goal'}: only the navigation scenario takes it, "
                                f"not {self.scenario.value}")
        if self.no_map and self.map is not None:
            raise ArgumentError("--map and --no-map: a run navigates on a map or without one, not both")


def map_free_params(path: Path, out_file: Path, window_m: int, odom_frame: str = "odom") -> Path:
    """Nav2's parameters at ``path`` made to navigate without a map, as Nav2 runs where none exists
    (outdoors, exploring), written to ``out_file``: the navigator, the behaviours and the global
    costmap in ``odom_frame``, the global costmap a ``window_m`` square rolling with the robot, marked
    and cleared by the lidar alone (its ``static_layer`` left out). The rest as the file says.

    Raises:
        ArgumentError: the file is not a ROS 2 parameter file (naming it and what is wrong).
    """
    try:
        check_parameter_file(path)
        document = yaml.safe_load(path.read_text()) or {}
    except (ParameterFileError, OSError, yaml.YAMLError) as exc:
        raise ArgumentError(f"--params-file {path}: {exc}") from exc

    def section(*keys: str) -> dict[str, Any]:
        node = document
        for key in (*keys, "ros__parameters"):
            node = node.setdefault(key, {})
        return node

    section("bt_navigator")["global_frame"] = odom_frame
    section("behavior_server")["global_frame"] = odom_frame
    costmap = section("global_costmap", "global_costmap")

    def static(name: str) -> bool:
        layer = costmap.get(name)
        return is_static_layer(name, layer.get("plugin") if isinstance(layer, dict) else None)

    plugins = [p for p in costmap.get("plugins", ["obstacle_layer", "inflation_layer"]) if not static(p)]
    for name in [k for k in costmap if static(k)]:
        costmap.pop(name)
    costmap.update(global_frame=odom_frame, rolling_window=True, width=window_m, height=window_m, plugins=plugins)
    out_file.parent.mkdir(parents=True, exist_ok=True)
    out_file.write_text(f"# {path} without a map (pppbot eval navigation --no-map)\n"
                        + yaml.safe_dump(document, sort_keys=False))
    return out_file


#: The velocity smoother's default ``max_velocity`` x (m/s; pppbot_nav's ``velocity_smoother``, Nav2's).
SMOOTHER_MAX_X_DEFAULT = 0.5


def _controller_speed(plugin: str, kind: str, params: dict[str, Any]) -> tuple[str, float]:
    """The parameter that sets controller ``plugin``'s top forward speed, and its value (the stack's
    default where the file is silent): DWB's ``max_vel_x``, Regulated Pure Pursuit's ``desired_linear_vel``."""
    settings = {DWB: ("max_vel_x", DWBSettings), RPP: ("desired_linear_vel", PurePursuitSettings)}
    name, cls = settings.get(kind, settings[RPP])
    default = next(f.default for f in dataclasses.fields(cls) if f.name == name)
    return f"{plugin}.{name}", params.get(f"{plugin}.{name}", default)


@dataclass(frozen=True)
class ScoredParameters:
    """The Nav2 parameters a score depends on, read from the one file the stack is given.

    ``amcl_transform_tolerance``: how far ahead AMCL stamps map -> odom (s); the localization
    scenario compares its estimate at the time it is valid for. ``max_speed_mps``: the speed goals
    are timed against (the navigation report's time ratios and each goal's time limit): the
    controller's (the first of ``controller_plugins``; without a ``plugin``, Nav2's default, DWB)
    capped by the velocity smoother's ``max_velocity``. Where the file is silent, the stack's defaults.
    """

    file: Path
    amcl_transform_tolerance: float = 1.0
    max_speed_mps: float = 0.5

    @classmethod
    def read(cls, path: Path) -> ScoredParameters:
        """The parameters ``path`` gives.

        Raises:
            ArgumentError: the file is not a ROS 2 parameter file, or a scored value is not a
                positive number (naming the file, node and parameter).
        """
        try:
            nodes = check_parameter_file(path)
        except ParameterFileError as exc:
            raise ArgumentError(f"--params-file {exc}") from exc

        def number(node: str, name: str, value: Any) -> float:
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < math.inf:
                raise ArgumentError(f"--params-file {path}: {node} {name} = {value!r}: the evaluation needs a "
                                    "positive number")
            return float(value)

        controller = node_parameters(nodes, "controller_server")
        plugins = controller.get("controller_plugins", ["FollowPath"])
        plugin = str(plugins if isinstance(plugins, str) else (plugins or ["FollowPath"])[0])
        kind = str(controller.get(f"{plugin}.plugin", DEFAULT_CONTROLLER_TYPES.get(plugin, DWB)))
        speed = number("controller_server", *_controller_speed(plugin, kind, controller))
        smoother = node_parameters(nodes, "velocity_smoother").get("max_velocity", [SMOOTHER_MAX_X_DEFAULT])
        if isinstance(smoother, list) and smoother:
            speed = min(speed, number("velocity_smoother", "max_velocity[0]", smoother[0]))
        amcl = node_parameters(nodes, "amcl")
        return cls(path, number("amcl", "transform_tolerance", amcl.get("transform_tolerance", 1.0)), speed)
