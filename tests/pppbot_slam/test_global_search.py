"""The global loop search (issue 45): a loop beyond the local window found after drift, aliases refused."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from slam_synthetic import CORRIDOR, RING, drifting_odometry, feed, ring_path
from test_visibility import corridors, front_rays, hall_search, hits, rays_at, search_from

from pppbot_common.se2 import se2_apply, se2_compose
from pppbot_slam.errors import MapperError
from pppbot_slam.likelihood_field import rotate
from pppbot_slam.loops import LOOP_SEE_THROUGH_MAX, LoopChain, LoopSearch, solve_loops
from pppbot_slam.mapper import Mapper, MapperSettings
from pppbot_slam.visibility import view_of


def claimed_pose(search: LoopSearch, match) -> np.ndarray:
    """Where a match puts the searching keyframe in the map."""
    return np.asarray(se2_compose(search.chains[0].poses[list(search.chains[0].indices).index(match.source)],
                                  match.relative))


@pytest.mark.parametrize("drift", [(5.0, -2.0, 0.2), (-6.0, 1.0, -0.3)])
def test_a_loop_beyond_the_local_window_is_found_by_the_global_search(drift):
    first_pass, _ = hall_search()
    truth = np.array([-1.2, -3.4, 0.08])  # back on the first pass's line, its estimate drifted 5-6 m
    rays = front_rays(truth)
    own, own_normals = hits(rays)
    local = LoopSearch(40, truth + np.array(drift), own, own_normals, first_pass.chains, rays, np.zeros(3))
    assert local.run(MapperSettings()) == []  # beyond loop_search_space_dimension's ±4 m
    search = replace(local, chains=(replace(first_pass.chains[0], global_search=True),))
    matches = search.run(MapperSettings())
    assert len(matches) == 1 and matches[0].global_search
    assert matches[0].response >= MapperSettings().loop_match_minimum_response_global
    np.testing.assert_allclose(claimed_pose(search, matches[0])[:2], truth[:2], atol=0.03)
    assert abs(claimed_pose(search, matches[0])[2] - truth[2]) < 0.01
    assert matches[0].see_through <= LOOP_SEE_THROUGH_MAX


def test_an_alias_the_global_window_finds_is_refused_for_seeing_through_a_wall():
    graph, truth, chain = corridors()
    last = len(truth) - 1
    estimate = truth[last] + np.array([3.0, -1.6, 0.1])
    matches = search_from(truth[last], estimate, last, replace(chain, global_search=True)).run(MapperSettings())
    assert len(matches) == 1 and abs(se2_compose(truth[matches[0].source], matches[0].relative)[1]) < 0.3  # in A
    graph.poses[-1] = estimate
    solution = solve_loops(graph.copy(), matches)
    assert solution.accepted == [] and solution.rejected == 1


def test_a_corridor_that_cannot_pin_a_global_match_along_it_is_refused(monkeypatch):
    # Keyframes along a featureless corridor; one later in it, its estimate 3 m ahead: over a
    # ±7 m window, every place along the corridor scores the same.
    poses = np.array([(x, 0.0, 0.0) for x in np.arange(-6.0, 0.01, 0.5)])
    points, normals, views = [], [], []
    for pose in poses:
        rays = rays_at(CORRIDOR, pose, max_range=8.0)
        own, own_normals = hits(rays)
        views.append(view_of(pose, np.zeros(3), rays))
        points.append(se2_apply(pose, own))
        normals.append(rotate(own_normals, float(pose[2])))
    chain = LoopChain(np.arange(len(poses)), poses, np.vstack(points), np.vstack(normals), tuple(views),
                      global_search=True)
    truth = np.array([-3.0, 0.1, 0.02])
    rays = rays_at(CORRIDOR, truth, max_range=8.0)
    own, own_normals = hits(rays)
    search = LoopSearch(40, truth + np.array([3.0, 0.0, 0.0]), own, own_normals, (chain,), rays, np.zeros(3))
    assert search.run(MapperSettings()) == []
    monkeypatch.setattr("pppbot_slam.loops.GLOBAL_MAX_SPREAD_M", np.inf)
    slid = search.run(MapperSettings())  # without the check: taken, anywhere along the corridor
    assert len(slid) == 1 and abs(claimed_pose(search, slid[0])[0] - truth[0]) > 0.2


def run_ring(settings: MapperSettings) -> tuple[Mapper, np.ndarray]:
    truth = ring_path()
    mapper = Mapper(settings)
    feed(mapper, RING, truth, drifting_odometry(truth, yaw_per_m=0.01, scale=1.01))
    stamps = np.array([k.stamp_s for k in mapper.keyframes])
    errors = np.linalg.norm(np.array(mapper.graph.poses)[:, :2] - truth[np.round(stamps / 0.1).astype(int), :2], axis=1)
    return mapper, errors


def test_the_global_search_closes_a_loop_the_local_search_does_not_reach():
    # A local search that reaches almost nothing: the ring's return is found globally alone.
    mapper, errors = run_ring(MapperSettings(loop_search_maximum_distance=0.2))
    assert len(mapper.loop_closures) >= 1
    assert np.sqrt(np.mean(errors ** 2)) < 0.01 and errors.max() < 0.02
    off, off_errors = run_ring(MapperSettings(loop_search_maximum_distance=0.2, loop_search_global_distance=0.0))
    assert off.loop_closures == [] and off_errors.max() > 2 * errors.max()


def test_a_corridor_driven_straight_on_is_never_searched_globally():
    # The corridor ahead is always within reach and was always just driven through: no loop.
    truth = np.array([(x, 0.0, 0.0) for x in np.arange(-18.0, 18.0, 0.1)])
    mapper = Mapper(MapperSettings(loop_search_global_after_distance=0.0))
    feed(mapper, CORRIDOR, truth, truth)
    assert len(mapper.keyframes) > 60
    assert all(mapper.global_loop_search(i) is None for i in range(len(mapper.keyframes)))
    assert mapper.loop_closures == []


def test_global_search_waits_for_the_distance_since_the_last_closure():
    mapper, _ = run_ring(MapperSettings())
    poses = np.array(mapper.graph.poses)[:, :2]
    travelled = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(poses, axis=0).T))])
    mapper.loop_closures = [replace(mapper.loop_closures[0], target=5)]
    mapper.global_tried = -10
    after = travelled - travelled[5]
    due = [mapper.global_search_due(k) for k in range(len(poses))]
    assert not any(d for d, a in zip(due, after, strict=True) if a < 10.0)
    assert all(d for d, a in zip(due, after, strict=True) if a > 10.6)  # beyond 10 m and one keyframe
    mapper.global_tried = len(poses) - 2  # searched a keyframe ago
    assert not mapper.global_search_due(len(poses) - 1)
    assert not Mapper(MapperSettings(loop_search_global_distance=0.0)).global_search_due(100)


@pytest.mark.parametrize(("name", "value"), [("loop_search_global_distance", -1.0),
                                             ("loop_search_global_after_distance", float("nan")),
                                             ("loop_match_minimum_response_global", 1.5)])
def test_bad_global_settings_name_the_value(name, value):
    with pytest.raises(MapperError, match=name):
        MapperSettings(**{name: value})
