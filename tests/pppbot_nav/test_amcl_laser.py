"""Laser models: beam selection as Nav2's, and the true pose scoring above shifted ones."""
from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from amcl_synthetic import grid, scan

from pppbot_common.maps import OccupancyGrid
from pppbot_nav.amcl.laser import (
    BeamModel,
    LaserModelType,
    LaserSettings,
    LikelihoodFieldModel,
    MapField,
    Scan,
    laser_model,
)
from pppbot_nav.errors import AmclError

TRUE_POSE = np.array([0.5, -1.0, 0.3])
SHIFTS = [(0.2, 0.0, 0.0), (0.0, -0.2, 0.0), (0.0, 0.0, 0.1), (0.1, 0.1, -0.05), (-0.5, 0.3, 0.0)]


@pytest.fixture(scope="module")
def field() -> MapField:
    return MapField(grid())


def test_nav2_beam_selection_takes_every_step_th_beam_and_treats_short_and_bad_ranges_as_no_return():
    ranges = np.linspace(1.0, 5.0, 640)
    ranges[0], ranges[10], ranges[20] = 0.05, np.nan, np.inf
    s = Scan.from_laser(ranges, -math.pi, 2 * math.pi / 640, 0.12, 12.0, (0.1, 0.0, 0.0), LaserSettings(max_beams=60))
    # (640 − 1) // (60 − 1) = 10: beams 0, 10, …, 630.
    assert s.ranges.size == 64
    assert s.bearings[1] - s.bearings[0] == pytest.approx(10 * 2 * math.pi / 640)
    assert s.ranges[:3].tolist() == [12.0, 12.0, 12.0]
    assert s.ranges[3] == pytest.approx(ranges[30])


def test_beams_with_returns_spreads_max_beams_over_the_beams_that_returned():
    ranges = np.full(360, np.inf)
    hits = np.array([3, 4, 5, 90, 91, 200, 201, 202, 203, 300, 350])  # a few cones in an open field
    ranges[hits] = np.linspace(2.0, 6.0, hits.size)
    ranges[100], ranges[101] = 0.05, 15.0  # under range_min, beyond range_max: no return
    args = (ranges, -math.pi, 2 * math.pi / 360, 0.12, 12.0, (0.1, 0.0, 0.0))
    nav2 = Scan.from_laser(*args, LaserSettings(max_beams=60))
    assert (nav2.ranges < 12.0).sum() == 2  # beams 0, 6, 12, ...: two of the eleven hits
    picked = Scan.from_laser(*args, LaserSettings(max_beams=60, beams_with_returns=True))
    assert picked.ranges.tolist() == pytest.approx(ranges[hits].tolist())  # fewer hits than max_beams: all of them
    assert picked.bearings.tolist() == pytest.approx((-math.pi + hits * 2 * math.pi / 360).tolist())
    few = Scan.from_laser(*args, LaserSettings(max_beams=4, beams_with_returns=True))  # evenly over the hits
    assert few.ranges.tolist() == pytest.approx(ranges[hits[[0, 3, 7, 10]]].tolist())
    full = Scan.from_laser(*args, LaserSettings(max_beams=4, beams_with_returns=True), max_beams=360)
    assert full.ranges.size == 360  # the full scan (for the refinement) is every beam, as before
    nothing = Scan.from_laser(np.full(360, np.inf), *args[1:], LaserSettings(beams_with_returns=True))
    assert nothing.ranges.size == nav2.ranges.size and (nothing.ranges == 12.0).all()  # no return: Nav2's pick


def test_laser_range_limits_override_the_scans():
    ranges = np.array([0.3, 1.0, 6.0, 9.0])
    s = Scan.from_laser(ranges, 0.0, 0.1, 0.1, 12.0, (0, 0, 0),
                        LaserSettings(laser_min_range=0.5, laser_max_range=8.0, max_beams=4))
    assert s.range_max == 8.0
    assert s.ranges.tolist() == [8.0, 1.0, 6.0, 8.0]


@pytest.mark.parametrize("bad", [dict(ranges=[]), dict(angle_min=math.nan)])
def test_a_malformed_scan_is_refused_by_name(bad):
    args: dict[str, Any] = dict(ranges=[1.0, 2.0], angle_min=0.0)
    args.update(bad)
    with pytest.raises(AmclError, match="scan"):
        Scan.from_laser(np.array(args["ranges"]), args["angle_min"], 0.1, 0.1, 10.0, (0, 0, 0), LaserSettings())


@pytest.mark.parametrize("kind", list(LaserModelType))
def test_the_true_pose_is_more_likely_than_shifted_ones(field, kind):
    model = laser_model(kind, field, LaserSettings())
    poses = np.array([TRUE_POSE, *(TRUE_POSE + np.array(s) for s in SHIFTS)])
    p = model.likelihoods(poses, scan(TRUE_POSE))
    assert p.shape == (len(poses),)
    assert np.all(p[0] > p[1:])
    assert np.all(p >= 1.0)


def test_likelihood_field_end_points_off_the_map_score_as_far_from_any_wall(field):
    model = LikelihoodFieldModel(field, LaserSettings())
    far_away = np.array([[100.0, 100.0, 0.0]])
    s = scan(TRUE_POSE)
    p = model.likelihoods(far_away, s)[0]
    st = LaserSettings()
    pz = st.z_hit * math.exp(-st.laser_likelihood_max_dist ** 2 / (2 * st.sigma_hit ** 2)) + st.z_rand / s.range_max
    assert p == pytest.approx(1.0 + np.sum(s.ranges < s.range_max) * pz ** 3, rel=1e-5)


def test_beam_model_ray_cast_finds_walls_to_within_a_cell(field):
    model = BeamModel(field, LaserSettings())
    s = scan(TRUE_POSE, max_beams=360)
    cast = model.ray_cast(TRUE_POSE[None, :], s)[0]
    hit = s.ranges < s.range_max
    assert np.median(np.abs(cast[hit] - s.ranges[hit])) < 0.05
    assert np.mean(np.abs(cast[hit] - s.ranges[hit]) < 0.1) > 0.95


def test_a_map_without_free_space_or_with_a_rotated_origin_is_refused():
    with pytest.raises(AmclError, match="free"):
        MapField(OccupancyGrid(np.full((4, 4), 100), 0.05))
    with pytest.raises(AmclError, match="yaw"):
        MapField(OccupancyGrid(np.zeros((4, 4)), 0.05, (0.0, 0.0, 0.5)))
