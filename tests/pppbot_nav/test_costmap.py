"""Costmap core: Nav2's cost values, the static, obstacle and inflation layers, rolling windows."""
from __future__ import annotations

import math

import numpy as np
import pytest

from pppbot_common.maps import OccupancyGrid
from pppbot_nav.costmap.costs import (
    FREE_SPACE,
    INSCRIBED_INFLATED_OBSTACLE,
    LETHAL_OBSTACLE,
    NO_INFORMATION,
    to_occupancy,
)
from pppbot_nav.costmap.grid import Costmap
from pppbot_nav.costmap.layers import InflationLayer, LayeredCostmap, ObservationSource, ObstacleLayer, StaticLayer
from pppbot_nav.errors import CostmapError

RES = 0.05


def blank(value: int = NO_INFORMATION, size_m: float = 4.0, origin=(-2.0, -2.0)) -> Costmap:
    return Costmap.filled(size_m, size_m, RES, origin, value)


def test_costs_publish_with_nav2s_occupancy_translation():
    costs = np.array([0, 1, 2, 126, 252, 253, 254, 255])
    assert to_occupancy(costs).tolist() == [0, 1, 1, 49, 98, 99, 100, -1]
    assert np.all(np.diff(to_occupancy(np.arange(0, 255)).astype(int)) >= 0)
    grid = Costmap(np.array([[0, 254], [255, 253]], dtype=np.uint8), RES, (1.0, 2.0)).to_occupancy_grid()
    assert grid.data.tolist() == [[0, 100], [-1, 99]] and grid.origin == (1.0, 2.0, 0.0)


def test_static_layer_makes_occupied_lethal_and_keeps_unknown_when_tracking_it():
    data = np.array([[0, 100, -1], [65, 99, 0]], dtype=np.int8)
    grid = OccupancyGrid(data, RES, (0.0, 0.0, 0.0))
    master = Costmap.filled(3 * RES, 2 * RES, RES, (0.0, 0.0), 7)
    layer = StaticLayer(track_unknown_space=True, lethal_cost_threshold=100)
    layer.set_map(grid)
    layer.update(master)
    assert master.costs.tolist() == [[FREE_SPACE, LETHAL_OBSTACLE, NO_INFORMATION],
                                     [FREE_SPACE, FREE_SPACE, FREE_SPACE]]
    assert StaticLayer(track_unknown_space=False, lethal_cost_threshold=65).costs_of(data).tolist() == \
        [[0, 254, 0], [254, 254, 0]]


def test_obstacle_layer_marks_hits_in_range_and_clears_along_beams():
    master = blank()
    layer = ObstacleLayer(track_unknown_space=True)
    source = ObservationSource(clearing=True, inf_is_valid=True, obstacle_max_range=1.5, raytrace_max_range=1.8)
    bearings = np.array([0.0, math.pi / 2, math.pi, -math.pi / 2])
    layer.observe(master, (0.0, 0.0), bearings, np.array([1.0, 1.7, np.inf, 0.5]), source)
    layer.update(master)
    assert master.cost_at(1.0 + RES / 4, 0.0, 0)[()] == LETHAL_OBSTACLE  # hit within range: marked
    assert master.cost_at(0.5, 0.0, 0)[()] == FREE_SPACE  # cleared on the way
    assert master.cost_at(0.0, 1.7 + RES / 4, 0)[()] != LETHAL_OBSTACLE  # beyond obstacle_max_range: not marked
    assert master.cost_at(0.0, 1.6, 0)[()] == FREE_SPACE  # but cleared up to it
    assert master.cost_at(-1.7, 0.0, 0)[()] == FREE_SPACE  # no return: cleared to raytrace_max_range
    assert master.cost_at(-1.9, 0.0, 0)[()] == NO_INFORMATION  # and not beyond
    # The obstacle goes away: a later beam through its cell clears it.
    layer.observe(master, (0.0, 0.0), np.array([0.0]), np.array([np.inf]), source)
    master.costs[:] = NO_INFORMATION
    layer.update(master)
    assert master.cost_at(1.0 + RES / 4, 0.0, 0)[()] == FREE_SPACE
    layer.clear()
    master.costs[:] = 17
    layer.update(master)
    assert np.all(master.costs == 17)  # unknown layer cells leave the master alone


