"""The particle filter: KLD bound, resampling, recovery injection and clusters."""
from __future__ import annotations

import math

import numpy as np
import pytest

from pppbot_nav.amcl.filter import FilterSettings, ParticleFilter, kld_limit, uniform_poses
from pppbot_nav.errors import AmclError

FREE_XY = np.array([[x, y] for x in np.arange(-5, 5, 0.05) for y in np.arange(-5, 5, 0.05)])


def test_kld_bound_grows_with_occupied_bins_and_stays_in_the_particle_limits():
    s = FilterSettings(min_particles=100, max_particles=5000, pf_err=0.05, pf_z=0.99)
    n = kld_limit(np.arange(1, 1000), s)
    assert n[0] == 5000  # one bin: nothing learnt yet, keep them all
    assert np.all(np.diff(n[1:]) >= 0)
    assert n[1] == 100 and n[-1] == 5000
    # Fox (2003) as Nav2's pf.c computes it, pf_z being the quantile itself:
    # k = 50, ε = 0.05: ⌈(49/0.1)·(1 − 2/441 + √(2/441)·0.99)³⌉ = 588.
    assert kld_limit(50, s) == 588
    # the textbook's z for a 99 % bound, 2.326: 750
    assert kld_limit(50, FilterSettings(min_particles=100, max_particles=5000, pf_err=0.05, pf_z=2.326)) == 750


def test_resampling_a_concentrated_set_keeps_min_particles_and_a_spread_one_keeps_max():
    rng = np.random.default_rng(0)
    pf = ParticleFilter(FilterSettings(min_particles=300, max_particles=3000))
    pf.init_gaussian(np.array([1.0, 1.0, 0.1]), np.diag([1e-4, 1e-4, 1e-4]), rng)
    pf.resample(rng, lambda n, r: uniform_poses(FREE_XY, 0.05, n, r))
    assert len(pf) == 301  # Nav2 stops once the count exceeds the bound
    pf.init_uniform(FREE_XY, 0.05, rng)
    pf.resample(rng, lambda n, r: uniform_poses(FREE_XY, 0.05, n, r))
    assert len(pf) == 3000


def test_resampling_draws_in_proportion_to_weight():
    rng = np.random.default_rng(1)
    pf = ParticleFilter(FilterSettings(min_particles=2000, max_particles=2000))
    pf.particles = np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]])
    pf.weights = np.array([0.5, 0.5])
    pf.update_sensor(np.array([1.0, 3.0]))
    pf.resample(rng, lambda n, r: np.zeros((n, 3)))
    assert np.mean(pf.particles[:, 0] == 3.0) == pytest.approx(0.75, abs=0.03)
    assert np.allclose(pf.weights, 1 / 2000)


def test_a_sudden_drop_in_likelihood_injects_random_particles_when_recovery_is_on():
    rng = np.random.default_rng(2)
    pf = ParticleFilter(FilterSettings(min_particles=1000, max_particles=1000,
                                       recovery_alpha_slow=0.001, recovery_alpha_fast=0.1))
    pf.init_gaussian(np.zeros(3), np.diag([0.01, 0.01, 0.01]), rng)
    for _ in range(20):
        pf.update_sensor(np.full(len(pf), 10.0))
    pf.update_sensor(np.full(len(pf), 1.0))  # the scan stopped fitting
    assert 0.0 < pf.random_fraction() < 1.0
    expected = pf.random_fraction()
    far = np.array([[50.0, 50.0, 0.0]])
    pf.resample(rng, lambda n, r: np.repeat(far, n, axis=0))
    assert np.mean(pf.particles[:, 0] == 50.0) == pytest.approx(expected, abs=0.05)
    assert pf.w_slow == pf.w_fast == 0.0  # Nav2 restarts the averages after injecting


def test_recovery_off_never_injects():
    pf = ParticleFilter(FilterSettings())
    pf.init_gaussian(np.zeros(3), np.eye(3) * 0.01, np.random.default_rng(3))
    pf.update_sensor(np.full(len(pf), 10.0))
    pf.update_sensor(np.full(len(pf), 1.0))
    assert pf.random_fraction() == 0.0


def test_clusters_separate_distant_groups_and_join_across_the_yaw_seam():
    rng = np.random.default_rng(4)
    pf = ParticleFilter(FilterSettings(min_particles=10, max_particles=3000))
    a = rng.normal([0.0, 0.0, math.pi], [0.05, 0.05, 0.03], size=(2000, 3))  # straddles ±π
    b = rng.normal([4.0, 1.0, 0.0], [0.05, 0.05, 0.03], size=(1000, 3))
    pf.particles = np.vstack([a, b])
    pf.particles[:, 2] = np.angle(np.exp(1j * pf.particles[:, 2]))
    pf.weights = np.full(3000, 1 / 3000)
    clusters = pf.clusters()
    assert len(clusters) == 2
    assert clusters[0].weight == pytest.approx(2 / 3)
    assert np.allclose(clusters[0].mean[:2], [0.0, 0.0], atol=0.01)
    assert abs(abs(clusters[0].mean[2]) - math.pi) < 0.01
    assert clusters[0].covariance[0, 0] == pytest.approx(0.05 ** 2, rel=0.15)
    assert clusters[0].covariance[2, 2] == pytest.approx(0.03 ** 2, rel=0.15)
    assert np.allclose(clusters[1].mean, [4.0, 1.0, 0.0], atol=0.01)


def test_gaussian_initialisation_follows_mean_and_covariance():
    pf = ParticleFilter(FilterSettings(max_particles=20000, min_particles=10))
    cov = np.array([[0.04, 0.01, 0.0], [0.01, 0.09, 0.0], [0.0, 0.0, 0.01]])
    pf.init_gaussian(np.array([1.0, -2.0, 0.5]), cov, np.random.default_rng(5))
    assert np.allclose(pf.particles.mean(axis=0), [1.0, -2.0, 0.5], atol=0.01)
    assert np.allclose(np.cov(pf.particles.T), cov, atol=0.004)


@pytest.mark.parametrize("mean, cov, what", [
    (np.array([0.0, math.nan, 0.0]), np.eye(3), "three finite"),
    (np.zeros(3), -np.eye(3), "positive semi-definite"),
    (np.zeros(3), np.array([[1, 2, 0], [0, 1, 0], [0, 0, 1.0]]), "symmetric"),
])
def test_bad_initial_poses_are_refused_by_value(mean, cov, what):
    with pytest.raises(AmclError, match=what):
        ParticleFilter(FilterSettings()).init_gaussian(mean, cov, np.random.default_rng(0))


@pytest.mark.parametrize("settings, name", [
    (FilterSettings(min_particles=600, max_particles=500), "min_particles"),
    (FilterSettings(pf_err=0.0), "pf_err"),
    (FilterSettings(pf_z=0.0), "pf_z"),
    (FilterSettings(pf_z=math.nan), "pf_z"),
    (FilterSettings(recovery_alpha_fast=-0.1), "recovery_alpha_fast"),
])
def test_bad_filter_settings_are_refused_by_name(settings, name):
    with pytest.raises(AmclError, match=name):
        ParticleFilter(settings)
