"""Nav2's costmap filters: zones drawn on a mask map that change the costmap (keepout) or the
robot's top speed (speed), after every layer of the costmap has updated.

A filter mask is an occupancy grid (a Nav2 map YAML and image, served by a ``map_server`` on its
own topic) whose values mean something only with the ``nav2_msgs/CostmapFilterInfo`` that
``costmap_filter_info_server`` publishes beside it: the filter ``type`` and the linear
conversion ``base + multiplier · value``. A costmap's ``filters`` list names its filters, each
with ``<name>.plugin`` (a type of the ``pppbot_nav.costmap_filters`` entry-point group) and
Nav2's parameters under ``<name>.``:

* ``nav2_costmap_2d::KeepoutFilter``: each mask cell becomes a cost (unknown −1 → no
  information, 0 → free, 100 → lethal, linearly between, as Nav2's ``getMaskCost``) that
  raises the costmap's cell, never lowers it; unknown mask cells leave the costmap as it is.
  With ``override_lethal_cost``, while the robot stands in a lethal keepout cell (put there by
  hand, or localized into one) the zone's lethal cells cost ``lethal_override_cost`` instead,
  so the robot can be planned out of it, as Nav2 Jazzy's.
* ``nav2_costmap_2d::SpeedFilter``: the mask value under the robot gives its speed limit:
  0 → no limit, otherwise ``base + multiplier · value``, in % of the top speed (info type 1,
  within (0, 100]) or in m/s (type 2, ≥ 0). A change is published on ``speed_limit_topic``
  (``nav2_msgs/SpeedLimit``, 0 meaning no limit) for the controller server; the robot off the
  mask, on an unknown cell or a limit out of range gives no limit, with a warning.

This module is ROS-free: :mod:`pppbot_nav.ros.costmap_node` feeds it the info, mask and poses.
"""
from __future__ import annotations

import math
from collections.abc import Collection
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from pppbot_common.params import ParameterError, check_finite_range, param
from pppbot_nav.costmap.costs import LETHAL_OBSTACLE, MAX_NON_OBSTACLE, NO_INFORMATION
from pppbot_nav.costmap.grid import Costmap
from pppbot_nav.costmap.interface import LayerContext

#: CostmapFilterInfo's types (Nav2's ``nav2_costmap_2d/cost_values`` enum).
KEEPOUT, SPEED_PERCENT, SPEED_ABSOLUTE, BINARY = 0, 1, 2, 3
#: SpeedLimit's "no limit".
NO_SPEED_LIMIT = 0.0
#: What the mask gives outside it.
OUTSIDE = -2


@dataclass(frozen=True)
class FilterInfo:
    """A ``nav2_msgs/CostmapFilterInfo``: the filter's type, its mask's topic and the conversion."""

    type: int
    mask_topic: str
    base: float = 0.0
    multiplier: float = 1.0