def test_inflation_costs_follow_nav2s_formula_around_lethal_cells():
    layer = InflationLayer(inflation_radius=0.55, cost_scaling_factor=3.0, inscribed_radius=0.3)
    d = np.array([0.0, 0.1, 0.3, 0.35, 0.5, 0.55, 0.6])
    expected = [254, 253, 253, int(252 * math.exp(-3.0 * 0.05)), int(252 * math.exp(-3.0 * 0.2)),
                int(252 * math.exp(-3.0 * 0.25)), 0]
    assert layer.cost_at_distance(d).tolist() == expected
    master = blank(FREE_SPACE)
    master.costs[40, 40] = LETHAL_OBSTACLE
    master.costs[0:5, :] = NO_INFORMATION
    layer.update(master)
    xs, ys = master.cell_centres()
    centre = (xs[40, 40], ys[40, 40])
    dist = np.hypot(xs - centre[0], ys - centre[1])
    ring = (dist > 0) & (dist < 0.3 - 1e-6)
    assert np.all(master.costs[ring] == INSCRIBED_INFLATED_OBSTACLE)
    assert np.all(master.costs[(dist > 0.55 + 1e-6) & (master.costs != NO_INFORMATION)] == FREE_SPACE)
    assert master.costs[40, 48] < master.costs[40, 47]  # falls off with distance
    assert np.all(master.costs[0:5, :] == NO_INFORMATION)  # too far to reach: unknown stays unknown


def test_inflation_again_after_a_few_changes_equals_inflating_from_scratch():
    """The layer inflates again only around the lethal cells that changed: the costs must be
    those of a fresh layer, for changes near each other, far apart, at the edges, and none."""
    rng = np.random.default_rng(3)
    kept = InflationLayer(inflation_radius=0.55, cost_scaling_factor=3.0, inscribed_radius=0.3)
    lethal = np.zeros((120, 90), dtype=bool)
    lethal[30, 10:80] = lethal[10:100, 45] = True
    changes = [[(31, 20)], [(31, 20), (5, 5)], [], [(0, 0), (119, 89)], [(60, 45)],
               *[[tuple(rng.integers(0, (120, 90))) for _ in range(k)] for k in (1, 3, 8, 40)]]
    for change in changes:
        lethal = lethal.copy()
        for cell in change:
            lethal[cell] = not lethal[cell]
        fresh = InflationLayer(inflation_radius=0.55, cost_scaling_factor=3.0, inscribed_radius=0.3)
        assert np.array_equal(kept.spread(lethal, RES), fresh.spread(lethal, RES)), change
    lethal[:] = False  # every obstacle gone: nothing to spread
    assert not kept.spread(lethal, RES).any()


def test_rolling_window_keeps_cells_where_they_are_in_the_world():
    cm = Costmap.filled(2.0, 2.0, RES, (-1.0, -1.0), FREE_SPACE, frame_id="odom")
    row, col = cm.cell_of(0.52, -0.33)
    cm.costs[row, col] = LETHAL_OBSTACLE
    cm.recentre(0.7, 0.2, NO_INFORMATION)
    assert cm.origin == pytest.approx((-0.3, -0.8))
    assert cm.cost_at(0.52, -0.33, 0)[()] == LETHAL_OBSTACLE
    assert cm.cost_at(1.6, 0.2, 0)[()] == NO_INFORMATION  # new cells
    assert np.sum(cm.costs == LETHAL_OBSTACLE) == 1


