"""Costmap layers (Nav2's ``nav2_costmap_2d`` plugins), applied in order onto a master costmap.

* :class:`StaticLayer` (``nav2_costmap_2d::StaticLayer``): a map (nav_msgs/OccupancyGrid
  values): cells at or above ``lethal_cost_threshold`` are lethal, unknown cells stay
  unknown with ``track_unknown_space`` (else free), the rest free. It overwrites the master.
* :class:`ObstacleLayer` (``nav2_costmap_2d::ObstacleLayer``): each observation (a scan's
  beams from one of its ``observation_sources``) clears the cells along each beam up to its
  end point when the source is ``clearing`` (beams with no return only with
  ``inf_is_valid``, as Nav2 drops them otherwise), and marks the end points within
  ``obstacle_min_range`` … ``obstacle_max_range`` when it is ``marking``. Its cells are
  combined with the master by ``combination_method`` (0 overwrite, 1 maximum, 2 maximum
  without unknown overwriting); with ``footprint_clearing_enabled`` the cells under the
  robot are freed.
* The same class stands for ``nav2_costmap_2d::VoxelLayer`` projected to 2D
  (``mark_threshold``): a planar scan puts one voxel in each column it hits, so a column is
  marked when one voxel is more than ``mark_threshold`` (0, Nav2's default: every hit).
* :class:`InflationLayer` (``nav2_costmap_2d::InflationLayer``): around every lethal cell,
  253 within ``inscribed_radius`` (the robot's radius) and ``252·exp(−cost_scaling_factor·(d −
  inscribed_radius))`` out to ``inflation_radius``, combined by maximum (an unknown master cell
  takes an inscribed or lethal cost only, unless ``inflate_unknown``); with
  ``inflate_around_unknown`` unknown cells are inflated around as lethal ones are.

Every layer has ``enabled``: a disabled layer leaves the master as it is.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from pppbot_common.maps import OccupancyGrid
from pppbot_nav.costmap.costs import FREE_SPACE, INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE, NO_INFORMATION
from pppbot_nav.costmap.grid import Costmap
from pppbot_nav.costmap.interface import Layer  # noqa: F401 (its old home)
from pppbot_nav.errors import CostmapError


class StaticLayer:
    plugin = "nav2_costmap_2d::StaticLayer"

    def __init__(self, track_unknown_space: bool = True, lethal_cost_threshold: int = 100, *,
                 enabled: bool = True) -> None:
        if not 1 <= lethal_cost_threshold <= 100:
            raise CostmapError(f"lethal_cost_threshold must be in [1, 100], not {lethal_cost_threshold}")
        self.enabled = enabled
        self.track_unknown_space = track_unknown_space
        self.lethal_cost_threshold = lethal_cost_threshold
        self.map: OccupancyGrid | None = None
        #: The map's costs over the master's last geometry: a window that has not moved (the
        #: global costmap, a robot standing still) takes them again without a lookup.
        self._window: tuple[tuple[object, ...], np.ndarray, np.ndarray] | None = None

    def set_map(self, grid: OccupancyGrid) -> None:
        if grid.origin[2] != 0.0:
            raise CostmapError(f"a map with a rotated origin (yaw {grid.origin[2]}) is not supported")
        self.map = grid
        self._window = None

    def costs_of(self, values: np.ndarray) -> np.ndarray:
        """Costs of OccupancyGrid values."""
        unknown = NO_INFORMATION if self.track_unknown_space else FREE_SPACE
        return np.where(values < 0, unknown, np.where(values >= self.lethal_cost_threshold, LETHAL_OBSTACLE,
                                                      FREE_SPACE)).astype(np.uint8)

    def update(self, master: Costmap) -> None:
        if self.map is None:
            return
        geometry = (master.origin, master.costs.shape, master.resolution)
        if self._window is None or self._window[0] != geometry:
            xs, ys = master.cell_centres()
            rows, cols = self.map.cell_of(xs, ys)
            h, w = self.map.data.shape
            ok = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
            values = self.map.data[np.where(ok, rows, 0), np.where(ok, cols, 0)]
            self._window = (geometry, ok, self.costs_of(values)[ok])
        _, ok, costs = self._window
        master.costs[ok] = costs


def combine_max(master: Costmap, layer: np.ndarray) -> None:
    """Nav2's ``updateWithMax``: the layer's unknown cells leave the master alone; its known ones
    replace an unknown master cell or a lower cost."""
    known = layer != NO_INFORMATION
    take = known & ((master.costs == NO_INFORMATION) | (master.costs < layer))
    master.costs[take] = layer[take]


@dataclass(frozen=True)
class ObservationSource:
    """One of an obstacle layer's ``observation_sources``: what its scans mark and clear (Nav2's
    per-source parameters and defaults)."""

    marking: bool = True
    clearing: bool = False
    obstacle_max_range: float = 2.5  # m
    obstacle_min_range: float = 0.0  # m
    raytrace_max_range: float = 3.0  # m
    raytrace_min_range: float = 0.0  # m
    inf_is_valid: bool = False  # a beam with no return clears up to raytrace_max_range

    def validate(self) -> None:
        """Raises CostmapError naming a bad range."""
        for name in ("obstacle_max_range", "obstacle_min_range", "raytrace_max_range", "raytrace_min_range"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise CostmapError(f"{name} must be a finite number ≥ 0, not {value}")


#: Nav2's ``combination_method`` values.
COMBINATION_METHODS = {0: "overwrite", 1: "maximum", 2: "maximum, unknown never overwriting"}


class ObstacleLayer:
    plugin = "nav2_costmap_2d::ObstacleLayer"

    def __init__(self, track_unknown_space: bool = False, *, combination_method: int = 1,
                 footprint_clearing_enabled: bool = True, mark_threshold: int | None = None,
                 enabled: bool = True) -> None:
        """``mark_threshold`` None: an obstacle layer; a number: a voxel layer projected to 2D."""
        if combination_method not in COMBINATION_METHODS:
            raise CostmapError(f"combination_method must be one of {sorted(COMBINATION_METHODS)} "
                               f"({', '.join(f'{k}: {v}' for k, v in COMBINATION_METHODS.items())}), "
                               f"not {combination_method}")
        if mark_threshold is not None and mark_threshold < 0:
            raise CostmapError(f"mark_threshold must be ≥ 0, not {mark_threshold}")
        self.unknown = NO_INFORMATION if track_unknown_space else FREE_SPACE
        self.combination_method = combination_method
        self.footprint_clearing_enabled = footprint_clearing_enabled
        self.mark_threshold = mark_threshold
        self.enabled = enabled
        if mark_threshold is not None:
            self.plugin = "nav2_costmap_2d::VoxelLayer"
        self.grid: Costmap | None = None  # this layer's own cells, the master's geometry

    def _match(self, master: Costmap) -> Costmap:
        g = self.grid
        if g is None or g.costs.shape != master.costs.shape or g.resolution != master.resolution:
            g = self.grid = Costmap(np.full(master.costs.shape, self.unknown, dtype=np.uint8), master.resolution,
                                    master.origin, master.frame_id)
        elif g.origin != master.origin:
            g.recentre(master.origin[0] + master.width * master.resolution / 2.0,
                       master.origin[1] + master.height * master.resolution / 2.0, self.unknown)
        return g

    def observe(self, master: Costmap, sensor_xy: tuple[float, float], bearings_rad: np.ndarray,
                ranges_m: np.ndarray, source: ObservationSource = ObservationSource()) -> None:
        """One scan of ``source`` from ``sensor_xy`` (in the costmap's frame): beams with world
        ``bearings_rad`` and ``ranges_m`` (inf or NaN: no return). Clears along each beam, then
        marks the end points (see the module doc)."""
        grid = self._match(master)
        ranges = np.asarray(ranges_m, dtype=float)
        bearings = np.asarray(bearings_rad, dtype=float)
        hit = np.isfinite(ranges)
        if source.clearing:
            # Up to the end point (its own cell is left to marking), or raytrace_max_range.
            no_return = np.inf if source.inf_is_valid else -np.inf
            reach = np.minimum(np.where(hit, ranges, no_return), source.raytrace_max_range)
            step = grid.resolution / 2.0
            steps = np.arange(0.0, max(float(reach.max(initial=0.0)), 0.0), step)
            if steps.size:
                t = steps[None, :]
                along = (t >= source.raytrace_min_range) & (t < reach[:, None] - step)
                xs = sensor_xy[0] + t * np.cos(bearings)[:, None]
                ys = sensor_xy[1] + t * np.sin(bearings)[:, None]
                rows, cols = grid.cell_of(xs[along], ys[along])
                ok = grid.inside(rows, cols)
                grid.costs[rows[ok], cols[ok]] = FREE_SPACE
        # A planar scan is one voxel per column: it marks only when one is above the threshold.
        if not source.marking or (self.mark_threshold is not None and self.mark_threshold >= 1):
            return
        mark = hit & (ranges <= source.obstacle_max_range) & (ranges >= source.obstacle_min_range)
        ex = sensor_xy[0] + ranges[mark] * np.cos(bearings[mark])
        ey = sensor_xy[1] + ranges[mark] * np.sin(bearings[mark])
        rows, cols = grid.cell_of(ex, ey)
        ok = grid.inside(rows, cols)
        grid.costs[rows[ok], cols[ok]] = LETHAL_OBSTACLE

    def clear_footprint(self, robot_xy: tuple[float, float], radius_m: float) -> None:
        """Free this layer's cells under the robot's (circular) footprint, as Nav2's
        ``footprint_clearing_enabled``."""
        if self.grid is None or not self.footprint_clearing_enabled:
            return
        g = self.grid
        xs = g.origin[0] + (np.arange(g.width) + 0.5) * g.resolution - robot_xy[0]
        ys = g.origin[1] + (np.arange(g.height) + 0.5) * g.resolution - robot_xy[1]
        under = ys[:, None] ** 2 + xs[None, :] ** 2 <= radius_m * radius_m
        g.costs[under & (g.costs == LETHAL_OBSTACLE)] = FREE_SPACE

    def clear_square(self, centre_xy: tuple[float, float], side_m: float, inside: bool = True) -> None:
        """Forget what was seen in the axis-aligned square of side ``side_m`` centred at ``centre_xy``
        (``inside=False``: everywhere but there), as Nav2's ``clearArea`` behind its
        ``clear_around_*`` and ``clear_except_*`` services."""
        if self.grid is None:
            return
        g = self.grid
        half = side_m / 2.0
        xs = g.origin[0] + (np.arange(g.width) + 0.5) * g.resolution
        ys = g.origin[1] + (np.arange(g.height) + 0.5) * g.resolution
        in_square = (np.abs(ys - centre_xy[1])[:, None] <= half) & (np.abs(xs - centre_xy[0])[None, :] <= half)
        g.costs[in_square if inside else ~in_square] = self.unknown

    def clear(self) -> None:
        """Forget every observation (Nav2's clear_entirely_* services)."""
        if self.grid is not None:
            self.grid.costs[:] = self.unknown

    def update(self, master: Costmap) -> None:
        costs = self._match(master).costs
        if self.combination_method == 0:  # Nav2's updateWithOverwrite: every known cell
            known = costs != NO_INFORMATION
            master.costs[known] = costs[known]
        elif self.combination_method == 1:
            combine_max(master, costs)
        else:  # updateWithMaxWithoutUnknownOverwrite: an unknown master cell stays unknown
            take = (costs != NO_INFORMATION) & (master.costs != NO_INFORMATION) & (master.costs < costs)
            master.costs[take] = costs[take]


class InflationLayer:
    plugin = "nav2_costmap_2d::InflationLayer"

    def __init__(self, inflation_radius: float = 0.55, cost_scaling_factor: float = 3.0,
                 inscribed_radius: float = 0.3, inflate_unknown: bool = False, *, enabled: bool = True,
                 inflate_around_unknown: bool = False) -> None:
        if not (math.isfinite(inflation_radius) and inflation_radius >= 0):
            raise CostmapError(f"inflation_radius must be a finite number ≥ 0, not {inflation_radius}")
        if not (math.isfinite(cost_scaling_factor) and cost_scaling_factor >= 0):
            raise CostmapError(f"cost_scaling_factor must be a finite number ≥ 0, not {cost_scaling_factor}")
        if not (math.isfinite(inscribed_radius) and inscribed_radius >= 0):
            raise CostmapError(f"the robot's inscribed radius must be a finite number ≥ 0, not {inscribed_radius}")
        self.inflation_radius, self.cost_scaling_factor = inflation_radius, cost_scaling_factor
        self.inscribed_radius, self.inflate_unknown = inscribed_radius, inflate_unknown
        self.enabled = enabled
        self.inflate_around_unknown = inflate_around_unknown
        #: The last lethal cells and the costs they spread (with the resolution): the next
        #: update inflates again only around the cells that changed, as Nav2 does within the
        #: layers' update bounds.
        self._spread: tuple[np.ndarray, float, np.ndarray] | None = None

    def forget(self) -> None:
        """Spread every cost afresh at the next update (a changed radius or scaling)."""
        self._spread = None

    def cost_at_distance(self, distance_m: np.ndarray) -> np.ndarray:
        """Nav2's ``computeCost`` of a distance (m) to the nearest lethal cell."""
        d = np.asarray(distance_m, dtype=float)
        decay = (INSCRIBED_INFLATED_OBSTACLE - 1) * np.exp(-self.cost_scaling_factor * (d - self.inscribed_radius))
        cost = np.where(d <= self.inscribed_radius, INSCRIBED_INFLATED_OBSTACLE, decay.astype(int))
        cost = np.where(d > self.inflation_radius, FREE_SPACE, cost)
        return np.where(d == 0.0, LETHAL_OBSTACLE, cost).astype(np.uint8)

    def spread(self, lethal: np.ndarray, resolution: float) -> np.ndarray:
        """The cost every cell gets from its nearest ``lethal`` cell. Where the lethal cells are
        those of the last call but for a few, only the cells within the inflation radius of a
        changed one are computed again (from the lethal cells within the radius of those):
        the global costmap takes one scan's worth of changes a second, not a whole map's. The
        array is read-only: the layer keeps it for the next call."""
        last = self._spread
        if last is None or last[1] != resolution or last[0].shape != lethal.shape:
            cost = self._spread_over(lethal, resolution)
        else:
            changed = lethal != last[0]
            if not changed.any():
                return last[2]
            rows, cols = np.flatnonzero(changed.any(axis=1)), np.flatnonzero(changed.any(axis=0))
            reach = int(math.ceil(self.inflation_radius / resolution)) + 1  # cells
            h, w = lethal.shape
            r0, r1 = max(rows[0] - reach, 0), min(rows[-1] + reach + 1, h)  # costs that may change
            c0, c1 = max(cols[0] - reach, 0), min(cols[-1] + reach + 1, w)
            s0, s1 = max(r0 - reach, 0), min(r1 + reach, h)  # lethal cells that may reach them
            t0, t1 = max(c0 - reach, 0), min(c1 + reach, w)
            around = self._spread_over(lethal[s0:s1, t0:t1], resolution)
            cost = last[2].copy()
            cost[r0:r1, c0:c1] = around[r0 - s0:r1 - s0, c0 - t0:c1 - t0]
        cost.flags.writeable = False
        self._spread = (lethal.copy(), resolution, cost)
        return cost

    def _spread_over(self, lethal: np.ndarray, resolution: float) -> np.ndarray:
        if not lethal.any():
            return np.full(lethal.shape, FREE_SPACE, dtype=np.uint8)
        return self.cost_at_distance(np.asarray(ndimage.distance_transform_edt(~lethal)) * resolution)

    def update(self, master: Costmap) -> None:
        lethal = master.costs == LETHAL_OBSTACLE
        if self.inflate_around_unknown:
            lethal |= master.costs == NO_INFORMATION
        if not lethal.any():
            return
        cost = self.spread(lethal, master.resolution)
        old = master.costs
        unknown = old == NO_INFORMATION
        floor = FREE_SPACE if self.inflate_unknown else INSCRIBED_INFLATED_OBSTACLE - 1
        take_unknown = unknown & (cost > floor)
        take_known = ~unknown & (cost > old)
        master.costs[take_unknown | take_known] = cost[take_unknown | take_known]


class LayeredCostmap:
    """A master costmap rebuilt from its layers in order; ``rolling`` windows follow the robot."""

    def __init__(self, master: Costmap, layers: list[Layer], rolling: bool = False,
                 default_value: int = NO_INFORMATION) -> None:
        self.master = master
        self.layers = layers
        self.rolling = rolling
        self.default_value = default_value

    def update(self, robot_xy: tuple[float, float] | None = None) -> Costmap:
        """Rebuild the master (recentred on ``robot_xy`` first when rolling) and return it."""
        if self.rolling and robot_xy is not None:
            self.master.recentre(robot_xy[0], robot_xy[1], self.default_value)
        self.master.costs[:] = self.default_value
        for layer in self.layers:
            if layer.enabled:
                layer.update(self.master)
        return self.master
