"""Nav2's costmap filters, ROS-free: the keepout filter raises a costmap to its mask's costs, the
speed filter turns the mask under the robot into a limit, and a limit caps a command."""
from __future__ import annotations

import math

import numpy as np
import pytest

from pppbot_common.params import ParameterError
from pppbot_nav.costmap.costs import LETHAL_OBSTACLE, MAX_NON_OBSTACLE, NO_INFORMATION
from pppbot_nav.costmap.filters import (
    KEEPOUT,
    NO_SPEED_LIMIT,
    OUTSIDE,
    SPEED_ABSOLUTE,
    SPEED_PERCENT,
    FilterInfo,
    FilterMask,
    KeepoutFilter,
    KeepoutFilterParameters,
    SpeedFilter,
    SpeedFilterParameters,
    SpeedLimit,
    limited,
    mask_costs,
)
from pppbot_nav.costmap.grid import Costmap
from pppbot_nav.costmap.interface import LayerContext

CONTEXT = LayerContext("f", "map", False, 100, 0.3)
#: The costmap's frame is the mask's.
HERE = (0.0, 0.0, 0.0)


def mask(values: np.ndarray, origin=(0.0, 0.0, 0.0), resolution: float = 0.1) -> FilterMask:
    return FilterMask(np.asarray(values, dtype=np.int8), resolution, origin)


def test_mask_values_become_nav2s_costs():
    costs = mask_costs(np.array([-1, 0, 1, 50, 99, 100, OUTSIDE]))
    assert costs.tolist() == [NO_INFORMATION, 0, 3, 127, 251, LETHAL_OBSTACLE, NO_INFORMATION]


def test_mask_lookup_follows_its_origin_and_rotation():
    values = np.zeros((10, 20), dtype=np.int8)
    values[2, 5] = 77  # row 2 (y 0.2-0.3), col 5 (x 0.5-0.6) of the mask
    m = mask(values, origin=(1.0, 2.0, 0.0))
    assert m.value_at(np.array(1.55), np.array(2.25)) == 77
    assert m.value_at(np.array(0.9), np.array(2.25)) == OUTSIDE
    turned = mask(values, origin=(1.0, 2.0, math.pi / 2))  # the mask's x along the world's y
    assert turned.value_at(np.array(1.0 - 0.25), np.array(2.0 + 0.55)) == 77


def keepout(values: np.ndarray, **kwargs) -> KeepoutFilter:
    f = KeepoutFilter("keepout_filter", True, "/info", **kwargs)
    f.set_info(FilterInfo(KEEPOUT, "/mask"))
    f.mask = mask(values)
    return f


def test_keepout_raises_cells_never_lowers_them_and_skips_unknown():
    values = np.zeros((10, 10), dtype=np.int8)
    values[:, 3:5] = 100  # a wall x 0.3-0.5 m
    values[0, 0] = -1
    values[9, 9] = 50
    master = Costmap(np.full((10, 10), 10, dtype=np.uint8), 0.1, (0.0, 0.0))
    master.costs[5, 7] = 200
    master.costs[9, 9] = 250
    master.costs[0, 0] = 30
    keepout(values).apply(master, (0.0, 0.0, 0.0), None)
    assert (master.costs[:, 3:5] == LETHAL_OBSTACLE).all()
    assert master.costs[5, 7] == 200 and master.costs[9, 9] == 250  # a higher cost stays
    assert master.costs[0, 0] == 30  # an unknown mask cell changes nothing
    assert master.costs[5, 0] == 10


def test_keepout_in_another_frame_is_transformed_and_unknown_cells_of_the_costmap_take_it():
    values = np.zeros((10, 10), dtype=np.int8)
    values[0:2, 0:2] = 100  # mask cells x, y in [0, 0.2) of the mask frame
    master = Costmap(np.full((10, 10), NO_INFORMATION, dtype=np.uint8), 0.1, (0.0, 0.0), "odom")
    # The costmap's frame (odom) sits at (-0.5, -0.5) in the mask's frame: its cells 5-6 are the zone.
    keepout(values).apply(master, (-0.5, -0.5, 0.0), None)
    assert (master.costs[5:7, 5:7] == LETHAL_OBSTACLE).all()
    assert (master.costs[7:, 7:] == 0).all()  # free mask cells over unknown ones: free (Nav2's rule)
    assert (master.costs[0:5, :] == NO_INFORMATION).all()  # off the mask: as it was


def test_override_lethal_cost_lets_a_robot_inside_a_zone_out():
    values = np.zeros((10, 10), dtype=np.int8)
    values[:, 3:7] = 100
    inside = Costmap(np.zeros((10, 10), dtype=np.uint8), 0.1, (0.0, 0.0))
    keepout(values, override_lethal_cost=True).apply(inside, (0.0, 0.0, 0.0), (0.45, 0.5))
    assert (inside.costs[:, 3:7] == MAX_NON_OBSTACLE).all()
    outside = Costmap(np.zeros((10, 10), dtype=np.uint8), 0.1, (0.0, 0.0))
    keepout(values, override_lethal_cost=True).apply(outside, (0.0, 0.0, 0.0), (0.05, 0.5))
    assert (outside.costs[:, 3:7] == LETHAL_OBSTACLE).all()