def test_layered_costmap_combines_static_obstacle_and_inflation():
    data = np.zeros((80, 80), dtype=np.int8)
    data[:, 60] = 100  # a wall at x = 1.0
    static = StaticLayer()
    static.set_map(OccupancyGrid(data, RES, (-2.0, -2.0, 0.0)))
    obstacles = ObstacleLayer(track_unknown_space=True)
    costmap = LayeredCostmap(blank(), [static, obstacles, InflationLayer(0.55, 3.0, 0.3)])
    obstacles.observe(costmap.master, (0.0, 0.0), np.array([math.pi / 2]), np.array([1.0]))  # a box not in the map
    master = costmap.update()
    assert master.cost_at(1.0 + RES / 2, 0.0, 0)[()] == LETHAL_OBSTACLE
    assert master.cost_at(0.0, 1.0 + RES / 4, 0)[()] == LETHAL_OBSTACLE
    assert master.cost_at(0.0, 0.8, 0)[()] == INSCRIBED_INFLATED_OBSTACLE
    assert master.cost_at(-1.0, -1.0, 0)[()] == FREE_SPACE


def test_static_layer_follows_a_moved_window_and_a_new_map():
    """The layer keeps the map's costs for the window it last filled: a moved window or a new
    map must be looked up again."""
    data = np.zeros((80, 80), dtype=np.int8)
    data[:, 60] = 100  # a wall at x = 1.0
    static = StaticLayer()
    static.set_map(OccupancyGrid(data, RES, (-2.0, -2.0, 0.0)))
    costmap = LayeredCostmap(Costmap.filled(2.0, 2.0, RES, (-0.5, -1.0), NO_INFORMATION), [static], rolling=True)
    assert costmap.update((0.5, 0.0)).cost_at(1.0 + RES / 2, 0.0, 0)[()] == LETHAL_OBSTACLE
    assert not (costmap.update((-1.0, 0.0)).costs == LETHAL_OBSTACLE).any()  # the wall is off the window
    assert (costmap.update((0.5, 0.0)).costs == LETHAL_OBSTACLE).sum() == 40  # back: the wall's column
    data[:, 60] = 0
    data[:, 50] = 100  # the map changed: a wall at x = 0.5
    static.set_map(OccupancyGrid(data, RES, (-2.0, -2.0, 0.0)))
    master = costmap.update((0.5, 0.0))
    assert master.cost_at(0.5 + RES / 2, 0.0, 0)[()] == LETHAL_OBSTACLE
    assert master.cost_at(1.0 + RES / 2, 0.0, 0)[()] == FREE_SPACE


@pytest.mark.parametrize("make, name", [
    (lambda: ObservationSource(obstacle_max_range=-1.0).validate(), "obstacle_max_range"),
    (lambda: ObstacleLayer(combination_method=3), "combination_method"),
    (lambda: ObstacleLayer(mark_threshold=-1), "mark_threshold"),
    (lambda: InflationLayer(inflation_radius=math.nan), "inflation_radius"),
    (lambda: StaticLayer(lethal_cost_threshold=0), "lethal_cost_threshold"),
    (lambda: Costmap.filled(0.0, 1.0, RES, (0.0, 0.0), 0), "size"),
])
def test_bad_settings_are_refused_by_name(make, name):
    with pytest.raises(CostmapError, match=name):
        make()


def beam_ahead(layer: ObstacleLayer, master: Costmap, range_m: float, source: ObservationSource) -> None:
    layer.observe(master, (0.0, 0.0), np.array([0.0]), np.array([range_m]), source)


def test_a_source_that_only_marks_never_clears_and_no_return_clears_only_when_inf_is_valid():
    master = blank()
    layer = ObstacleLayer(track_unknown_space=True)
    beam_ahead(layer, master, 1.0, ObservationSource())  # Nav2's defaults: marking, not clearing
    layer.update(master)
    assert master.cost_at(1.0 + RES / 4, 0.0, 0)[()] == LETHAL_OBSTACLE
    assert master.cost_at(0.5, 0.0, 0)[()] == NO_INFORMATION  # nothing cleared on the way
    beam_ahead(layer, master, np.inf, ObservationSource(clearing=True))  # no return, inf_is_valid false
    layer.update(master)
    assert master.cost_at(1.0 + RES / 4, 0.0, 0)[()] == LETHAL_OBSTACLE  # Nav2 drops the beam
    beam_ahead(layer, master, np.inf, ObservationSource(clearing=True, inf_is_valid=True))
    master.costs[:] = NO_INFORMATION
    layer.update(master)
    assert master.cost_at(1.0 + RES / 4, 0.0, 0)[()] == FREE_SPACE
    beam_ahead(layer, master, 1.0, ObservationSource(marking=False, clearing=True))
    layer.update(master)
    assert master.cost_at(1.0 + RES / 4, 0.0, 0)[()] == FREE_SPACE  # a clearing-only source marks nothing


