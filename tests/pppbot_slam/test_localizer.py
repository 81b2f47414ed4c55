"""Localization in a saved pose graph (slam_toolbox's localization mode), without ROS.

A ring corridor is mapped once (the module's fixture), serialized and loaded back; each test then
localizes a drive in it that the mapping run never took."""
from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from slam_synthetic import RING, ROOM, drifting_odometry, ring_path, scan_rays

from pppbot_common.errors import ParameterError
from pppbot_common.se2 import se2_compose, se2_inverse, wrap_angles
from pppbot_slam.async_localizer import AsyncLocalizer, LocalizerEvents
from pppbot_slam.async_mapper import ScanInput
from pppbot_slam.errors import LocalizerError
from pppbot_slam.localizer import BUFFER_RESPONSE, LocalizedPose, Localizer
from pppbot_slam.mapper import LOST_KEYFRAMES, Mapper, MapperSettings
from pppbot_slam.occupancy import ScanRays
from pppbot_slam.ros.slam import SlamParameters
from pppbot_slam.serialization import load_posegraph, posegraph_path, save_posegraph

#: The localized drive: the ring 0.4 m off the mapped centre line, odometry drifting 1 % in scale
#: and 0.01 rad per metre, in an odometry frame that starts at the drive's start.
OFFSET = np.array([0.0, 0.4, 0.0])


@pytest.fixture(scope="module")
def graph_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    mapper = Mapper(MapperSettings())
    for k, pose in enumerate(ring_path(0.1, 4.0)):
        mapper.process(0.1 * k, pose, scan_rays(RING, pose, seed=k))
    return save_posegraph(mapper, tmp_path_factory.mktemp("localizer") / "ring")


def drive(steps: int = 300) -> tuple[np.ndarray, np.ndarray]:
    """The drive's true map poses and its odometry (frame at its start), one every 0.1 m."""
    truth = (ring_path(0.1, 4.0) + OFFSET)[:steps]
    odom = drifting_odometry(truth, 0.01, 1.01)
    return truth, np.array([se2_compose(se2_inverse(odom[0]), o) for o in odom])


def localize(localizer: Localizer, truth: np.ndarray, odom: np.ndarray,
             first: int = 0) -> list[tuple[int, LocalizedPose]]:
    taken = []
    for k in range(first, len(truth)):
        localized = localizer.process(0.1 * k, odom[k], scan_rays(RING, truth[k], seed=1000 + k), np.zeros(3))
        if localized is not None:
            taken.append((k, localized))
    return taken


