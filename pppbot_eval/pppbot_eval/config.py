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

from pppbot_common.errors import ArgumentError
from pppbot_eval.scenarios import Scenario

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
    view: bool = False
    json: bool = False
    log_level: str = "info"

    @classmethod
    def from_flags(cls, flags: object, max_wheel_slip: float) -> EvalConfig:
        """The config of parsed flags (an argparse namespace with these fields' names), checked."""
        values = {f.name: getattr(flags, f.name) for f in dataclasses.fields(cls) if hasattr(flags, f.name)}
        values["scenario"] = Scenario(values["scenario"])
        for name in ("map_pose", "initial_offset", "start"):
            if name in values:
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
                             ("--initial-offset", self.initial_offset)):
            if not all(math.isfinite(v) for v in triple):
                raise ArgumentError(f"{flag} {' '.join(map(str, triple))}: must be three finite numbers")
        if self.scenario is Scenario.MAP and self.map is None:
            raise ArgumentError("--map: the map scenario needs it")
        if self.map is not None and self.scenario not in MAP_SCENARIOS:
            raise ArgumentError(f"--map: only the map, localization and navigation scenarios take it, "
                                f"not {self.scenario.value}")
        if self.params_file is not None and not self.params_file.is_file():
            raise ArgumentError(f"--params-file {self.params_file}: no such file")
        if self.goals < 1:
            raise ArgumentError(f"--goals {self.goals}: must be at least 1")
        if not (math.isfinite(self.goal_distance) and self.goal_distance >= 0):
            raise ArgumentError(f"--goal-distance {self.goal_distance}: must be a non-negative number of metres")
        if not (0.0 <= self.min_success_rate <= 1.0):
            raise ArgumentError(f"--min-success-rate {self.min_success_rate}: must be in [0, 1]")
        if self.seed < 0:
            raise ArgumentError(f"--seed {self.seed}: must be a non-negative integer")
        if self.timeout is not None and not (math.isfinite(self.timeout) and self.timeout > 0):
            raise ArgumentError(f"--timeout {self.timeout}: must be a positive number of sim seconds")
        return dataclasses.replace(self, real_time_factor=rtf)
