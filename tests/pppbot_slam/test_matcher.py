"""The correlative scan matcher on synthetic scans of known geometry."""
from __future__ import annotations

import numpy as np
import pytest

from pppbot_common.se2 import se2_apply
from pppbot_slam.matcher import MatcherError, MatcherSettings, ScanMatcher
from slam_synthetic import CORRIDOR, ROOM, cast, wall_points

SEGMENTS = ROOM


@pytest.mark.parametrize("offset", [(0.15, -0.1, 0.1), (-0.2, 0.2, -0.25), (0.0, 0.0, 0.0), (0.08, 0.03, 0.3)])
def test_recovers_a_known_offset_from_the_prior(offset):
    truth = np.array([0.3, -0.4, 0.7])
    matcher = ScanMatcher(wall_points(SEGMENTS))
    scan = cast(SEGMENTS, truth, noise=0.01)
    result = matcher.match(scan, truth + np.array(offset))
    assert np.hypot(*(result.pose[:2] - truth[:2])) < 0.01
    assert abs(result.pose[2] - truth[2]) < 0.005
    assert result.response > 0.8 and result.raw_response >= result.response
    assert np.all(np.linalg.eigvalsh(result.covariance) > 0)


def test_response_is_best_at_the_true_pose():
    truth = np.array([-0.5, 0.6, -1.2])
    matcher = ScanMatcher(wall_points(SEGMENTS))
    scan = cast(SEGMENTS, truth)
    best = matcher.response(scan, truth)
    for shift in ([0.1, 0, 0], [0, -0.1, 0], [0, 0, 0.05]):
        assert matcher.response(scan, truth + np.array(shift)) < best


def test_in_a_featureless_corridor_the_match_stays_near_the_prior_along_it():
    truth = np.array([0.0, 0.1, 0.0])
    matcher = ScanMatcher(wall_points(CORRIDOR))
    scan = cast(CORRIDOR, truth, max_range=8.0)
    result = matcher.match(scan, truth + np.array([0.2, 0.1, 0.05]))
    # Across the corridor and in heading the walls decide; along it, the penalty keeps the prior.
    assert abs(result.pose[1] - truth[1]) < 0.01 and abs(result.pose[2] - truth[2]) < 0.005
    assert abs(result.pose[0] - 0.2) < 0.05
    assert result.covariance[0, 0] > 10 * result.covariance[1, 1]  # uncertain along the corridor


def test_any_beam_count_and_a_far_prior_outside_the_window_fails_gracefully():
    truth = np.array([0.0, 0.0, 0.0])
    matcher = ScanMatcher(wall_points(SEGMENTS))
    for beams in (90, 1081):
        result = matcher.match(cast(SEGMENTS, truth, beams=beams), truth + np.array([0.1, 0.1, 0.1]))
        assert np.hypot(*result.pose[:2]) < 0.015
    far = matcher.match(cast(SEGMENTS, truth), np.array([1.5, 1.0, 0.0]))  # 1.8 m off, window ±0.25 m
    assert far.response < 0.5


def test_scan_points_map_into_the_world_at_the_result():
    truth = np.array([1.0, -1.0, 2.0])
    scan = cast(SEGMENTS, truth)
    result = ScanMatcher(wall_points(SEGMENTS)).match(scan, truth + np.array([0.1, 0.0, 0.0]))
    np.testing.assert_allclose(se2_apply(result.pose, scan), se2_apply(truth, scan), atol=0.03)


def test_bad_settings_and_inputs_name_the_value():
    with pytest.raises(MatcherError, match="smear_m must be a positive number, not 0"):
        MatcherSettings(smear_m=0)
    with pytest.raises(MatcherError, match="fine_resolution_m 0.1 must not exceed"):
        MatcherSettings(fine_resolution_m=0.1)
    with pytest.raises(MatcherError, match="no map points"):
        ScanMatcher(np.empty((0, 2)))
    with pytest.raises(MatcherError, match="at least 3 finite points"):
        ScanMatcher(wall_points(SEGMENTS)).match(np.array([[np.nan, 1.0], [1.0, 1.0]]), (0, 0, 0))