def error(pose: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    return float(np.hypot(*(pose[:2] - truth[:2]))), abs(float(wrap_angles(pose[2] - truth[2])))


def test_a_drive_off_the_mapped_path_is_localized_within_a_few_cm_and_a_degree(graph_file: Path):
    truth, odom = drive()
    localizer = Localizer(load_posegraph(graph_file), truth[0] + [0.1, -0.1, 0.05])
    taken = localize(localizer, truth, odom)
    errors = np.array([error(localized.pose, truth[k]) for k, localized in taken])
    assert len(taken) >= 55 and all(localized.matched for _, localized in taken)
    assert errors[:, 0].max() < 0.03 and errors[:, 1].max() < math.radians(1.0)
    # map → odom carries the odometry pose of the last scan to its map pose
    k, last = taken[-1]
    map_to_odom = localizer.map_to_odom()
    assert map_to_odom is not None
    np.testing.assert_allclose(se2_compose(map_to_odom, odom[k]), last.pose, atol=1e-9)


def test_the_saved_graph_is_not_grown_and_the_buffer_keeps_the_last_scans(graph_file: Path):
    before = posegraph_path(graph_file).read_bytes()
    graph = load_posegraph(graph_file)
    keyframes, poses, edges = len(graph.keyframes), np.array(graph.graph.poses), len(graph.graph.edges)
    truth, odom = drive(200)
    localizer = Localizer(graph, truth[0])
    taken = localize(localizer, truth, odom)
    assert len(graph.keyframes) == keyframes and len(graph.graph.edges) == edges
    np.testing.assert_array_equal(np.array(graph.graph.poses), poses)
    size = graph.settings.scan_buffer_size
    assert len(localizer.buffer) == size < len(taken)
    assert [b.stamp_s for b in localizer.buffer] == [localized.stamp_s for _, localized in taken[-size:]]
    assert posegraph_path(graph_file).read_bytes() == before


def test_a_scan_is_taken_only_after_minimum_travel(graph_file: Path):
    truth, odom = drive(60)
    taken = localize(Localizer(load_posegraph(graph_file), truth[0]), truth, odom)
    steps = [k for k, _ in taken]
    # the first at once, then every 0.5 m (minimum_travel_distance), 0.1 m a step
    assert steps[0] == 0 and all(4 <= b - a <= 6 for a, b in zip(steps[:-1], steps[1:], strict=True))


@pytest.mark.parametrize("guess", [[0.2, -0.2, 0.2], [0.5, 0.2, -0.6]])
def test_the_first_scan_is_found_from_a_rough_start_pose(graph_file: Path, guess: list[float]):
    truth, odom = drive(1)
    _, first = localize(Localizer(load_posegraph(graph_file), truth[0] + guess), truth, odom)[0]
    assert first.relocalized and first.matched
    position, heading = error(first.pose, truth[0])
    assert position < 0.02 and heading < math.radians(0.5)


def test_a_given_pose_relocalizes_the_next_scan_and_clears_the_buffer(graph_file: Path):
    truth, odom = drive(150)
    localizer = Localizer(load_posegraph(graph_file), truth[0])
    localize(localizer, truth[:100], odom[:100])
    assert localizer.buffer
    # the robot was carried: odometry says it is where it was, the map says 2 m on
    kidnapped = truth[120]
    localizer.relocalize(kidnapped + [0.1, 0.1, -0.1])
    assert not localizer.buffer
    localized = localizer.process(20.0, odom[99], scan_rays(RING, kidnapped, seed=7), np.zeros(3))
    assert localized is not None and localized.relocalized and localized.matched
    position, heading = error(localized.pose, kidnapped)
    assert position < 0.02 and heading < math.radians(0.5)


def test_scans_that_match_nothing_follow_odometry_and_make_it_lost():
    # The box room, mapped along its middle; then clutter half a metre around the lidar, in the open
    # middle of the room (nothing of the map within reach of any fit), while odometry turns on the spot.
    mapper = Mapper(MapperSettings())
    for k, x in enumerate(np.linspace(-1.0, 1.0, 21)):
        mapper.process(0.1 * k, [x, 0.0, 0.0], scan_rays(ROOM, np.array([x, 0.0, 0.0]), seed=k))
    localizer = Localizer(mapper, [0.0, -0.3, 0.0])
    first = localizer.process(0.0, np.zeros(3), scan_rays(ROOM, np.array([0.0, -0.3, 0.0]), seed=1))
    assert first is not None and first.matched
    clutter = np.random.default_rng(0)
    angles = np.linspace(-math.pi, math.pi, 640, endpoint=False)
    results = []
    for k in range(1, LOST_KEYFRAMES + 2):
        rays = ScanRays.from_laser(float(angles[0]), float(angles[1] - angles[0]),
                                   clutter.uniform(0.3, 0.5, 640), 0.08, 20.0)
        odom = np.array([0.0, 0.0, 0.6 * k])
        predicted = localizer.predict(odom)
        localized = localizer.process(0.5 * k, odom, rays)
        assert localized is not None and predicted is not None
        np.testing.assert_allclose(localized.pose, predicted)  # placed by odometry
        results.append(localized)
    assert not any(r.matched for r in results) and len(localizer.buffer) == 1  # the first scan only
    assert [r.lost for r in results] == [False] * (LOST_KEYFRAMES - 1) + [True, True]
    assert results[LOST_KEYFRAMES - 1].lost_changed and localizer.health()["lost"]
    # the room's walls again: found, as well as a loop closure must match
    turned = np.array([0.0, -0.3, 0.6 * (LOST_KEYFRAMES + 2)])
    found = localizer.process(9.0, [0.0, 0.0, turned[2]], scan_rays(ROOM, turned, seed=3))
    assert found is not None and found.matched and found.lost_changed and not found.lost
    assert found.required_response == localizer.settings.loop_match_minimum_response_fine
    assert error(found.pose, turned)[0] < 0.02


def test_scans_that_fit_the_map_only_just_stay_out_of_the_buffer(graph_file: Path):
    # Random clutter around the lidar in the ring corridor fits some wall at about 0.2 (above
    # link_match_minimum_response_fine): it is taken, but kept out of the rolling buffer, so the next
    # clutter scans are matched against the map alone and fit no better (buffered, they fit each other
    # at 0.42-0.47).
    truth, odom = drive(40)
    localizer = Localizer(load_posegraph(graph_file), truth[0])
    localize(localizer, truth[:1], odom[:1])
    clutter = np.random.default_rng(0)
    angles = np.linspace(-math.pi, math.pi, 640, endpoint=False)
    responses = []
    for k in range(5, 40, 5):
        rays = ScanRays.from_laser(float(angles[0]), float(angles[1] - angles[0]),
                                   clutter.uniform(0.3, 0.5, 640), 0.08, 20.0)
        localized = localizer.process(0.1 * k, odom[k], rays, np.zeros(3))
        assert localized is not None
        responses.append(localized.response)
    assert len(localizer.buffer) == 1  # the first, real scan
    assert max(responses) < BUFFER_RESPONSE - 0.2


def test_localization_needs_a_graph_with_keyframes_and_a_finite_start():
    with pytest.raises(LocalizerError, match="no keyframes"):
        Localizer(Mapper())
    mapper = Mapper()
    mapper.process(0.0, np.zeros(3), scan_rays(RING, np.array([0.0, -3.0, 0.0]), seed=0))
    with pytest.raises(LocalizerError, match="the pose to localize at"):
        Localizer(mapper, [0.0, float("nan"), 0.0])
    # without a start pose: the first keyframe (slam_toolbox's dock)
    assert Localizer(mapper).pending is not None
    np.testing.assert_array_equal(Localizer(mapper).pending, mapper.map_pose(0))


def test_the_worker_localizes_queued_scans_and_releases_every_hold(graph_file: Path):
    truth, odom = drive(30)
    held: list[int] = []
    released: list[int] = []

    def hold() -> Callable[[], None]:
        held.append(1)
        return lambda: released.append(1)

    poses: list[tuple[LocalizedPose, object]] = []
    worker = AsyncLocalizer(Localizer(load_posegraph(graph_file), truth[0]),
                            LocalizerEvents(localized=lambda pose, tag: poses.append((pose, tag))), hold=hold)
    scans = [ScanInput(0.1 * k, "lidar", odom[k], np.zeros(3), scan_rays(RING, truth[k], seed=k), tag=k)
             for k in range(len(truth))]
    for scan in scans:  # processed in the caller's thread: the worker is not started
        worker.process(scan)
    assert [tag for _, tag in poses] == [0, 5, 10, 15, 20, 25]
    map_to_odom = worker.map_to_odom
    assert map_to_odom is not None
    np.testing.assert_allclose(se2_compose(map_to_odom, odom[25]), poses[-1][0].pose, atol=1e-9)
    worker.add_scan(scans[29])
    assert worker.clear_queue() == 1 and len(held) == len(released) == 1
    worker.start()
    worker.replace(None)
    assert not worker.loaded and worker.map_to_odom is None and not worker.relocalize(truth[0])
    worker.add_scan(scans[29])
    worker.stop()
    assert len(held) == len(released) == 2


@pytest.mark.parametrize("mode", ["lifelong", "Localization", ""])
def test_modes_other_than_mapping_and_localization_are_refused_by_name(mode: str):
    with pytest.raises(ParameterError, match=f"'mode' = '{mode}': must be 'mapping' or 'localization'"):
        SlamParameters(mode=mode).validate()
