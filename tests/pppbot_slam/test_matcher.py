"""The correlative scan matcher on synthetic scans of known geometry."""
from __future__ import annotations

import numpy as np
import pytest
from slam_synthetic import CORRIDOR, ROOM, cast, wall_points

from pppbot_common.se2 import se2_apply
from pppbot_slam.likelihood_field import normal_classes, rotate, scan_normals
from pppbot_slam.matcher import MatcherError, MatcherSettings, ScanMatcher

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


@pytest.mark.parametrize("offset", [(0.023, -0.031, 0.012), (-0.17, 0.061, -0.19)])
def test_the_refinement_goes_below_the_coarse_cells(offset):
    """The coarse grid is 5 cm and 2°; Gauss-Newton on the smooth response gets to millimetres."""
    truth = np.array([0.3, -0.4, 0.7])
    matcher = ScanMatcher(wall_points(SEGMENTS))
    scan = cast(SEGMENTS, truth)
    coarse = matcher.match(scan, truth + np.array(offset), coarse_only=True)
    result = matcher.match(scan, truth + np.array(offset))
    assert np.hypot(*(coarse.pose[:2] - truth[:2])) > 0.01 or abs(coarse.pose[2] - truth[2]) > 0.005
    assert np.hypot(*(result.pose[:2] - truth[:2])) < 0.004 and abs(result.pose[2] - truth[2]) < 0.001
    assert result.raw_response > coarse.raw_response


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


def test_scan_normals_face_the_sensor():
    # A wall at x = 2 seen from the origin, and one at y = −1: normals point back at the sensor.
    wall = np.stack([np.full(21, 2.0), np.linspace(-1, 1, 21)], axis=1)
    floor = np.stack([np.linspace(-1, 1, 21), np.full(21, -1.0)], axis=1)
    np.testing.assert_allclose(scan_normals(wall)[1:-1], [[-1.0, 0.0]] * 19, atol=1e-9)
    np.testing.assert_allclose(scan_normals(floor)[1:-1], [[0.0, 1.0]] * 19, atol=1e-9)
    assert list(normal_classes(np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]]))) == [0, 1, 2, 3]


def test_the_far_face_of_a_thin_wall_is_not_matched_with_normals():
    # The map holds only the far face of a 0.15 m wall (x = 2.15, seen from beyond it); the
    # scan sees the near face (x = 2) from the origin. Without normals the faces align with
    # a 0.15 m error; with them, nothing in the map faces the scan.
    far_face = np.stack([np.full(201, 2.15), np.linspace(-1, 1, 201)], axis=1)
    far_normals = np.tile([1.0, 0.0], (201, 1))
    scan = np.stack([np.full(101, 2.0), np.linspace(-1, 1, 101)], axis=1)
    plain = ScanMatcher(far_face).match(scan, [0.1, 0.0, 0.0])
    assert plain.response > 0.8 and abs(plain.pose[0] - 0.15) < 0.03
    facing = ScanMatcher(far_face, map_normals_xy=far_normals)
    assert facing.match(scan, [0.1, 0.0, 0.0], scan_normals(scan)).raw_response < 0.05
    # and a map of the near face, seen from this side, matches as before
    near = ScanMatcher(scan, map_normals_xy=scan_normals(scan)).match(scan, [0.1, 0.0, 0.0], scan_normals(scan))
    assert near.response > 0.9 and abs(near.pose[0]) < 0.01


def test_branch_and_bound_finds_the_exhaustive_best():
    truth = np.array([0.4, -0.3, 0.2])
    settings = MatcherSettings(search_size_m=4.0, coarse_resolution_m=0.1, smear_m=0.03, coarse_points=100)
    matcher = ScanMatcher(wall_points(SEGMENTS), settings)
    scan = cast(SEGMENTS, truth, noise=0.01)[::6]
    prior = truth + np.array([1.1, -0.7, 0.1])
    best, candidates, scores = matcher._coarse(scan, None, prior)
    assert len(candidates) < 41 * 41 * 21 / 4  # it did not score every shift
    shifts = np.arange(-20, 21)
    exhaustive = [matcher._score_shifts(prior, (dyaw, *matcher.coarse.cells(se2_apply(prior + [0, 0, dyaw], scan)),
                                                None), shifts, shifts)
                  for dyaw in np.arange(-10, 11) * settings.coarse_angle_step_rad]
    all_scores = np.concatenate([r for _, r in exhaustive])
    assert scores.max() == pytest.approx(all_scores.max())
    assert np.hypot(*(best[:2] - truth[:2])) < 0.15