def test_a_filter_waits_for_its_info_and_mask_and_refuses_another_type():
    f = KeepoutFilter("k", True, "/info")
    master = Costmap(np.zeros((4, 4), dtype=np.uint8), 0.1, (0.0, 0.0))
    f.apply(master, (0.0, 0.0, 0.0), None)
    assert not f.ready and (master.costs == 0).all()
    with pytest.raises(ValueError, match="type 1 is not one KeepoutFilter takes"):
        f.set_info(FilterInfo(SPEED_PERCENT, "/mask"))


def speed(values: np.ndarray, kind: int = SPEED_PERCENT, base: float = 100.0, multiplier: float = -1.0
          ) -> SpeedFilter:
    f = SpeedFilter("speed_filter", True, "/info")
    f.set_info(FilterInfo(kind, "/mask", base, multiplier))
    f.mask = mask(values)
    return f


def test_the_speed_mask_under_the_robot_gives_its_limit_once_per_change():
    values = np.zeros((10, 10), dtype=np.int8)
    values[:, 5:] = 70
    values[0, 0] = -1
    f = speed(values)
    assert f.update(HERE, (0.25, 0.5)) is None  # 0: no limit, as it was
    assert f.update(HERE, (0.75, 0.5)) == SpeedLimit(30.0, True)  # 100 - 70 %
    assert f.update(HERE, (0.85, 0.5)) is None  # the same limit is not given again
    assert f.update(HERE, (0.05, 0.05)) == SpeedLimit(NO_SPEED_LIMIT, True) and "unknown cell" in str(f.problem)
    f.update(HERE, (0.75, 0.5))
    assert f.update(HERE, (5.0, 5.0)) == SpeedLimit(NO_SPEED_LIMIT, True) and "off the speed mask" in str(f.problem)


def test_absolute_limits_and_limits_out_of_range():
    values = np.full((10, 10), 40, dtype=np.int8)
    assert speed(values, SPEED_ABSOLUTE, 0.0, 0.01).update(HERE, (0.5, 0.5)) == SpeedLimit(0.4, False)
    values[:, 5:] = 80  # x ≥ 0.5 m in the mask: 0.8 m/s
    turned = speed(values, SPEED_ABSOLUTE, 0.0, 0.01)  # the costmap's frame at (1, 0) in the mask's, turned by π/2:
    assert turned.update((1.0, 0.0, math.pi / 2), (0.8, 0.3)) == SpeedLimit(0.8, False)  # (0.8, 0.3) is (0.7, 0.8)
    assert turned.update((1.0, 0.0, math.pi / 2), (0.3, 0.8)) == SpeedLimit(0.4, False)  # … and (0.3, 0.8) (0.2, 0.3)
    f = speed(values, SPEED_PERCENT, 100.0, 1.0)  # 140 %: out of (0, 100]
    assert f.update(HERE, (0.5, 0.5)) is None and "out of (0, 100] %" in str(f.problem)
    f = speed(values, SPEED_ABSOLUTE, -1.0, 0.01)  # -0.6 m/s
    assert f.update(HERE, (0.5, 0.5)) is None and "out of ≥ 0 m/s" in str(f.problem)


def test_a_limit_caps_the_speed_and_keeps_the_curvature():
    assert limited((0.5, 0.2), SpeedLimit(NO_SPEED_LIMIT, True), 0.5) == (0.5, 0.2)
    v, w = limited((0.5, 0.2), SpeedLimit(30.0, True), 0.5)
    assert v == pytest.approx(0.15) and w / v == pytest.approx(0.4)
    assert limited((0.1, 0.3), SpeedLimit(30.0, True), 0.5) == (0.1, 0.3)  # already slower
    v, w = limited((-0.4, 0.2), SpeedLimit(0.2, False), 0.5)
    assert v == pytest.approx(-0.2) and w == pytest.approx(0.1)


def test_filter_parameters_are_nav2s_and_the_info_topic_is_required():
    with pytest.raises(ParameterError, match="filter_info_topic.*must name the CostmapFilterInfo topic"):
        KeepoutFilterParameters().validate()
    with pytest.raises(ParameterError, match="lethal_override_cost"):
        KeepoutFilterParameters(filter_info_topic="/i", lethal_override_cost=254).validate()
    made = SpeedFilterParameters(filter_info_topic="/i").make(CONTEXT)
    assert made.speed_limit_topic == "speed_limit" and made.enabled
    keep = KeepoutFilterParameters(filter_info_topic="/i")
    assert not keep.override_lethal_cost and keep.lethal_override_cost == MAX_NON_OBSTACLE
