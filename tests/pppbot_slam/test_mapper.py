"""The mapper on a synthetic ring corridor: keyframes by travel, drift corrected, loops closed, a clean map."""
from __future__ import annotations

import math

import numpy as np
import pytest

from pppbot_common.maps import OCCUPIED
from pppbot_common.se2 import se2_compose, se2_inverse
from pppbot_slam.mapper import Mapper, MapperError, MapperSettings
from pppbot_slam.occupancy import ScanRays
from slam_synthetic import beam_angles, box, cast_ranges, wall_points

# A ring corridor 2 m wide around a 6 × 4 m block, with pillars so that the straight parts
# are not featureless.
PILLARS = [box(x - 0.15, y - 0.15, x + 0.15, y + 0.15) for x, y in
           [(-1.5, -3.6), (2.0, -3.6), (4.6, 0.5), (0.5, 3.6), (-2.5, 3.6), (-4.6, -1.0)]]
WORLD = np.vstack([box(-5, -4, 5, 4), box(-3, -2, 3, 2), *PILLARS])


def ring_path(step_m: float = 0.1, overlap_m: float = 4.0) -> np.ndarray:
    """Around the block counter-clockwise from (0, −3), and on past the start by ``overlap_m``."""
    corners = np.array([[0, -3], [4, -3], [4, 3], [-4, 3], [-4, -3], [0, -3], [overlap_m, -3]], dtype=float)
    poses = []
    for a, b in zip(corners[:-1], corners[1:]):
        yaw = math.atan2(*(b - a)[::-1])
        n = int(round(np.linalg.norm(b - a) / step_m))
        poses += [(*(a + (b - a) * k / n), yaw) for k in range(n)]
    return np.array(poses)


def drifting_odometry(truth: np.ndarray, yaw_per_m: float, scale: float) -> np.ndarray:
    odom = [truth[0].copy()]
    for prev, cur in zip(truth[:-1], truth[1:]):
        step = se2_compose(se2_inverse(prev), cur)
        moved = math.hypot(step[0], step[1])
        odom.append(se2_compose(odom[-1], [step[0] * scale, step[1] * scale, step[2] + yaw_per_m * moved]))
    return np.array(odom)


def run(settings: MapperSettings) -> tuple[Mapper, np.ndarray]:
    truth = ring_path()
    odom = drifting_odometry(truth, yaw_per_m=0.01, scale=1.01)
    mapper = Mapper(settings)
    angles = beam_angles()
    for k, (pose, odom_pose) in enumerate(zip(truth, odom)):
        rays = ScanRays.from_laser(float(angles[0]), float(angles[1] - angles[0]),
                                   cast_ranges(WORLD, pose, noise=0.01, seed=k), 0.08, 20.0)
        mapper.process(0.1 * k, odom_pose, rays)
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
    walls = wall_points(WORLD, 0.01)
    distance = np.min(np.linalg.norm(centres[:, None, :] - walls[None, ::4, :], axis=2), axis=1)
    # Every occupied cell lies on a wall (within a cell and a half): no ghost walls.
    assert np.quantile(distance, 0.99) < 0.075


def test_without_loop_closing_nothing_is_closed():
    mapper, truth = run(MapperSettings(do_loop_closing=False))
    assert mapper.loop_closures == [] and mapper.graph.loop_closures == 0


def test_bad_settings_name_the_value():
    with pytest.raises(MapperError, match="minimum_travel_distance must be a number >= 0, not -1"):
        MapperSettings(minimum_travel_distance=-1)
    with pytest.raises(MapperError, match="loop_match_minimum_response_fine must be in \\[0, 1\\], not 2"):
        MapperSettings(loop_match_minimum_response_fine=2)