def test_the_refinement_climbs_a_sharper_field_and_finds_the_wall_a_wide_smear_blurs_with_its_double():
    # The running map holds every wall twice: once where it is, once (half as dense) 4 cm off,
    # as a keyframe placed 4 cm wrong draws it. At the search's 10 cm smear the two merge into
    # one peak between them; the refinement's 5 cm field keeps them apart.
    truth = np.array([0.3, -0.4, 0.7])
    walls = wall_points(SEGMENTS)
    drawn_twice = np.vstack([walls, walls[::2] + np.array([0.0, 0.04])])
    scan = cast(SEGMENTS, truth, noise=0.005)
    prior = truth + np.array([0.03, 0.02, 0.01])
    blurred = ScanMatcher(drawn_twice, MatcherSettings(refine_smear_m=0.1, refine_exact=False)).match(scan, prior)
    matcher = ScanMatcher(drawn_twice, MatcherSettings(refine_exact=False))  # refine_smear_m 0.05 by default
    sharp = matcher.match(scan, prior)
    assert np.hypot(*(blurred.pose[:2] - truth[:2])) > 0.01
    assert np.hypot(*(sharp.pose[:2] - truth[:2])) < 0.003 and abs(sharp.pose[2] - truth[2]) < 0.002
    # The exact refinement (the default) has no field to blur: it climbs to the nearer wall.
    exact = ScanMatcher(drawn_twice).match(scan, prior)
    assert np.hypot(*(exact.pose[:2] - truth[:2])) < 0.002 and abs(exact.pose[2] - truth[2]) < 0.001
    # The response stays the search's (the thresholds on it keep their meaning); the sharper
    # field covers the scan, not the whole map.
    assert sharp.raw_response == pytest.approx(matcher.response(scan, sharp.pose))
    field = matcher.refine_field(scan, sharp.pose)
    assert field.smear_m == 0.05 and field is not matcher.fine
    near_part = scan[np.hypot(scan[:, 0], scan[:, 1]) < 2.0]
    assert matcher.refine_field(near_part, sharp.pose).values.size < field.values.size
    assert ScanMatcher(drawn_twice, MatcherSettings(refine_smear_m=0.2)).refine_field(scan, sharp.pose).smear_m == 0.1
    with pytest.raises(MatcherError, match="refine_smear_m must be a positive number"):
        MatcherSettings(refine_smear_m=-0.05)


def seen_map(segments: np.ndarray, poses: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """A running map's points and surface normals: the scans (5 mm noise) of lidars at ``poses``."""
    points, normals = [], []
    for seed, pose in enumerate(poses):
        scan = cast(segments, pose, noise=0.005, seed=10 + seed)
        points.append(se2_apply(pose, scan))
        normals.append(rotate(scan_normals(scan), pose[2]))
    return np.vstack(points), np.vstack(normals)


@pytest.mark.parametrize("seed", [0, 2, 4])
def test_the_polish_fits_the_walls_closer_than_the_likelihood_field(seed):
    room, room_normals = seen_map(ROOM, [np.zeros(3), np.array([1.0, 0.5, 1.0]), np.array([-1.0, -0.5, 2.0])])
    truth = np.array([0.3, -0.4, 0.7])
    scan = cast(ROOM, truth, noise=0.005, seed=seed)
    prior = truth + np.array([0.03, 0.02, 0.01])
    errors = []
    for exact, iterations in ((False, 0), (False, 10), (True, 0)):
        settings = MatcherSettings(polish_iterations=iterations, refine_exact=exact)
        result = ScanMatcher(room, settings, room_normals).match(scan, prior, scan_normals(scan))
        errors.append((np.hypot(*(result.pose[:2] - truth[:2])), abs(result.pose[2] - truth[2])))
    (field_m, _), (polished_m, polished_rad), (exact_m, exact_rad) = errors
    assert field_m > 0.0015 and polished_m < field_m / 2 and polished_rad < 0.0005
    # The exact refinement alone (nearest map points, no cells) comes near the polish.
    assert exact_m < field_m / 2 and exact_rad < 0.001


def test_the_polish_moves_no_further_than_a_fine_step_from_the_search():
    room, room_normals = seen_map(ROOM, [np.zeros(3), np.array([1.0, 0.5, 1.0])])
    truth = np.array([0.3, -0.4, 0.7])
    scan = cast(ROOM, truth, noise=0.005)
    matcher = ScanMatcher(room, MatcherSettings(fine_resolution_m=0.01), room_normals)
    # Given a pose 3 cm off, it goes 1 cm (fine_resolution_m) toward the walls and stops.
    polished = matcher.polish(scan, scan_normals(scan), truth + np.array([0.03, 0.0, 0.0]))
    assert polished[0] - truth[0] == pytest.approx(0.02, abs=1e-9)
    assert abs(polished[1] - truth[1]) < 0.002 and abs(polished[2] - truth[2]) < 0.002


def test_the_polish_does_not_slide_along_a_featureless_corridor():
    corridor, corridor_normals = seen_map(CORRIDOR, [np.array([-2.0, 0.0, 0.0]), np.array([2.0, 0.1, 0.0])])
    truth = np.array([0.0, 0.1, 0.0])
    scan = cast(CORRIDOR, truth, noise=0.005, max_range=8.0)
    start = truth + np.array([0.006, 0.006, 0.0])
    polished = ScanMatcher(corridor, MatcherSettings(), corridor_normals).polish(scan, scan_normals(scan), start)
    assert polished[0] == pytest.approx(start[0], abs=1e-4)  # along: nothing pins it, it stays
    assert abs(polished[1] - truth[1]) < 0.002  # across: the walls decide
