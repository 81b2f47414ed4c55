"""The footprint a costmap publishes: Nav2's 16-point circle, padded, at the robot's pose."""
from __future__ import annotations

import math

import numpy as np
import pytest

from pppbot_nav.costmap.footprint import CIRCLE_POINTS, circle_footprint, placed


def test_a_circular_robot_is_nav2s_padded_sixteen_point_polygon() -> None:
    footprint = circle_footprint(0.3, 0.01)
    assert footprint.shape == (CIRCLE_POINTS, 2) == (16, 2)
    np.testing.assert_allclose(np.hypot(*footprint.T), 0.31)
    np.testing.assert_allclose(footprint[0], [0.31, 0.0])


def test_placed_at_the_robots_pose() -> None:
    at = placed(np.array([[1.0, 0.0], [0.0, 0.5]]), (2.0, -1.0, math.pi / 2))
    np.testing.assert_allclose(at, [[2.0, 0.0], [1.5, -1.0]], atol=1e-12)


@pytest.mark.parametrize("radius, padding, points", [(math.nan, 0.0, 16), (0.1, -0.2, 16), (0.1, 0.0, 2)])
def test_a_bad_footprint_is_refused_with_its_values(radius: float, padding: float, points: int) -> None:
    with pytest.raises(ValueError, match="a footprint needs"):
        circle_footprint(radius, padding, points)
