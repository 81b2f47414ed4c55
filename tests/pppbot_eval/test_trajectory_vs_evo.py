"""pppbot_eval's ATE and RPE against evo, the standard SLAM-evaluation library, on a stored run.

The trajectories are maze_101's held-out SLAM run (the autonomy suite, wheel slip 0.01), the
SLAM estimate (map → odom ∘ odom → base_link, the map frame at the world origin) and the
ground truth, sampled at 1 Hz at the same stamps and stored in TUM format in ``data/``. evo
reads the files itself. pppbot computes its own figures (they go into every report, with no
extra dependency in the nodes), and this test holds them to evo's on the same samples.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from evo.core import filters, metrics
from evo.core.units import Unit
from evo.tools import file_interface

from pppbot_common.se2 import yaw_from_quaternion
from pppbot_eval.trajectory import PoseSeries, absolute_trajectory_error, relative_pose_error

DATA = Path(__file__).resolve().parent / "data"
TRUTH, ESTIMATE = DATA / "maze_101_truth.tum", DATA / "maze_101_slam.tum"


def series(path: Path) -> PoseSeries:
    rows = np.loadtxt(path)
    yaw = [yaw_from_quaternion(*q) for q in rows[:, 4:8]]
    return PoseSeries.from_poses(rows[:, 0], np.c_[rows[:, 1:3], yaw])


@pytest.fixture(scope="module")
def evo_pair():
    return file_interface.read_tum_trajectory_file(str(TRUTH)), file_interface.read_tum_trajectory_file(str(ESTIMATE))


def test_the_stored_run_is_long_enough_to_mean_something(evo_pair):
    truth, _ = evo_pair
    assert truth.num_poses > 400 and truth.path_length > 100.0  # m


def test_ate_position_and_heading_equal_evos_ape_without_alignment(evo_pair):
    ours = absolute_trajectory_error(series(ESTIMATE), series(TRUTH))
    position = metrics.APE(metrics.PoseRelation.translation_part)
    position.process_data(evo_pair)
    heading = metrics.APE(metrics.PoseRelation.rotation_angle_rad)
    heading.process_data(evo_pair)
    assert ours.samples == position.error.size
    assert ours.rms_m == pytest.approx(position.get_statistic(metrics.StatisticsType.rmse), abs=1e-9)
    assert ours.max_m == pytest.approx(position.get_statistic(metrics.StatisticsType.max), abs=1e-9)
    # In the plane the rotation angle of the error is |yaw error|.
    assert ours.yaw_rms_rad == pytest.approx(heading.get_statistic(metrics.StatisticsType.rmse), abs=1e-7)
    assert ours.yaw_max_rad == pytest.approx(heading.get_statistic(metrics.StatisticsType.max), abs=1e-7)
    assert 0.005 < ours.rms_m < 0.05  # a real run's error, not zero


@pytest.mark.parametrize("segment_m", [1.0, 5.0])
def test_rpe_over_path_segments_equals_evos_rpe_on_the_same_pairs(evo_pair, segment_m: float):
    ours = relative_pose_error(series(ESTIMATE), series(TRUTH), segment_m=segment_m)
    rpe = metrics.RPE(metrics.PoseRelation.translation_part, delta=segment_m, delta_unit=Unit.meters,
                      all_pairs=False)
    rpe.process_data(evo_pair)
    # evo takes consecutive segments (each starts where the last ended), pppbot every start
    # sample; both end a segment at the first sample segment_m of truth path later, and pppbot
    # divides by the truth path driven.
    pairs = filters.filter_pairs_by_path(evo_pair[0].poses_se3, segment_m)  # evo's own choice, as RPE makes it
    assert [j for _, j in pairs] == rpe.delta_ids
    truth = series(TRUTH)
    length = truth.cumulative_length_m()
    starts, ends = [i for i, _ in pairs], [j for _, j in pairs]
    index = {t: k for k, t in enumerate(ours.t_s)}
    per_metre = np.array([ours.trans_error_m_per_m[index[truth.t_s[i]]] for i in starts])
    driven = length[ends] - length[starts]
    assert len(starts) > 10
    np.testing.assert_allclose(per_metre * driven, rpe.error, rtol=1e-6, atol=1e-8)  # the files hold 9 decimals