@pytest.mark.parametrize("threshold, marked", [(0, True), (1, False)])
def test_a_voxel_layer_marks_a_planar_scans_column_only_under_a_zero_mark_threshold(threshold, marked):
    master = blank()
    layer = ObstacleLayer(track_unknown_space=True, mark_threshold=threshold)
    beam_ahead(layer, master, 1.0, ObservationSource(clearing=True))
    layer.update(master)
    assert layer.plugin == "nav2_costmap_2d::VoxelLayer"
    assert bool(master.cost_at(1.0 + RES / 4, 0.0, 0)[()] == LETHAL_OBSTACLE) is marked
    assert master.cost_at(0.5, 0.0, 0)[()] == FREE_SPACE  # clearing either way


@pytest.mark.parametrize("method, expected", [(0, [FREE_SPACE, LETHAL_OBSTACLE, 77]),
                                              (1, [90, LETHAL_OBSTACLE, 77]),
                                              (2, [90, LETHAL_OBSTACLE, 77])])
def test_combination_methods_as_nav2s(method, expected):
    """Layer cells (free, lethal, unknown) over master cells (90, unknown, 77)."""
    layer = ObstacleLayer(track_unknown_space=True, combination_method=method)
    master = Costmap(np.array([[90, NO_INFORMATION, 77]], dtype=np.uint8), RES, (0.0, 0.0))
    layer.update(master)  # sizes the layer's own grid
    assert layer.grid is not None
    layer.grid.costs[:] = [[FREE_SPACE, LETHAL_OBSTACLE, NO_INFORMATION]]
    layer.update(master)
    if method == 2:
        expected = [90, NO_INFORMATION, 77]  # an unknown master cell is never overwritten
    assert master.costs.tolist() == [expected]


def test_footprint_clearing_frees_the_cells_under_the_robot_only_when_enabled():
    for enabled, left in ((True, FREE_SPACE), (False, LETHAL_OBSTACLE)):
        master = blank()
        layer = ObstacleLayer(track_unknown_space=True, footprint_clearing_enabled=enabled)
        beam_ahead(layer, master, 0.2, ObservationSource())  # a "return" under the robot itself
        beam_ahead(layer, master, 1.0, ObservationSource())
        layer.clear_footprint((0.0, 0.0), 0.3)
        layer.update(master)
        assert master.cost_at(0.2 + RES / 4, 0.0, 0)[()] == left
        assert master.cost_at(1.0 + RES / 4, 0.0, 0)[()] == LETHAL_OBSTACLE


def test_a_disabled_layer_leaves_the_master_alone_and_unknown_can_be_inflated_around():
    master = Costmap.filled(2.0, 2.0, RES, (-1.0, -1.0), FREE_SPACE)
    master.costs[20, 20] = NO_INFORMATION
    LayeredCostmap(master, [InflationLayer(0.55, 3.0, 0.3, enabled=False)], default_value=FREE_SPACE)
    around = InflationLayer(0.55, 3.0, 0.3, inflate_around_unknown=True)
    around.update(master)
    assert master.costs[20, 24] == INSCRIBED_INFLATED_OBSTACLE  # 0.2 m from the unknown cell
    plain = Costmap.filled(2.0, 2.0, RES, (-1.0, -1.0), FREE_SPACE)
    plain.costs[20, 20] = NO_INFORMATION
    off = LayeredCostmap(plain, [InflationLayer(0.55, 3.0, 0.3, inflate_around_unknown=True, enabled=False)],
                         default_value=FREE_SPACE)
    off.master.costs[20, 20] = NO_INFORMATION
    assert off.layers[0].enabled is False
    InflationLayer(0.55, 3.0, 0.3).update(plain)
    assert plain.costs[20, 24] == FREE_SPACE  # without inflate_around_unknown nothing spreads
