"""Trajectory errors: SE(2) helpers, pose series, ATE and RPE against constructed ground truth."""
from __future__ import annotations

import json
import math
import sys

import numpy as np
import pytest

from pppbot_common.se2 import se2_apply, se2_compose, se2_inverse, wrap_angles
from pppbot_eval.trajectory import (
    NoOverlapError,
    PoseRows,
    PoseSeries,
    PoseSeriesError,
    absolute_trajectory_error,
    relative_pose_error,
)


def straight_line(speed_mps: float = 0.5, duration_s: float = 10.0, dt_s: float = 0.05) -> PoseSeries:
    """Along +x from the origin, heading 0."""
    t = np.arange(0.0, duration_s + dt_s / 2, dt_s)
    return PoseSeries(t, np.column_stack([speed_mps * t, np.zeros_like(t)]), np.zeros_like(t))


def curve(dt_s: float = 0.05) -> PoseSeries:
    """An S-shaped drive: position and heading from a smooth, seeded random yaw rate."""
    rng = np.random.default_rng(7)
    t = np.arange(0.0, 20.0, dt_s)
    yaw_rate = np.convolve(rng.normal(0.0, 0.6, t.size), np.ones(40) / 40, mode="same")
    yaw = np.cumsum(yaw_rate) * dt_s
    xy = np.cumsum(0.4 * np.column_stack([np.cos(yaw), np.sin(yaw)]) * dt_s, axis=0)
    return PoseSeries(t, xy, wrap_angles(yaw))


# --- SE(2) ----------------------------------------------------------------------------------------


def test_compose_and_inverse_round_trip():
    rng = np.random.default_rng(1)
    poses = np.column_stack([rng.normal(size=(50, 2)), rng.uniform(-math.pi, math.pi, 50)])
    others = np.column_stack([rng.normal(size=(50, 2)), rng.uniform(-math.pi, math.pi, 50)])
    assert np.allclose(se2_compose(poses, se2_inverse(poses)), 0.0, atol=1e-12)
    back = se2_compose(se2_inverse(poses), se2_compose(poses, others))
    assert np.allclose(back[:, :2], others[:, :2]) and np.allclose(wrap_angles(back[:, 2] - others[:, 2]), 0.0)


def test_compose_matches_a_hand_example():
    # a robot at (1, 2) facing +y; a point 1 m ahead of it and facing its left is at (1, 3) facing −x
    assert np.allclose(se2_compose((1.0, 2.0, math.pi / 2), (1.0, 0.0, math.pi / 2)), (1.0, 3.0, math.pi))
    assert np.allclose(se2_apply((1.0, 2.0, math.pi / 2), np.array([[1.0, 0.0], [0.0, 1.0]])), [[1, 3], [0, 2]])


def test_wrap_angles_is_half_open_at_minus_pi():
    assert np.allclose(wrap_angles(np.array([math.pi, -math.pi, 3 * math.pi, 0.5 - 2 * math.pi])),
                       [math.pi, math.pi, math.pi, 0.5])


# --- pose series ----------------------------------------------------------------------------------


def test_from_rows_drops_duplicate_times_keeping_the_last():
    series = PoseSeries.from_rows([(0.0, 0.0, 0.0, 0.0), (1.0, 1.0, 0.0, 0.0), (1.0, 2.0, 0.0, 0.0)])
    assert series.t_s.tolist() == [0.0, 1.0]
    assert series.xy[:, 0].tolist() == [0.0, 2.0]
    assert not series.xy.flags.writeable


def test_pose_rows_keep_what_a_list_of_tuples_would_in_a_fifth_of_the_memory():
    rows = [(0.5 * i, 0.1 * i, -0.2 * i, 0.01 * i) for i in range(1000)]
    packed = PoseRows(rows[:1])
    for row in rows[1:]:
        packed.append(row)
    assert len(packed) == 1000 and list(packed) == rows
    assert np.array_equal(np.array(packed), np.array(rows)) and np.array(packed).shape == (1000, 4)
    series, expected = PoseSeries.from_rows(packed), PoseSeries.from_rows(rows)
    assert np.array_equal(series.t_s, expected.t_s) and np.array_equal(series.xy, expected.xy)
    assert np.array(PoseRows()).shape == (0, 4) and PoseSeries.from_rows(PoseRows()).t_s.size == 0
    tuples = sys.getsizeof(rows) + sum(sys.getsizeof(row) + sum(map(sys.getsizeof, row)) for row in rows)
    assert sys.getsizeof(packed._values) * 5 < tuples
    with pytest.raises(PoseSeriesError, match=r"a pose row is \(t_s, x, y, yaw\); got 3 values"):
        packed.append((1.0, 2.0, 3.0))
    with pytest.raises(PoseSeriesError, match="a pose row is four numbers; got"):
        packed.append((1.0, 2.0, None, 3.0))  # type: ignore[arg-type]
    assert len(packed) == 1000 and list(packed)[-1] == rows[-1]  # the bad rows left nothing behind


