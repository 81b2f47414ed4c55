"""The localizer on a synthetic room: convergence, global localization, update gating, refinement."""
from __future__ import annotations

import math

import numpy as np
import pytest
from amcl_synthetic import BEAMS, LIDAR, RANGE_MAX, box, drive, grid, ranges, scan

from pppbot_common.se2 import se2_compose
from pppbot_nav.amcl.filter import FilterSettings
from pppbot_nav.amcl.laser import LaserSettings, Scan
from pppbot_nav.amcl.localizer import (
    Localizer,
    LocalizerMode,
    LocalizerSettings,
    covariance_from_message,
    covariance_to_message,
)
from pppbot_nav.errors import AmclError

NAV2_INITIAL_COVARIANCE = np.diag([0.5 ** 2, 0.5 ** 2, (math.pi / 12) ** 2])


def localizer(seed: int = 0, **settings) -> Localizer:
    return Localizer(LocalizerSettings(**settings), grid(), np.random.default_rng(seed))


def run(loc: Localizer, seed: int = 0, noise_m: float = 0.01) -> list[tuple[float, float, float, int, float]]:
    """Drive the route; (distance, position error, yaw error, particles, error of the particles'
    weighted mean position) at each filter update."""
    rng = np.random.default_rng(seed + 100)
    errors = []
    for distance, truth, odom in drive(seed=seed):
        update = loc.update(odom, scan(truth, noise_m=noise_m, rng=rng), scan(truth, max_beams=360, noise_m=noise_m,
                                                                                 rng=rng))
        if update is not None:
            e = update.estimate.mean - truth
            mean = np.average(loc.filter.particles[:, :2], axis=0, weights=loc.filter.weights)
            errors.append((distance, math.hypot(e[0], e[1]), abs(math.remainder(e[2], 2 * math.pi)), len(loc.filter),
                           float(np.hypot(*(mean - truth[:2])))))
    return errors


