"""The mapper on a synthetic ring corridor: keyframes by travel, drift corrected, loops closed, a clean map."""
from __future__ import annotations

import numpy as np
import pytest
from slam_synthetic import RING, drifting_odometry, feed, ring_path, scan_rays, wall_points

from pppbot_common.maps import OCCUPIED
from pppbot_common.se2 import se2_compose, se2_inverse
from pppbot_slam.loops import LoopSolution, solve_loops
from pppbot_slam.mapper import Mapper, MapperError, MapperSettings


def run(settings: MapperSettings) -> tuple[Mapper, np.ndarray]:
    truth = ring_path()
    mapper = Mapper(settings)
    feed(mapper, RING, truth, drifting_odometry(truth, yaw_per_m=0.01, scale=1.01))
    return mapper, truth


@pytest.fixture(scope="module")
def mapped() -> tuple[Mapper, np.ndarray]:
    return run(MapperSettings())


def keyframe_errors(mapper: Mapper, truth: np.ndarray) -> np.ndarray:
    stamps = np.array([k.stamp_s for k in mapper.keyframes])
    true_poses = truth[np.round(stamps / 0.1).astype(int)]
    return np.linalg.norm(np.array(mapper.graph.poses)[:, :2] - true_poses[:, :2], axis=1)


def test_keyframes_follow_travel_and_turns(mapped):
    mapper, truth = mapped
    odom = np.array([k.odom_pose for k in mapper.keyframes])
    steps = np.linalg.norm(np.diff(odom[:, :2], axis=0), axis=1)
    turns = np.abs(np.diff(np.unwrap(odom[:, 2])))
    assert np.all((steps >= 0.5 - 1e-9) | (turns >= 0.5 - 1e-9))
    assert 55 <= len(mapper.keyframes) <= 75  # 32 m of path at 0.5 m, plus the corners


def test_drift_is_corrected_and_the_loop_is_closed(mapped):
    mapper, truth = mapped
    assert len(mapper.loop_closures) >= 1
    errors = keyframe_errors(mapper, truth)
    assert np.sqrt(np.mean(errors ** 2)) < 0.05 and errors.max() < 0.1
    # Every accepted loop edge agrees with the truth: no false closure.
    stamps = {k.index: round(k.stamp_s / 0.1) for k in mapper.keyframes}
    for closure in mapper.loop_closures:
        a, b = truth[stamps[closure.source]], truth[stamps[closure.target]]
        measured = mapper.graph.relative(closure.source, closure.target)
        assert np.linalg.norm(measured[:2] - se2_compose(se2_inverse(a), b)[:2]) < 0.1


def test_map_frame_relation_and_the_grid(mapped):
    mapper, truth = mapped
    # map → odom takes the last odometry pose onto the last keyframe's map pose.
    last = mapper.keyframes[-1]
    np.testing.assert_allclose(se2_compose(mapper.map_to_odom(), last.odom_pose), mapper.map_pose(last.index),
                               atol=1e-9)
    grid = mapper.grid()
    rows, cols = np.nonzero(grid.data == OCCUPIED)
    centres = np.stack([grid.origin[0] + (cols + 0.5) * grid.resolution,
                        grid.origin[1] + (rows + 0.5) * grid.resolution], axis=1)
    walls = wall_points(RING, 0.01)
    distance = np.min(np.linalg.norm(centres[:, None, :] - walls[None, ::2, :], axis=2), axis=1)
    # Every occupied cell lies on a wall (its centre within a cell and a half): no ghost walls.
    assert np.quantile(distance, 0.99) < 0.08


