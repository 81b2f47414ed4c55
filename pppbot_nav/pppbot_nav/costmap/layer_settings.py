"""The costmap plugins' parameters, by Nav2's plugin type, and the layers they make.

A costmap's ``plugins`` names its layers; each layer's ``<name>.plugin`` is a type of the
``pppbot_nav.costmap_layers`` entry-point group (Nav2's ``nav2_costmap_2d::StaticLayer``,
``ObstacleLayer``, ``VoxelLayer``, ``InflationLayer``, registered in ``pppbot_nav/setup.py``, or a
user's: :mod:`pppbot_nav.costmap.interface`) and its parameters sit under ``<name>.``, Nav2's
names and defaults. An obstacle or voxel layer's
``observation_sources`` (space-separated) names its sources, each with its parameters under
``<name>.<source>.`` (:class:`SourceParameters`).

Nav2's keys that mean nothing for a planar costmap are not declared; the node names them in
its start-up warning with :data:`NO_EFFECT`'s reasons.
"""
from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass
from typing import ClassVar

from pppbot_common.params import ParameterError, check_finite_range, param
from pppbot_nav.costmap.interface import LayerContext
from pppbot_nav.costmap.layers import COMBINATION_METHODS, InflationLayer, ObservationSource, ObstacleLayer, StaticLayer
from pppbot_nav.errors import CostmapError

STATIC = "nav2_costmap_2d::StaticLayer"
OBSTACLE = "nav2_costmap_2d::ObstacleLayer"
VOXEL = "nav2_costmap_2d::VoxelLayer"
INFLATION = "nav2_costmap_2d::InflationLayer"

#: The type a layer without ``<name>.plugin`` gets: Nav2's default layers, and ppp_bot's voxel_layer.
DEFAULT_TYPES = {"static_layer": STATIC, "obstacle_layer": OBSTACLE, "voxel_layer": VOXEL,
                 "inflation_layer": INFLATION}

_PLANAR = "pppbot's costmaps and transforms are planar: a scan's returns have no height to filter"
#: Nav2 keys (patterns, ``*`` any name) read by Nav2 and meaning nothing here, with the reason.
NO_EFFECT = {
    "*.max_obstacle_height": _PLANAR,
    "*.*.max_obstacle_height": _PLANAR,
    "*.*.min_obstacle_height": _PLANAR,
    "*.origin_z": _PLANAR,
    "*.z_resolution": _PLANAR,
    "*.z_voxels": _PLANAR,
    "*.unknown_threshold": _PLANAR,
    "*.publish_voxel_map": "a planar voxel layer has no voxel grid to publish",
    "*.*.expected_update_rate": "pppbot's costmaps are never marked out of date",
    "*.transform_tolerance": "pppbot waits for each scan's own transform (up to 20 scans) instead",
    "*.restore_cleared_footprint": "the static layer never clears the footprint here",
    "*.footprint_clearing_enabled": "only obstacle layers clear the footprint here (a static layer's map stays)",
    "*.subscribe_to_updates": "map_server and slam publish whole maps, no map updates",
    "always_send_full_costmap": "pppbot always publishes the whole costmap",
    "footprint": "the footprint is a circle of robot_radius",
    "transform_tolerance": "pppbot waits for each scan's own transform (up to 20 scans) instead",
    "initial_transform_timeout": "the costmap starts without waiting for a transform",
    "use_maximum": "layers are combined by each layer's own method",
    "unknown_cost_value": "unknown cells are always 255 (NO_INFORMATION)",
    "trinary_costmap": "a map's values are always read trinary (lethal_cost_threshold)",
    "clearable_layers": "every obstacle layer is cleared by the clear services",
    "filters": "keepout and speed filters are not implemented",
    "use_sim_time": "",
}


@dataclass(frozen=True)
class StaticLayerParameters:
    #: What may change while the costmap runs (the rest is refused), as Nav2's dynamic parameters.
    LIVE_PARAMETERS: ClassVar[Collection[str] | None] = frozenset({"enabled"})

    enabled: bool = param(True, "a disabled layer leaves the master as it is")
    map_topic: str = param("", "the map topic (transient local); empty: the costmap's map_topic")
    map_subscribe_transient_local: bool = param(True, "subscribe to the map latched (transient local)")

    def validate(self) -> None:
        pass

    def make(self, context: LayerContext) -> StaticLayer:
        return StaticLayer(context.track_unknown_space, context.lethal_cost_threshold, enabled=self.enabled)


