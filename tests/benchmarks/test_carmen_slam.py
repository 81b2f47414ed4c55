"""The CARMEN-log benchmark's pieces on constructed cases: reading, odometry synthesis, the metrics."""
from __future__ import annotations

import gzip
import math
from pathlib import Path

import numpy as np
import pytest


@pytest.fixture(scope="module")
def carmen(load_benchmark):
    return load_benchmark("carmen_slam")


def _write_log(path: Path, scans: list[tuple[list[float], tuple[float, float, float], float]]) -> None:
    lines = ["# a comment", "PARAM robot_frontlaser_offset 0.0 nohost 0", "ODOM 0 0 0 0 0 0 0.1 host 0.1"]
    for ranges, (x, y, yaw), stamp in scans:
        values = " ".join(f"{r:g}" for r in ranges)
        lines.append(f"FLASER {len(ranges)} {values} {x} {y} {yaw} {x} {y} {yaw} {stamp} host {stamp}")
    with gzip.open(path, "wt") as f:
        f.write("\n".join(lines) + "\n")


def test_a_log_is_read_with_no_return_as_inf_and_its_beams_over_180_degrees(carmen, tmp_path):
    path = tmp_path / "tiny.log.gz"
    _write_log(path, [([1.0, 81.9, 2.5], (0.0, 0.0, 0.0), 1.5), ([1.1, 2.0, 3.0], (0.5, 0.1, 0.2), 2.5)])
    log = carmen.read_carmen(path)
    assert log.name == "tiny" and log.ranges_m.shape == (2, 3)
    assert math.isinf(log.ranges_m[0, 1]) and log.ranges_m[1, 2] == 3.0
    assert np.allclose(log.poses[1], (0.5, 0.1, 0.2)) and np.allclose(log.stamps_s, (1.5, 2.5))
    # three beams (odd): −90°, 0°, +90°
    assert log.angle_min_rad == pytest.approx(-math.pi / 2) and log.angle_increment_rad == pytest.approx(math.pi / 2)


def test_bad_logs_are_named(carmen, tmp_path):
    with pytest.raises(carmen.CarmenError, match="nowhere.log.gz: no such log; the public originals: Radish"):
        carmen.read_carmen(tmp_path / "nowhere.log.gz")
    path = tmp_path / "bad.log.gz"
    with gzip.open(path, "wt") as f:
        f.write("FLASER 3 1.0 2.0 x 0 0 0 0 0 0 1.0 host 1.0\n")
    with pytest.raises(carmen.CarmenError, match=r"bad.log.gz:1: malformed FLASER record"):
        carmen.read_carmen(path)


def _square_loop() -> np.ndarray:
    poses = []
    for side in range(4):
        for k in range(10):
            yaw = side * math.pi / 2
            corner = [(0, 0), (5, 0), (5, 5), (0, 5)][side]
            poses.append((corner[0] + 0.5 * k * math.cos(yaw), corner[1] + 0.5 * k * math.sin(yaw), yaw))
    return np.array(poses)


def test_noise_free_odometry_is_the_reference_and_noise_grows_with_the_alphas(carmen):
    truth = _square_loop()
    exact = carmen.synthesize_odometry(truth, (0.0, 0.0, 0.0, 0.0), np.random.default_rng(0))
    assert np.allclose(exact[:, :2], truth[:, :2], atol=1e-9)
    assert np.allclose(np.cos(exact[:, 2] - truth[:, 2]), 1.0)
    drift = [np.linalg.norm(carmen.synthesize_odometry(truth, (a, a, a, a), np.random.default_rng(1))[-1, :2]
                            - truth[-1, :2]) for a in (0.01, 0.2)]
    assert drift[0] < drift[1]


def test_relation_error_is_zero_for_the_reference_and_measures_a_local_slip(carmen):
    truth = _square_loop()
    pairs = np.stack([np.arange(len(truth) - 1), np.arange(1, len(truth))], axis=1)
    trans, rot = carmen.relation_errors(truth, truth, pairs)
    assert np.allclose(trans, 0.0) and np.allclose(rot, 0.0)
    # the whole trajectory moved rigidly: relations do not change
    moved = truth.copy()
    moved[:, :2] = truth[:, :2] @ np.array([[0.0, -1.0], [1.0, 0.0]]).T + (3.0, -2.0)
    moved[:, 2] += math.pi / 2
    trans, rot = carmen.relation_errors(moved, truth, pairs)
    assert np.allclose(trans, 0.0, atol=1e-9) and np.allclose(rot, 0.0, atol=1e-9)
    # every pose after the 20th 0.1 m further along x: one relation of 0.1 m error
    slipped = truth.copy()
    slipped[20:, 0] += 0.1
    trans, _ = carmen.relation_errors(slipped, truth, pairs)
    assert np.count_nonzero(trans > 1e-9) == 1 and trans.max() == pytest.approx(0.1)