def test_decreasing_times_are_refused():
    with pytest.raises(PoseSeriesError, match=r"t_s\[2\] = 0.5 s"):
        PoseSeries.from_rows([(0.0, 0, 0, 0), (1.0, 0, 0, 0), (0.5, 0, 0, 0)])


@pytest.mark.parametrize("rows", [[(0.0, 1.0, 2.0)], [(0.0, 1.0, math.nan, 0.0)]])
def test_malformed_rows_are_refused(rows):
    with pytest.raises(PoseSeriesError):
        PoseSeries.from_rows(rows)


def test_interpolation_crosses_the_yaw_wrap_the_short_way():
    series = PoseSeries.from_rows([(0.0, 0.0, 0.0, 3.1), (1.0, 1.0, 0.0, -3.1)])
    half = series.interpolate([0.25])
    short_step = 2 * math.pi - 6.2
    assert half.yaw_rad[0] == pytest.approx(3.1 + 0.25 * short_step)
    assert half.xy[0].tolist() == pytest.approx([0.25, 0.0])


def test_interpolation_outside_the_span_is_refused():
    with pytest.raises(PoseSeriesError, match=r"time 1.5 s is outside"):
        straight_line(duration_s=1.0).interpolate([0.5, 1.5])


def test_path_length_and_within():
    line = straight_line(speed_mps=0.5, duration_s=10.0)
    assert line.path_length_m() == pytest.approx(5.0)
    assert line.within(2.0, 4.0).path_length_m() == pytest.approx(1.0)


def test_transformed_left_composes():
    series = PoseSeries.from_rows([(0.0, 1.0, 0.0, 0.0)])
    moved = series.transformed((2.0, 3.0, math.pi / 2))
    assert moved.xy[0].tolist() == pytest.approx([2.0, 4.0])
    assert moved.yaw_rad[0] == pytest.approx(math.pi / 2)


# --- ATE -------------------------------------------------------------------------------------------


def test_identical_trajectories_have_no_error():
    truth = curve()
    ate = absolute_trajectory_error(truth, truth)
    rpe = relative_pose_error(truth, truth)
    assert (ate.rms_m, ate.max_m, ate.yaw_max_rad, ate.samples) == (0.0, 0.0, 0.0, len(truth))
    assert rpe.segments > 0
    assert rpe.trans_max_m_per_m == pytest.approx(0.0, abs=1e-12)
    assert rpe.rot_max_rad_per_m == pytest.approx(0.0, abs=1e-12)


def test_constant_offset():
    truth = straight_line()
    estimate = PoseSeries(truth.t_s, truth.xy + [0.1, 0.0], truth.yaw_rad)
    ate = absolute_trajectory_error(estimate, truth)
    assert ate.rms_m == pytest.approx(0.1) and ate.max_m == pytest.approx(0.1)
    assert ate.yaw_rms_rad == 0.0


def test_yaw_offset_about_the_start_grows_with_distance():
    truth = straight_line(speed_mps=0.5)
    estimate = truth.transformed((0.0, 0.0, 0.05))
    ate = absolute_trajectory_error(estimate, truth)
    at_4m = int(np.flatnonzero(np.isclose(ate.t_s, 8.0))[0])  # x = 4 m
    assert ate.position_error_m[at_4m] == pytest.approx(2 * 4.0 * math.sin(0.025))
    assert np.allclose(ate.yaw_error_rad, 0.05)
    assert ate.max_m == pytest.approx(2 * 5.0 * math.sin(0.025))


def test_estimate_at_other_times_is_compared_with_interpolated_truth():
    truth = straight_line(dt_s=0.05)
    times = np.arange(0.01, 9.9, 0.13)
    estimate = PoseSeries(times, np.column_stack([0.5 * times, np.zeros_like(times)]), np.zeros_like(times))
    ate = absolute_trajectory_error(estimate, truth)
    assert ate.samples == times.size
    assert ate.max_m == pytest.approx(0.0, abs=1e-12)


def test_truth_gaps_wider_than_max_gap_drop_samples():
    truth = PoseSeries.from_rows([(0.0, 0, 0, 0), (0.05, 0, 0, 0), (1.0, 0, 0, 0), (1.05, 0, 0, 0)])
    estimate = PoseSeries.from_rows([(0.02, 0, 0, 0), (0.5, 0, 0, 0), (1.0, 0, 0, 0)])
    assert absolute_trajectory_error(estimate, truth, max_gap_s=0.1).t_s.tolist() == [0.02, 1.0]


