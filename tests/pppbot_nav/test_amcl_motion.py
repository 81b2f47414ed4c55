"""Odometry motion models: exact without noise, and the noise statistics of Nav2's alphas."""
from __future__ import annotations

import math

import numpy as np
import pytest

from pppbot_common.se2 import se2_compose, wrap_angles
from pppbot_nav.amcl.motion import (
    DifferentialMotionModel,
    MotionNoise,
    OmniMotionModel,
    RobotModel,
    motion_model,
)

SILENT = MotionNoise(0.0, 0.0, 0.0, 0.0, 0.0)
N = 40000


def spread(model: DifferentialMotionModel | OmniMotionModel, step: np.ndarray, seed: int = 0) -> np.ndarray:
    """``N`` particles at the origin moved by the odometry step from (1, 2, 0.5) to (1, 2, 0.5) ∘ step."""
    particles = np.zeros((N, 3))
    old = np.array([1.0, 2.0, 0.5])
    model.sample(particles, old, se2_compose(old, step), np.random.default_rng(seed))
    return particles


@pytest.mark.parametrize("model", [DifferentialMotionModel(SILENT), OmniMotionModel(SILENT)])
@pytest.mark.parametrize("step", [(0.3, 0.0, 0.0), (0.2, 0.1, 0.4), (-0.25, 0.0, 0.1), (0.0, 0.0, -1.2)])
def test_without_noise_each_particle_moves_by_the_odometry_step_in_its_own_frame(model, step):
    particles = np.array([[0.0, 0.0, 0.0], [3.0, -1.0, 2.5], [-2.0, 4.0, -3.0]])
    old = np.array([1.0, 2.0, 0.5])
    expected = se2_compose(particles, np.array(step))
    model.sample(particles, old, se2_compose(old, np.array(step)), np.random.default_rng(0))
    assert np.allclose(particles[:, :2], expected[:, :2], atol=1e-9)
    assert np.allclose(wrap_angles(particles[:, 2] - expected[:, 2]), 0.0, atol=1e-9)


def test_differential_noise_follows_the_alphas_on_a_straight_step():
    a = MotionNoise(alpha1=0.1, alpha2=0.05, alpha3=0.2, alpha4=0.3)
    p = spread(DifferentialMotionModel(a), np.array([1.0, 0.0, 0.0]))
    # Translation noise: alpha3·trans² (no turns); heading noise: two turns of alpha2·trans² each.
    assert np.std(p[:, 0]) == pytest.approx(math.sqrt(a.alpha3), rel=0.03)
    assert np.std(p[:, 2]) == pytest.approx(math.sqrt(2 * a.alpha2), rel=0.03)
    assert np.mean(np.hypot(p[:, 0], p[:, 1])) == pytest.approx(1.0, abs=0.01)  # unbiased distance


def test_differential_noise_of_a_turn_on_the_spot_follows_alpha1_and_alpha4():
    a = MotionNoise(alpha1=0.1, alpha2=0.0, alpha3=0.0, alpha4=0.2)
    p = spread(DifferentialMotionModel(a), np.array([0.0, 0.0, 0.8]))
    assert np.std(wrap_angles(p[:, 2] - 0.8)) == pytest.approx(math.sqrt(a.alpha1) * 0.8, rel=0.03)
    assert np.std(np.hypot(p[:, 0], p[:, 1])) > 0.5 * math.sqrt(a.alpha4) * 0.8  # translation noise from rotation


def test_driving_backwards_is_not_taken_for_turning_around():
    a = MotionNoise(alpha1=0.5, alpha2=0.01, alpha3=0.01, alpha4=0.5)
    forward = spread(DifferentialMotionModel(a), np.array([0.5, 0.0, 0.0]))
    backward = spread(DifferentialMotionModel(a), np.array([-0.5, 0.0, 0.0]))
    assert np.std(backward[:, 2]) == pytest.approx(np.std(forward[:, 2]), rel=0.05)
    assert np.mean(backward[:, 0]) == pytest.approx(-0.5, abs=0.01)


def test_omni_strafe_noise_follows_alpha5():
    a = MotionNoise(alpha1=0.0, alpha2=0.0, alpha3=0.0, alpha4=0.0, alpha5=0.09)
    p = spread(OmniMotionModel(a), np.array([1.0, 0.0, 0.0]))
    assert np.std(p[:, 1]) == pytest.approx(0.3, rel=0.03)
    assert np.std(p[:, 0]) == pytest.approx(0.0, abs=1e-9)


def test_models_are_chosen_by_nav2s_names():
    assert isinstance(motion_model(RobotModel("nav2_amcl::DifferentialMotionModel"), SILENT),
                      DifferentialMotionModel)
    assert isinstance(motion_model(RobotModel("nav2_amcl::OmniMotionModel"), SILENT), OmniMotionModel)