def test_aligned_ate_ignores_a_rigid_motion_but_not_a_distortion(carmen):
    truth = _square_loop()
    c, s = math.cos(0.7), math.sin(0.7)
    moved = truth.copy()
    moved[:, :2] = truth[:, :2] @ np.array([[c, -s], [s, c]]).T + (10.0, 4.0)
    assert carmen.aligned_ate(moved, truth).max() < 1e-9
    stretched = truth.copy()
    stretched[:, 0] *= 1.1
    assert carmen.aligned_ate(stretched, truth).max() > 0.1


def test_overlap_pairs_are_places_seen_twice(carmen):
    truth = _square_loop()
    pairs = carmen.overlap_pairs(truth)
    assert len(pairs) and np.all(pairs[:, 1] > pairs[:, 0] + 1)
    d = np.hypot(*(truth[pairs[:, 0], :2] - truth[pairs[:, 1], :2]).T)
    assert d.max() < carmen.OVERLAP_DISTANCE_M


def test_the_worst_seed_judges_each_log_and_a_log_without_time_is_judged_without_speed(carmen):
    def run(log, seed, ate_max, false, factor):
        return {"log": log, "seed": seed, "ate_rms_m": ate_max / 3, "ate_max_m": ate_max, "relation_mean_m": 0.03,
                "false_closures": false, "real_time_factor": factor}
    results = [run("fhw", 0, 0.3, 0, 40.0), run("fhw", 1, 0.35, 0, 18.0), run("campus", 0, 0.2, 0, None),
               run("campus", 1, 0.3, 1, None), run("edmonton", 0, 0.6, 0, 30.0)]
    worst = carmen.worst_per_log(results)
    assert worst["fhw"] == {"ate_rms_m": pytest.approx(0.35 / 3), "ate_max_m": 0.35, "relation_mean_m": 0.03,
                            "false_closures": 0, "real_time_factor": 18.0}
    assert worst["campus"]["real_time_factor"] is None and worst["campus"]["false_closures"] == 1
    # one false closure of any seed fails the log; so does an ATE max over 0.4 m
    assert carmen.targets_met(results) == {"fhw": True, "campus": False, "edmonton": False}
    assert carmen.targets_met(results[:3]) == {"fhw": True, "campus": True}


def test_the_parameter_file_describes_the_laser_and_bad_names_are_refused(carmen, tmp_path):
    params = carmen.slam_parameters(carmen.DEFAULT_PARAMS)
    assert params.max_laser_range == 30.0 and params.minimum_travel_distance == 0.0
    # loop chains as long in metres as the defaults' (10 keyframes 0.5 m apart) at the logs' ~1 m
    assert params.mapper_settings().loop_match_minimum_chain_size == 5
    bad = tmp_path / "bad.yaml"
    bad.write_text("slam_toolbox:\n  ros__parameters:\n    max_laser_rnage: 30.0\n")
    with pytest.raises(carmen.ParameterError, match="max_laser_rnage"):
        carmen.slam_parameters(bad)


def test_the_first_150_scans_of_the_intel_lab_map_far_better_than_odometry(carmen):
    path = carmen.DEFAULT_DATASETS / "intel.log.gz"
    if not path.is_file():
        pytest.skip(f"{path} is not here; {carmen.ORIGINALS}")
    log = carmen.read_carmen(path)
    head = carmen.CarmenLog(log.name, log.stamps_s[:150], log.ranges_m[:150], log.poses[:150],
                            log.angle_min_rad, log.angle_increment_rad)
    result = carmen.evaluate(head, carmen.slam_parameters(carmen.DEFAULT_PARAMS), (0.05, 0.05, 0.05, 0.05), seed=0)
    assert result["relation_mean_m"] < carmen.TARGET_INTEL_RELATION_MEAN_M
    assert result["ate_rms_m"] < 0.2 * result["odometry_ate_rms_m"]
    # Its closures judged against the corrected poses: as many as the mapper kept, none false.
    assert result["false_closures"] == 0 and (result["closure_max_error_m"] is None) == (result["loop_closures"] == 0)
