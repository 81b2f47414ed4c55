"""The offline SLAM replay on a constructed drive: the online error it reports is the SLAM pose's, not odometry's."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "pppbot_slam"))
from slam_synthetic import RING, beam_angles, cast_ranges, drifting_odometry, ring_path  # noqa: E402


@pytest.fixture(scope="module")
def replay(load_benchmark):
    return load_benchmark("slam_replay")


def ring_drive(replay, truth: np.ndarray, odom: np.ndarray):
    angles = beam_angles()
    ranges = np.array([cast_ranges(RING, pose, noise=0.01, seed=k) for k, pose in enumerate(truth)], dtype=np.float32)
    stamps = 0.1 * np.arange(len(truth))
    return replay.SlamDataset(
        world="ring", route="loop", seed=0, wheel_slip=0.0, stamps=stamps, odom=odom, truth=truth, ranges=ranges,
        angle_min=float(angles[0]), angle_increment=float(angles[1] - angles[0]), range_min=0.08, range_max=20.0,
        sensor_offset=np.zeros(3), lidar_frame="lidar", odom_stream_stamps=stamps, odom_stream=odom,
        route_points=truth[:, :2], speed_mps=1.0, collisions=0, route_completed=True)


def test_the_slam_pose_is_scored_against_the_truth_while_odometry_drifts(replay):
    truth = ring_path(step_m=0.1)
    odom = drifting_odometry(truth, yaw_per_m=0.01, scale=1.02)
    result = replay.replay(ring_drive(replay, truth, odom), {})
    odometry_error = np.linalg.norm(odom[-1, :2] - truth[-1, :2])
    assert odometry_error > 0.5
    assert result["online_rms_cm"] < 5.0 and result["online_max_cm"] < 15.0
    assert result["keyframes"] > 40 and len(result["online_timeline_cm"]) == replay.TIMELINE_POINTS
    # The starting pose is where SLAM starts too: the first moment's error is nothing.
    assert result["online_timeline_cm"][0] == 0.0


def test_matcher_overrides_name_what_is_wrong(replay):
    assert replay.matcher_overrides(["refine_smear_m=0.1", "coarse_points=50"]) == {"refine_smear_m": 0.1,
                                                                                   "coarse_points": 50}
    polish = replay.matcher_overrides(["polish_iterations=0"])["polish_iterations"]
    assert polish == 0 and isinstance(polish, int)  # a count, as range() takes it
    with pytest.raises(ValueError, match="NAME one of"):
        replay.matcher_overrides(["smear=0.1"])
    with pytest.raises(ValueError, match="'x' is not a number"):
        replay.matcher_overrides(["smear_m=x"])


def test_mapper_overrides_take_its_numbers_and_refuse_the_rest(replay):
    assert replay.mapper_overrides(["loop_search_global_distance=0", "scan_buffer_size=5"]) == {
        "loop_search_global_distance": 0.0, "scan_buffer_size": 5}
    with pytest.raises(ValueError, match="--mapper 'matcher=1'.*NAME one of"):
        replay.mapper_overrides(["matcher=1"])  # a MatcherSettings, not a number
