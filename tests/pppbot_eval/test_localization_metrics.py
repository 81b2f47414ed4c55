"""AMCL's figures from an estimate and the truth: when it converged and its error from then on."""
from __future__ import annotations

import numpy as np
import pytest

from pppbot_eval.scenarios import localization_metrics
from pppbot_eval.trajectory import PoseSeries, absolute_trajectory_error


def straight_run(offset_of_travel) -> tuple[PoseSeries, PoseSeries]:
    """10 m along x at 1 m/s, sampled at 10 Hz; the estimate is off in y by ``offset_of_travel(x)``."""
    t = np.arange(0.0, 10.0, 0.1)
    truth = PoseSeries.from_poses(t, np.column_stack([t, np.zeros_like(t), np.zeros_like(t)]))
    estimate = PoseSeries.from_poses(t, np.column_stack([t, offset_of_travel(t), np.zeros_like(t)]))
    return estimate, truth


def test_converges_where_the_error_stays_small_and_is_measured_from_there():
    # 0.5 m off, shrinking to 2 cm by 3 m of travel, then 2 cm.
    estimate, truth = straight_run(lambda x: np.where(x < 3.0, 0.5 - 0.16 * x, 0.02))
    metrics = localization_metrics(absolute_trajectory_error(estimate, truth), truth)
    assert metrics["initial_position_error_m"] == pytest.approx(0.5)
    assert metrics["converged"] is True
    # The error is within 0.1 m from x = 2.5 m on (0.5 − 0.16 x ≤ 0.1).
    assert metrics["converged_after_m"] == pytest.approx(2.5, abs=0.051)
    assert metrics["amcl_max_m"] <= 0.1 and metrics["amcl_rms_m"] < 0.04


def test_a_later_spike_shows_in_the_maximum_and_never_settling_is_reported():
    # Within bounds from the start (1 m of it is enough), then a 0.3 m spike from 4 to 5 m.
    estimate, truth = straight_run(lambda x: np.where((x > 4.0) & (x < 5.0), 0.3, 0.02))
    metrics = localization_metrics(absolute_trajectory_error(estimate, truth), truth)
    assert metrics["converged_after_m"] == pytest.approx(0.0)
    assert metrics["amcl_max_m"] == pytest.approx(0.3)
    estimate, truth = straight_run(lambda x: 0.5 + 0.0 * x)
    never = localization_metrics(absolute_trajectory_error(estimate, truth), truth)
    assert never["converged"] is False and never["converged_after_m"] is None and "amcl_rms_m" not in never


def test_map_to_odom_stamped_ahead_is_taken_back_to_the_scan_it_came_from():
    from pppbot_common.se2 import se2_compose, se2_inverse
    from pppbot_eval.scenarios import ESTIMATES, Recording, Scenario, estimate_series

    t = np.arange(0.0, 20.0, 0.1)
    truth = np.column_stack([0.3 * t, np.zeros_like(t), 0.05 * t])
    drift = np.column_stack([0.01 * t, -0.02 * t, 0.01 * t])  # odometry's error grows
    odom = se2_compose(drift, truth)
    correction = se2_compose(truth, se2_inverse(odom))  # map → odom that puts the base on the truth
    recording = Recording()
    recording.edge_rows[("odom", "base_link")] = [(ti, *p) for ti, p in zip(t, odom, strict=True)]
    recording.edge_rows[("map", "odom")] = [(ti + 1.0, *c) for ti, c in zip(t, correction, strict=True)]  # 1 s ahead
    at_scan = estimate_series(recording, ESTIMATES[Scenario.LOCALIZATION], outer_ahead_s=1.0)
    assert np.allclose(at_scan.xy, truth[: len(at_scan), :2], atol=1e-6)
    as_stamped = estimate_series(recording, ESTIMATES[Scenario.LOCALIZATION])
    assert as_stamped.t_s[0] == pytest.approx(1.0)  # a TF user has nothing before the first stamp
    lagging = np.hypot(*(as_stamped.xy - truth[10:10 + len(as_stamped), :2]).T)
    assert lagging.max() > 0.01  # a correction 1 s old, with 1 s more of drift