@dataclass(frozen=True)
class FilterMask:
    """A mask map: ``values[row, col]`` −1 (unknown) or 0..100, row 0 at the bottom, cell (0, 0)'s
    corner at ``origin`` (x, y, yaw) in ``frame_id``."""

    values: np.ndarray  # int8 (height, width)
    resolution: float
    origin: tuple[float, float, float]
    frame_id: str = "map"

    def value_at(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """The values at points in the mask's frame; :data:`OUTSIDE` off the mask."""
        ox, oy, oyaw = self.origin
        c, s = math.cos(oyaw), math.sin(oyaw)
        dx, dy = np.asarray(x, dtype=float) - ox, np.asarray(y, dtype=float) - oy
        col = np.floor((c * dx + s * dy) / self.resolution).astype(np.int64)
        row = np.floor((-s * dx + c * dy) / self.resolution).astype(np.int64)
        height, width = self.values.shape
        inside = (col >= 0) & (col < width) & (row >= 0) & (row < height)
        picked = self.values[np.where(inside, row, 0), np.where(inside, col, 0)].astype(np.int16)
        return np.where(inside, picked, OUTSIDE)


def mask_costs(values: np.ndarray) -> np.ndarray:
    """Mask values as costmap costs, as Nav2's ``getMaskCost``: −1 → no information, else
    ``round(value · 254 / 100)`` (100 → lethal). Values off the mask (:data:`OUTSIDE`) → no information."""
    values = np.asarray(values)
    scaled = np.rint(np.clip(values, 0, 100) * (LETHAL_OBSTACLE / 100.0)).astype(np.uint8)
    return np.where(values < 0, NO_INFORMATION, scaled).astype(np.uint8)


Transform = tuple[float, float, float]  # x, y, yaw of a frame in another


def _to_mask(transform: Transform, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points of the costmap's frame in the mask's, ``transform`` being the costmap frame's pose there."""
    tx, ty, yaw = transform
    c, s = math.cos(yaw), math.sin(yaw)
    return tx + c * x - s * y, ty + s * x + c * y


class CostmapFilter:
    """What every filter has: its info and mask, once both have come."""

    plugin: ClassVar[str] = ""

    def __init__(self, name: str, enabled: bool, filter_info_topic: str) -> None:
        self.name = name
        self.enabled = enabled
        self.filter_info_topic = filter_info_topic
        self.info: FilterInfo | None = None
        self.mask: FilterMask | None = None

    def expected_types(self) -> Collection[int]:
        raise NotImplementedError

    def set_info(self, info: FilterInfo) -> None:
        """Raises ValueError: an info of a type this filter does not take (the message says which)."""
        if info.type not in self.expected_types():
            raise ValueError(f"{self.name}: CostmapFilterInfo type {info.type} is not one {type(self).__name__} "
                             f"takes ({', '.join(map(str, self.expected_types()))})")
        if self.info is not None and self.info.mask_topic != info.mask_topic:
            self.mask = None
        self.info = info

    @property
    def ready(self) -> bool:
        return self.enabled and self.info is not None and self.mask is not None


class KeepoutFilter(CostmapFilter):
    plugin = "nav2_costmap_2d::KeepoutFilter"

    def __init__(self, name: str, enabled: bool, filter_info_topic: str, override_lethal_cost: bool = False,
                 lethal_override_cost: int = MAX_NON_OBSTACLE) -> None:
        super().__init__(name, enabled, filter_info_topic)
        self.override_lethal_cost = override_lethal_cost
        self.lethal_override_cost = lethal_override_cost

    def expected_types(self) -> Collection[int]:
        return (KEEPOUT,)

    def apply(self, master: Costmap, to_mask: Transform, robot_xy: tuple[float, float] | None) -> None:
        """Raise ``master``'s cells to the mask's costs (``to_mask``: the master frame's pose in the mask's)."""
        if not self.ready:
            return
        assert self.mask is not None
        height, width = master.costs.shape
        cols = master.origin[0] + (np.arange(width) + 0.5) * master.resolution
        rows = master.origin[1] + (np.arange(height) + 0.5) * master.resolution
        x, y = np.meshgrid(cols, rows)
        mx, my = _to_mask(to_mask, x, y)
        costs = mask_costs(self.mask.value_at(mx, my))
        if self.override_lethal_cost and robot_xy is not None:
            rx, ry = _to_mask(to_mask, np.array(robot_xy[0]), np.array(robot_xy[1]))
            if mask_costs(self.mask.value_at(rx, ry)) == LETHAL_OBSTACLE:
                costs = np.where(costs == LETHAL_OBSTACLE, np.uint8(self.lethal_override_cost), costs)
        old = master.costs
        raise_it = (costs != NO_INFORMATION) & ((costs > old) | (old == NO_INFORMATION))
        master.costs[raise_it] = costs[raise_it]


@dataclass(frozen=True)
class SpeedLimit:
    """A ``nav2_msgs/SpeedLimit``: ``speed_limit`` in % of the top speed (``percentage``) or m/s; 0: none."""

    speed_limit: float
    percentage: bool


class SpeedFilter(CostmapFilter):
    plugin = "nav2_costmap_2d::SpeedFilter"

    def __init__(self, name: str, enabled: bool, filter_info_topic: str, speed_limit_topic: str = "speed_limit"
                 ) -> None:
        super().__init__(name, enabled, filter_info_topic)
        self.speed_limit_topic = speed_limit_topic
        self.limit = SpeedLimit(NO_SPEED_LIMIT, True)
        #: Why the last limit is "none" although the robot is on the mask (a warning to give).
        self.problem: str | None = None

    def expected_types(self) -> Collection[int]:
        return (SPEED_PERCENT, SPEED_ABSOLUTE)

    def update(self, to_mask: Transform, robot_xy: tuple[float, float]) -> SpeedLimit | None:
        """The limit at the robot (x, y in the costmap's frame; ``to_mask``: that frame's pose in the
        mask's) when it differs from the last one given, else None."""
        self.problem = None
        if not self.ready:
            return None
        assert self.mask is not None and self.info is not None
        percentage = self.info.type == SPEED_PERCENT
        value = int(self.mask.value_at(*_to_mask(to_mask, np.array(robot_xy[0]), np.array(robot_xy[1]))))
        limit = NO_SPEED_LIMIT
        if value == OUTSIDE:
            self.problem = "the robot is off the speed mask: no speed limit"
        elif value < 0:
            self.problem = "the robot is on an unknown cell of the speed mask: no speed limit"
        elif value > 0:
            limit = self.info.base + self.info.multiplier * value
            if (percentage and not 0.0 < limit <= 100.0) or (not percentage and limit < 0.0):
                allowed = "(0, 100] %" if percentage else "≥ 0 m/s"
                self.problem = f"speed limit {limit:g} from mask value {value} is out of {allowed}: no speed limit"
                limit = NO_SPEED_LIMIT
        new = SpeedLimit(limit, percentage)
        if new.speed_limit == self.limit.speed_limit:  # Nav2 compares the value only
            return None
        self.limit = new
        return new


@dataclass(frozen=True)
class FilterParameters:
    """What every costmap filter has (Nav2's CostmapFilter): its switch, its CostmapFilterInfo topic,
    and how old a transform it uses may be. Only ``enabled`` may change while it runs."""

    LIVE_PARAMETERS: ClassVar[Collection[str] | None] = frozenset({"enabled"})

    enabled: bool = param(True, "a disabled filter does nothing")
    filter_info_topic: str = param("", "the CostmapFilterInfo topic (Nav2: no default, required)")
    transform_tolerance: float = param(0.1, "how old the mask frame → costmap frame transform may be (s)")

    def validate(self) -> None:
        if not self.filter_info_topic:
            raise ParameterError("filter_info_topic", self.filter_info_topic, "must name the CostmapFilterInfo "
                                 "topic (costmap_filter_info_server's filter_info_topic, e.g. /costmap_filter_info)")
        check_finite_range("transform_tolerance", self.transform_tolerance, 0.0, 60.0)


@dataclass(frozen=True)
class KeepoutFilterParameters(FilterParameters):
    enabled: bool = param(True, "a disabled filter leaves the costmap as it is")
    override_lethal_cost: bool = param(False, "while the robot is in a lethal keepout cell, the zone costs "
                                              "lethal_override_cost instead (so it can leave)")
    lethal_override_cost: int = param(MAX_NON_OBSTACLE, "the cost of the zone's lethal cells then (0..252)")

    def validate(self) -> None:
        super().validate()
        check_finite_range("lethal_override_cost", self.lethal_override_cost, 0, MAX_NON_OBSTACLE)

    def make(self, context: LayerContext) -> KeepoutFilter:
        return KeepoutFilter(context.name, self.enabled, self.filter_info_topic, self.override_lethal_cost,
                             self.lethal_override_cost)


@dataclass(frozen=True)
class SpeedFilterParameters(FilterParameters):
    enabled: bool = param(True, "a disabled filter sets no speed limit")
    speed_limit_topic: str = param("speed_limit", "where speed limits go (nav2_msgs/SpeedLimit), for the "
                                                  "controller server")

    def validate(self) -> None:
        super().validate()
        if not self.speed_limit_topic:
            raise ParameterError("speed_limit_topic", self.speed_limit_topic, "must name a topic")

    def make(self, context: LayerContext) -> SpeedFilter:
        return SpeedFilter(context.name, self.enabled, self.filter_info_topic, self.speed_limit_topic)


def limited(command: tuple[float, float], limit: SpeedLimit, top_speed: float) -> tuple[float, float]:
    """A (v, ω) command under ``limit``: |v| capped at a percentage of ``top_speed`` (the
    controller's, m/s) or at an absolute m/s, ω scaled with it so the curvature is kept. No limit:
    the command as it is."""
    v, w = command
    if limit.speed_limit == NO_SPEED_LIMIT:
        return command
    cap = top_speed * limit.speed_limit / 100.0 if limit.percentage else limit.speed_limit
    if abs(v) <= cap:
        return command
    scale = cap / abs(v)
    return v * scale, w * scale