@dataclass(frozen=True)
class ObstacleLayerParameters:
    #: What may change while the costmap runs (the rest is refused), as Nav2's dynamic parameters.
    LIVE_PARAMETERS: ClassVar[Collection[str] | None] = frozenset({
        "enabled", "footprint_clearing_enabled", "combination_method"})

    enabled: bool = param(True, "a disabled layer leaves the master as it is")
    footprint_clearing_enabled: bool = param(True, "free the cells under the robot")
    combination_method: int = param(1, "0 overwrite, 1 maximum, 2 maximum without unknown overwriting")
    observation_sources: str = param("", "the sources (space-separated); each has its parameters under its name")

    def validate(self) -> None:
        if self.combination_method not in COMBINATION_METHODS:
            raise ParameterError("combination_method", self.combination_method,
                                 f"must be one of {sorted(COMBINATION_METHODS)}")

    def sources(self) -> list[str]:
        return self.observation_sources.split()

    def make(self, context: LayerContext) -> ObstacleLayer:
        return ObstacleLayer(context.track_unknown_space, combination_method=self.combination_method,
                             footprint_clearing_enabled=self.footprint_clearing_enabled, enabled=self.enabled)


@dataclass(frozen=True)
class VoxelLayerParameters(ObstacleLayerParameters):
    mark_threshold: int = param(0, "a column is marked with more voxels than this (a planar scan has one)")

    def validate(self) -> None:
        super().validate()
        if self.mark_threshold < 0:
            raise ParameterError("mark_threshold", self.mark_threshold, "must be ≥ 0")

    def make(self, context: LayerContext) -> ObstacleLayer:
        return ObstacleLayer(context.track_unknown_space, combination_method=self.combination_method,
                             footprint_clearing_enabled=self.footprint_clearing_enabled,
                             mark_threshold=self.mark_threshold, enabled=self.enabled)


@dataclass(frozen=True)
class SourceParameters:
    """One observation source (``<layer>.<source>.``); its ``topic`` defaults to its name."""

    topic: str = param("", "the topic (relative names are global here); default: the source's name")
    sensor_frame: str = param("", "the sensor's frame; empty: the message's")
    data_type: str = param("LaserScan", "the message type: LaserScan")
    observation_persistence: float = param(0.0, "how long a scan is applied (s); 0: the newest only")
    marking: bool = param(True, "the source marks obstacles")
    clearing: bool = param(False, "the source clears along its beams")
    inf_is_valid: bool = param(False, "a beam with no return (inf) clears up to raytrace_max_range")
    obstacle_max_range: float = param(2.5, "mark returns up to this range (m)")
    obstacle_min_range: float = param(0.0, "mark returns from this range (m)")
    raytrace_max_range: float = param(3.0, "clear along beams up to this range (m)")
    raytrace_min_range: float = param(0.0, "clear from this range (m)")

    def validate(self) -> None:
        if self.data_type != "LaserScan":
            raise ParameterError("data_type", self.data_type,
                                 "must be LaserScan (pppbot's obstacle layers read 2D scans; PointCloud2 is not read)")
        check_finite_range("observation_persistence", self.observation_persistence, 0.0, 3600.0)
        try:
            self.source().validate()
        except CostmapError as exc:
            raise ParameterError(str(exc).split(" ")[0], "", str(exc)) from exc

    def source(self) -> ObservationSource:
        return ObservationSource(self.marking, self.clearing, self.obstacle_max_range, self.obstacle_min_range,
                                 self.raytrace_max_range, self.raytrace_min_range, self.inf_is_valid)


@dataclass(frozen=True)
class InflationLayerParameters:
    #: What may change while the costmap runs (the rest is refused), as Nav2's dynamic parameters.
    LIVE_PARAMETERS: ClassVar[Collection[str] | None] = frozenset({
        "enabled", "inflation_radius", "cost_scaling_factor", "inflate_unknown", "inflate_around_unknown"})

    enabled: bool = param(True, "a disabled layer leaves the master as it is")
    inflation_radius: float = param(0.55, "radius (m)")
    cost_scaling_factor: float = param(10.0, "exponential decay (1/m)")
    inflate_unknown: bool = param(False, "inflate into unknown cells")
    inflate_around_unknown: bool = param(False, "unknown cells are inflated around as obstacles are")

    def validate(self) -> None:
        check_finite_range("inflation_radius", self.inflation_radius, 0.0, 100.0)
        check_finite_range("cost_scaling_factor", self.cost_scaling_factor, 0.0, 1000.0)

    def make(self, context: LayerContext) -> InflationLayer:
        return InflationLayer(self.inflation_radius, self.cost_scaling_factor, context.robot_radius,
                              self.inflate_unknown, enabled=self.enabled,
                              inflate_around_unknown=self.inflate_around_unknown)