def test_no_overlap_names_both_spans():
    truth = straight_line(duration_s=1.0)
    estimate = PoseSeries.from_rows([(5.0, 0, 0, 0), (6.0, 0, 0, 0)])
    with pytest.raises(NoOverlapError, match=r"estimate spans \[5.000, 6.000\] s, the truth \[0.000, 1.000\] s"):
        absolute_trajectory_error(estimate, truth)
    assert issubclass(NoOverlapError, ValueError)


def test_estimate_in_the_spawn_frame_is_moved_into_the_world():
    spawn = (1.0, 2.0, math.pi / 2)
    truth = curve().transformed(spawn)  # the drive, started at the spawn pose, in the world
    estimate = truth.transformed(se2_inverse(spawn))  # the same drive in the map (spawn) frame
    ate = absolute_trajectory_error(estimate, truth, estimate_to_world=spawn)
    assert ate.max_m == pytest.approx(0.0, abs=1e-9) and ate.yaw_max_rad == pytest.approx(0.0, abs=1e-9)
    assert absolute_trajectory_error(estimate, truth).max_m > 1.0


def test_ate_as_dict_is_json_safe():
    truth = straight_line()
    summary = absolute_trajectory_error(truth, truth).as_dict()
    assert set(summary) == {"ate_rms_m", "ate_max_m", "ate_yaw_rms_rad", "ate_yaw_max_rad", "ate_samples"}
    json.dumps(summary, allow_nan=False)


# --- RPE -------------------------------------------------------------------------------------------


def test_linear_drift_is_one_percent_per_metre():
    truth = straight_line(speed_mps=0.5, duration_s=10.0)
    estimate = PoseSeries(truth.t_s, truth.xy * [1.01, 1.0], truth.yaw_rad)
    rpe = relative_pose_error(estimate, truth, segment_m=1.0)
    assert rpe.segments == len(truth) - 40  # samples at least 1 m (40 steps of 2.5 cm) before the end
    assert rpe.trans_mean_m_per_m == pytest.approx(0.01)
    assert rpe.trans_max_m_per_m == pytest.approx(0.01)
    assert rpe.rot_max_rad_per_m == pytest.approx(0.0, abs=1e-12)


def test_heading_drift_shows_in_rotation_error():
    """The estimate turns 0.02 rad per metre more than the truth: yaw error per metre is 0.02."""
    truth = straight_line(speed_mps=0.5)
    yaw = 0.02 * truth.xy[:, 0]
    estimate = PoseSeries(truth.t_s, truth.xy, yaw)
    rpe = relative_pose_error(estimate, truth, segment_m=2.0)
    assert rpe.rot_mean_rad_per_m == pytest.approx(0.02)


def test_rpe_shorter_than_a_segment_is_none():
    truth = straight_line(speed_mps=0.5, duration_s=1.0)
    rpe = relative_pose_error(truth, truth, segment_m=1.0)
    assert rpe.segments == 0
    summary = rpe.as_dict()
    assert summary == {"rpe_trans_mean_m_per_m": None, "rpe_trans_max_m_per_m": None, "rpe_rot_mean_rad_per_m": None,
                       "rpe_rot_max_rad_per_m": None, "rpe_segments": 0}
    json.dumps(summary, allow_nan=False)


def test_rpe_segment_must_be_positive():
    with pytest.raises(PoseSeriesError, match="segment_m"):
        relative_pose_error(straight_line(), straight_line(), segment_m=0.0)


def test_compose_chain_interpolates_the_outer_transform_at_inner_stamps():
    from pppbot_eval.trajectory import compose_chain
    # map → odom drifts from (0, 0, 0) at t=1 to (1, 0, π/2) at t=3 (published rarely).
    outer = PoseSeries.from_rows([(1.0, 0.0, 0.0, 0.0), (3.0, 1.0, 0.0, math.pi / 2)])
    # odom → base_link: the robot 1 m ahead in odom, at 10 Hz from t=0 to t=4.
    inner = PoseSeries.from_rows([(k / 10, 1.0, 0.0, 0.0) for k in range(41)])
    chain = compose_chain(outer, inner)
    assert chain.t_s[0] == pytest.approx(1.0) and chain.t_s[-1] == pytest.approx(3.0)  # no extrapolation
    i = int(np.argmin(np.abs(chain.t_s - 3.0)))
    assert chain.xy[i] == pytest.approx([1.0, 1.0]) and chain.yaw_rad[i] == pytest.approx(math.pi / 2)
    j = int(np.argmin(np.abs(chain.t_s - 2.0)))  # halfway: (0.5, 0, π/4) ∘ (1, 0, 0)
    assert chain.xy[j] == pytest.approx([0.5 + math.cos(math.pi / 4), math.sin(math.pi / 4)])
    static = compose_chain(PoseSeries.from_rows([(0.0, 2.0, 0.0, 0.0)]), inner)
    assert len(static) == len(inner) and static.xy[:, 0] == pytest.approx(3.0)