def converged_at(errors: list[tuple[float, float, float, int, float]], position_m: float, yaw_rad: float) -> float:
    """Distance after which every update is within the bounds."""
    bad = [d for d, p, y, *_ in errors if p > position_m or y > yaw_rad]
    return max(bad, default=0.0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_converges_from_half_a_metre_and_0_3_rad_within_2_m(seed):
    start = drive()[0][1]
    loc = localizer(seed)
    off = np.array([0.5 * math.cos(seed), 0.5 * math.sin(seed), 0.3 if seed % 2 else -0.3])
    loc.set_initial_pose(start + off, NAV2_INITIAL_COVARIANCE)
    errors = run(loc, seed)
    assert converged_at(errors, 0.05, math.radians(1.0)) < 2.0
    late = np.array([e for e in errors if e[0] > 2.0])
    assert np.sqrt(np.mean(late[:, 1] ** 2)) < 0.03
    assert np.sqrt(np.mean(late[:, 2] ** 2)) < math.radians(1.0)
    assert late[-1, 3] < 2000  # KLD shrank the set once it converged


@pytest.mark.parametrize("seed", [3, 4])
def test_global_localization_finds_the_robot_anywhere_in_the_map(seed):
    loc = localizer(seed)
    loc.global_localization()
    assert len(loc.filter) == 2000
    spread = loc.filter.particles
    assert np.ptp(spread[:, 0]) > 6.0 and np.ptp(spread[:, 1]) > 4.0  # uniform until the first scan
    errors = run(loc, seed)
    assert converged_at(errors, 0.1, 0.05) < 5.0


def test_refinement_is_more_accurate_than_the_particle_mean():
    start = drive()[0][1]
    results = {}
    for refine in (False, True):
        loc = localizer(4, refine_estimate=refine)
        loc.set_initial_pose(start, NAV2_INITIAL_COVARIANCE / 25)
        late = np.array([e for e in run(loc, 4) if e[0] > 2.0])
        results[refine] = np.sqrt(np.mean(late[:, 1] ** 2))
    assert results[True] < 0.5 * results[False]


def test_standing_still_the_fit_between_updates_is_not_made_again():
    """Between filter updates the estimate is fitted to each scan, but not again while odometry
    stands still (it would only follow the scan's noise); moving, or a new update, fits again."""
    loc = localizer(4, refine_estimate=True, update_min_d=0.25, update_min_a=0.2)
    _, truth, odom = drive()[0]
    loc.set_initial_pose(truth + [0.03, -0.02, 0.01], NAV2_INITIAL_COVARIANCE / 100)
    assert loc.update(odom, scan(truth)) is not None
    assert loc.track(odom, scan(truth)) is not None  # the first fit after the update
    assert loc.track(odom, scan(truth)) is None  # standing still
    assert loc.track(odom + [0.0005, 0.0, 0.0], scan(truth)) is None  # within a millimetre
    moved = odom + [0.01, 0.0, 0.0]
    assert loc.track(moved, scan(truth + [0.01, 0.0, 0.0])) is not None
    loc.request_nomotion_update()
    assert loc.update(moved, scan(truth + [0.01, 0.0, 0.0])) is not None
    assert loc.track(moved, scan(truth + [0.01, 0.0, 0.0])) is not None  # a new update: fitted again


def test_in_an_open_field_of_cones_the_beams_that_returned_keep_it_localized():
    """A 14 m field with 16 cones (0.24 m) and nothing else: with Nav2's pick of 60 of 360
    beams few of the hits are weighed and the filter drifts off by metres; spread over the
    beams that returned (``beams_with_returns``), it tracks the robot to centimetres."""
    cones = np.random.default_rng(5).uniform(-7.0, 7.0, size=(16, 2))
    segments = np.array([side for x, y in cones for side in box(x - 0.12, y - 0.12, x + 0.12, y + 0.12)])
    route = np.array([[0.0, 0.0], [5.5, 0.0], [5.5, 5.5], [-5.5, 5.5], [-5.5, -5.5], [3.0, -5.5]])
    errors = {}
    for returns in (False, True):
        settings = LaserSettings(beams_with_returns=returns)
        loc = Localizer(LocalizerSettings(laser=settings), grid(segments, margin_m=1.0), np.random.default_rng(1))
        path = drive(route, seed=1)
        loc.set_initial_pose(path[0][1] + [0.35, 0.35, 0.3], NAV2_INITIAL_COVARIANCE)
        noise = np.random.default_rng(2)
        late = []
        for distance, truth, odom in path[::2]:
            args = (ranges(truth, segments, noise_m=0.01, rng=noise), -math.pi, 2 * math.pi / BEAMS, 0.12, RANGE_MAX,
                    LIDAR, settings)
            full = Scan.from_laser(*args, max_beams=BEAMS)
            if loc.update(odom, Scan.from_laser(*args), full) is None:
                loc.track(odom, full)
            if distance > 5.0:
                assert loc.last is not None
                estimate = se2_compose(loc.last.map_to_odom, odom)
                late.append(math.hypot(*(estimate[:2] - truth[:2])))
        errors[returns] = math.sqrt(np.mean(np.square(late)))
    assert errors[True] < 0.03, errors
    assert errors[False] > 0.2, errors  # what Nav2's pick gives here


def test_nothing_happens_before_an_initial_pose():
    loc = localizer()
    _, truth, odom = drive()[0]
    assert loc.update(odom, scan(truth)) is None
    assert not loc.initialized


def test_the_mode_goes_from_no_pose_to_tracking_or_through_global_localization():
    loc = localizer()
    _, truth, odom = drive()[0]
    assert loc.mode is LocalizerMode.UNINITIALIZED
    loc.set_initial_pose(truth, NAV2_INITIAL_COVARIANCE / 100)
    assert loc.mode is LocalizerMode.TRACKING
    loc.global_localization()
    assert loc.mode is LocalizerMode.SEARCH_PENDING and loc.initialized
    assert loc.update(odom, scan(truth), scan(truth, max_beams=360)) is not None
    # the search has placed the particles; one settled hypothesis that fits ends it
    assert loc.mode in (LocalizerMode.SETTLING, LocalizerMode.TRACKING)
    for _, truth, odom in drive()[1:60]:
        loc.request_nomotion_update()
        loc.update(odom, scan(truth), scan(truth, max_beams=360))
        if loc.mode is LocalizerMode.TRACKING:
            break
    assert loc.mode is LocalizerMode.TRACKING


@pytest.mark.parametrize(("mean", "covariance", "message"), [
    ((1e6, 1e6, 0.0), NAV2_INITIAL_COVARIANCE, r"at \(1e\+06, 1e\+06\) lies outside the map \(x -4\.53 to 4\.53 m"),
    ((0.0, -3.6, 0.0), NAV2_INITIAL_COVARIANCE, r"at \(0, -3\.6\) lies outside the map"),
    (None, np.diag([1e300, 1e300, 1.0]), r"spread \(a standard deviation of 1e\+150 m\) is wider than the map "
                                         r"\(11\.47 m across\).*reinitialize_global_localization"),
    (None, np.diag([0.01, 12.0 ** 2, 1.0]), r"standard deviation of 12 m"),
])
def test_an_initial_pose_off_the_map_or_wider_than_it_is_refused_and_the_particles_stay(mean, covariance, message):
    """A stranger's /initialpose (issue 55): Nav2 takes it and localizes nowhere; here it is named
    and the filter goes on where it was."""
    loc = localizer()
    _, truth, odom = drive()[0]
    loc.set_initial_pose(truth, NAV2_INITIAL_COVARIANCE / 100)
    assert loc.update(odom, scan(truth)) is not None
    before = loc.filter.particles.copy()
    with pytest.raises(AmclError, match=message):
        loc.set_initial_pose(np.array(truth if mean is None else mean), covariance)
    assert np.array_equal(loc.filter.particles, before)
    # A pose on the map's very corner, with the widest spread the map allows, is taken; half a cell
    # beyond the corner, or a spread a centimetre wider, is not.
    g = loc.field.grid
    x0, x1, y0, y1 = g.extent
    across = math.hypot(x1 - x0, y1 - y0)
    loc.set_initial_pose(np.array([x1, y0, 0.0]), np.diag([across ** 2, 0.01, 0.1]))
    assert np.abs(loc.filter.particles[:, 0].std() - across) < 0.1 * across
    with pytest.raises(AmclError, match="outside the map"):
        loc.set_initial_pose(np.array([x1 + 0.51 * g.resolution, y0, 0.0]), NAV2_INITIAL_COVARIANCE)
    with pytest.raises(AmclError, match="wider than the map"):
        loc.set_initial_pose(np.array([x1, y0, 0.0]), np.diag([(across + 0.01) ** 2, 0.01, 0.1]))


def test_updates_wait_for_update_min_d_or_a_unless_forced():
    loc = localizer(update_min_d=0.25, update_min_a=0.2)
    _, truth, odom = drive()[0]
    loc.set_initial_pose(truth, NAV2_INITIAL_COVARIANCE / 100)
    s = scan(truth)
    assert loc.update(odom, s) is not None  # the first scan after an initial pose
    assert loc.update(odom + [0.2, 0.0, 0.0], s) is None
    assert loc.update(odom + [0.0, 0.0, 0.15], s) is None
    assert loc.update(odom + [0.3, 0.0, 0.0], s) is not None
    loc.request_nomotion_update()
    assert loc.update(odom + [0.3, 0.0, 0.0], s) is not None
    assert loc.update(odom + [0.3, 0.0, 0.0], s) is None
    assert loc.update(odom + [0.3, 0.0, 0.25], s) is not None


def test_resample_interval_skips_resampling_between_updates():
    loc = localizer(resample_interval=2)
    _, truth, odom = drive()[0]
    loc.set_initial_pose(truth, NAV2_INITIAL_COVARIANCE / 100)
    flags = []
    for _ in range(4):
        loc.request_nomotion_update()
        update = loc.update(odom, scan(truth))
        assert update is not None
        flags.append(update.resampled)
    assert flags == [False, True, False, True]


def test_map_to_odom_puts_the_base_at_the_estimate():
    loc = localizer()
    _, truth, _ = drive()[0]
    odom = np.array([1.0, -0.5, 0.7])
    loc.set_initial_pose(truth, NAV2_INITIAL_COVARIANCE / 1e4)
    update = loc.update(odom, scan(truth))
    from pppbot_common.se2 import se2_compose
    assert update is not None
    assert np.allclose(se2_compose(update.map_to_odom, odom), update.estimate.mean, atol=1e-9)


def test_a_non_finite_odometry_pose_is_refused():
    loc = localizer()
    loc.global_localization()
    with pytest.raises(AmclError, match="odometry pose"):
        loc.update(np.array([0.0, math.inf, 0.0]), scan(np.array([0.5, -1.0, 0.0])))


def test_covariance_round_trips_through_the_ros_layout():
    cov = np.array([[0.2, 0.01, 0.003], [0.01, 0.3, 0.002], [0.003, 0.002, 0.05]])
    ros = covariance_to_message(cov)
    assert ros[0] == 0.2 and ros[7] == 0.3 and ros[35] == 0.05 and ros[5] == 0.003
    assert np.array_equal(covariance_from_message(ros), cov)
    with pytest.raises(AmclError, match="36"):
        covariance_from_message([0.0] * 35)


def test_particles_redrawn_around_the_refined_estimate_keep_the_particles_on_the_robot():
    start = drive()[0][1]
    mean_error = {}
    for fraction in (0.0, 0.1):
        errors = []
        for seed in (0, 1, 2):  # one seed's ratio ranges from 0.4 to 0.8
            loc = localizer(seed, refined_particle_fraction=fraction)
            loc.set_initial_pose(start, NAV2_INITIAL_COVARIANCE / 25)
            errors += [e[4] for e in run(loc, seed)]
        mean_error[fraction] = float(np.sqrt(np.mean(np.square(errors))))
    assert mean_error[0.1] < 0.7 * mean_error[0.0]


def test_replacing_particles_keeps_the_weights_normalised():
    from pppbot_nav.amcl.filter import ParticleFilter
    pf = ParticleFilter(FilterSettings(min_particles=10, max_particles=100))
    pf.init_gaussian(np.zeros(3), np.eye(3) * 0.01, np.random.default_rng(0))
    pf.update_sensor(np.linspace(1.0, 5.0, 100))
    pf.replace_some(np.tile([9.0, 9.0, 0.0], (10, 1)), np.random.default_rng(1))
    assert np.sum(pf.particles[:, 0] == 9.0) == 10
    assert pf.weights.sum() == pytest.approx(1.0)


def test_reconfiguring_keeps_the_particles_and_updates_on_the_next_scan():
    loc = localizer(update_min_d=0.25)
    _, truth, odom = drive()[0]
    loc.set_initial_pose(truth, NAV2_INITIAL_COVARIANCE / 100)
    s = scan(truth)
    loc.update(odom, s)
    before = loc.filter.particles.copy()
    loc.reconfigure(LocalizerSettings(update_min_d=1.0, laser=loc.settings.laser))
    assert np.array_equal(loc.filter.particles, before) and loc.initialized
    assert loc.update(odom, s) is not None  # forced once
    assert loc.update(odom + [0.5, 0.0, 0.0], s) is None  # under the new update_min_d
    with pytest.raises(AmclError, match="min_particles"):
        loc.reconfigure(LocalizerSettings(filter=FilterSettings(min_particles=10, max_particles=5)))
    assert loc.settings.update_min_d == 1.0  # the refused settings changed nothing


def test_global_localization_searches_again_when_the_hypothesis_it_settles_on_does_not_fit():
    """A cluster that holds all the weight where the scan does not fit the map (an alias of
    the place, as a maze has many) is not taken: the particles are searched for again."""
    _, truth, odom = drive()[0]
    loc = localizer(1)
    loc.global_localization()
    assert loc.update(odom, scan(truth), scan(truth, max_beams=360)) is not None
    wrong = truth + np.array([-4.5, 2.6, 0.0])  # free space across the room, the same heading
    assert loc.fitter.fit_fraction(wrong, scan(truth, max_beams=360)) < 0.5
    assert loc.fitter.fit_fraction(truth, scan(truth, max_beams=360)) > 0.95
    loc.filter.particles = np.tile(wrong, (len(loc.filter), 1))  # collapsed on the wrong place
    loc.request_nomotion_update()
    update = loc.update(odom, scan(truth), scan(truth, max_beams=360))
    assert update is not None and update.alias is not None
    assert np.hypot(*(update.alias[0][:2] - wrong[:2])) < 0.35 and update.alias[1] < 0.5
    particles = loc.filter.particles
    near_wrong = np.hypot(*(particles[:, :2] - wrong[:2]).T) < 0.5
    near_truth = (np.hypot(*(particles[:, :2] - truth[:2]).T) < 0.15) & (
        np.abs(np.remainder(particles[:, 2] - truth[2] + np.pi, 2 * np.pi) - np.pi) < 0.1)
    assert near_wrong.mean() < 0.05  # the alias let go
    assert near_truth.any()  # and the robot's true place is among the hypotheses again


def test_a_set_initial_pose_is_trusted_without_the_fit_test():
    """Outside global localization the filter is never restarted by the fit test: a pose the
    user gave stays the estimate's neighbourhood even where the scan fits poorly."""
    _, truth, odom = drive()[0]
    loc = localizer(1)
    wrong = truth + np.array([-4.5, 2.6, 0.0])
    loc.set_initial_pose(wrong, NAV2_INITIAL_COVARIANCE / 100)
    update = loc.update(odom, scan(truth), scan(truth, max_beams=360))
    assert update is not None and np.hypot(*(update.estimate.mean[:2] - wrong[:2])) < 0.5