def test_loops_closed_beside_the_scans_merge_with_the_keyframes_added_meanwhile():
    """As the node's loop-closing thread does it: the search and the solve run on what the
    mapper was at keyframe i, and the result is merged two keyframes later."""
    truth = ring_path()
    odom = drifting_odometry(truth, yaw_per_m=0.01, scale=1.01)
    mapper = Mapper(MapperSettings(), defer_loops=True)
    in_flight: list[tuple[int, LoopSolution]] = []  # (keyframe it was solved at, solve_loops' result)
    moved_tails = 0
    for k in range(len(truth)):
        keyframe = mapper.process(0.1 * k, odom[k], scan_rays(RING, truth[k], seed=k))
        if keyframe is None:
            continue
        for solved_at, result in [item for item in in_flight if keyframe.index - item[0] >= 2]:
            last = len(result.graph.poses) - 1
            tail = [mapper.graph.relative(last, j) for j in range(last + 1, len(mapper.keyframes))]
            newest = mapper.graph.poses[-1].copy()
            moved = mapper.merge_loops(result)
            np.testing.assert_allclose(mapper.graph.poses[-1][:2] - newest[:2], moved[:2], atol=1e-12)
            assert tail, "keyframes were added between the solve and the merge"
            for j, relative in enumerate(tail, start=last + 1):
                np.testing.assert_allclose(mapper.graph.relative(last, j), relative, atol=1e-9)
            moved_tails += 1
            in_flight.remove((solved_at, result))
        search = mapper.loop_search(keyframe.index)
        matches = search.run(mapper.settings) if search is not None else []
        if matches:
            in_flight.append((keyframe.index, solve_loops(mapper.graph.copy(), matches)))
    assert moved_tails >= 1 and len(mapper.loop_closures) >= 1
    errors = keyframe_errors(mapper, truth)
    assert np.sqrt(np.mean(errors ** 2)) < 0.05 and errors.max() < 0.1
    assert len(mapper.loop_closures) == mapper.graph.loop_closures
    # A solution for another map (one reset since, say) is refused.
    with pytest.raises(MapperError, match="does not belong to this map"):
        Mapper().merge_loops(LoopSolution(mapper.graph, [object()], 0, frozenset(), ()))  # type: ignore[list-item]


def jumped_run(jump: bool) -> tuple[Mapper, np.ndarray]:
    """The ring without loop closing; with ``jump``, a collision at scan 60 turns the robot
    0.8 rad and shifts it 0.3 m unseen by odometry (the usual window is ±0.35 rad)."""
    truth = ring_path()
    odom = drifting_odometry(truth, yaw_per_m=0.0, scale=1.0)
    if jump:
        unseen = se2_compose(se2_compose(odom[60], [0.2, -0.2, 0.8]), se2_inverse(odom[60]))
        odom[60:] = [se2_compose(unseen, pose) for pose in odom[60:]]
    mapper = Mapper(MapperSettings(do_loop_closing=False))
    feed(mapper, RING, truth, odom)
    return mapper, keyframe_errors(mapper, truth)


def test_a_jump_in_odometry_beyond_the_search_window_is_recovered(monkeypatch):
    _, smooth = jumped_run(jump=False)
    mapper, errors = jumped_run(jump=True)
    assert mapper.recoveries >= 1
    assert errors.max() < smooth.max() + 0.02, (errors.max(), smooth.max())
    # Without the wider search the scan is placed inside the usual window: far off.
    monkeypatch.setattr("pppbot_slam.mapper.RECOVERY_RESPONSE", 0.0)
    _, unrecovered = jumped_run(jump=True)
    assert unrecovered.max() > 0.2


def test_without_loop_closing_nothing_is_closed():
    mapper, truth = run(MapperSettings(do_loop_closing=False))
    assert mapper.loop_closures == [] and mapper.graph.loop_closures == 0


def test_bad_settings_name_the_value():
    with pytest.raises(MapperError, match="minimum_travel_distance must be a number >= 0, not -1"):
        MapperSettings(minimum_travel_distance=-1)
    with pytest.raises(MapperError, match="loop_match_minimum_response_fine must be in \\[0, 1\\], not 2"):
        MapperSettings(loop_match_minimum_response_fine=2)
