"""The asynchronous mapper without ROS: its threads map the ring corridor and close its loop, every
piece of work holds until done (or dropped, or failed), a full queue drops the oldest, a failure
is warned about and the threads go on, a replaced mapper's loop search is left alone."""
from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from slam_synthetic import RING, drifting_odometry, ring_path, scan_rays

from pppbot_common.se2 import se2_compose
from pppbot_slam import async_mapper
from pppbot_slam.async_mapper import AsyncMapper, AsyncMapperEvents, KeyframeAdded, LoopsMerged, ScanInput
from pppbot_slam.mapper import Mapper, MapperSettings
from pppbot_slam.occupancy import LogOddsGrid

SENSOR = np.array([0.1, 0.0, 0.0])


class Holds:
    """A counting stand-in for lockstep's hold: how many pieces of work are outstanding."""

    def __init__(self) -> None:
        self.taken = self.released = self.twice = 0
        self.lock = threading.Lock()

    def __call__(self):
        with self.lock:
            self.taken += 1
        done = False

        def release() -> None:
            nonlocal done
            with self.lock:
                self.twice += done
                self.released += not done
            done = True
        return release

    @property
    def outstanding(self) -> int:
        with self.lock:
            return self.taken - self.released

    def wait_until(self, most: int, timeout_s: float = 120.0) -> None:
        deadline = time.monotonic() + timeout_s
        while self.outstanding > most:
            assert time.monotonic() < deadline, f"{self.outstanding} pieces of work still held"
            time.sleep(0.005)


class Recorded(AsyncMapperEvents):
    def __init__(self) -> None:
        self.keyframes: list[KeyframeAdded] = []
        self.merged: list[LoopsMerged] = []
        self.maps: list[int] = []  # occupied cells of each map built
        self.last_map = None
        self.warnings: list[tuple[str, str]] = []
        super().__init__(keyframe=self.keyframes.append, loops=self.merged.append, map_built=self.map_built,
                         warn=lambda kind, text: self.warnings.append((kind, text)))

    def map_built(self, grid) -> None:
        self.maps.append(int((grid.data == 100).sum()))
        self.last_map = grid


def scan(k: int, truth: np.ndarray, odom: np.ndarray) -> ScanInput:
    """Scan k of the ring, cast from the lidar (mounted at SENSOR on the robot)."""
    rays = scan_rays(RING, se2_compose(truth[k], SENSOR), seed=k)
    return ScanInput(0.1 * k, "lidar_link", odom[k], SENSOR, rays, tag=("stamp", k))


@pytest.fixture
def started():
    made: list[AsyncMapper] = []

    def make(mapper: Mapper | None = None) -> tuple[AsyncMapper, Recorded, Holds]:
        events, holds = Recorded(), Holds()
        mapping = AsyncMapper(mapper or Mapper(MapperSettings()), events, hold=holds)
        mapping.start()
        made.append(mapping)
        return mapping, events, holds
    yield make
    for mapping in made:
        mapping.stop()


def test_the_threads_map_the_ring_and_close_its_loop(started):
    truth = ring_path()
    odom = drifting_odometry(truth, yaw_per_m=0.01, scale=1.01)
    mapping, events, holds = started()
    for k in range(len(truth)):
        mapping.add_scan(scan(k, truth, odom))
        if k % 20 == 19:
            mapping.request_map()  # as the node's map_update_interval does
        holds.wait_until(50)  # within the queue's bound: no scan dropped
    holds.wait_until(0)
    assert holds.twice == 0 and events.warnings == []
    mapper = mapping.mapper
    assert [k.index for k in events.keyframes] == list(range(len(mapper.keyframes)))
    assert len(mapper.keyframes) > 30
    first = events.keyframes[0]
    assert first.tag == ("stamp", 0) and not first.lost and not first.lost_changed
    np.testing.assert_allclose(mapper.sensor_offset, SENSOR)
    # The first keyframe asked for a map at once.
    assert events.maps and events.maps[0] > 0
    # The loop thread closed the ring: merged reports and closures in the graph, drift corrected.
    assert events.merged and sum(len(m.accepted) for m in events.merged) >= 1
    assert len(mapper.loop_closures) >= 1
    stamps = np.array([k.stamp_s for k in mapper.keyframes])
    errors = np.linalg.norm(np.array(mapper.graph.poses)[:, :2] - truth[np.round(stamps / 0.1).astype(int), :2], axis=1)
    assert np.sqrt(np.mean(errors ** 2)) < 0.05 and errors.max() < 0.1
    # A map on request from the corrected poses. Updates drew only the keyframes new since the one
    # before, unless the loop's correction moved a drawn scan over half a cell: a rebuild's map to
    # a cell (the correction here was about 1 cm).
    for _ in range(3):
        before = len(events.maps)
        mapping.add_scan(scan(len(truth) - 1, truth, odom))  # standing still: no keyframe, no new pose
        mapping.request_map()
        holds.wait_until(0)
        assert len(events.maps) == before + 1
    assert 1 <= mapping.map_rebuilds <= len(events.maps) - 3  # standing still redraws nothing
    assert mapping.map_stale_keyframes == 0  # a small map's redraws are never put off
    rebuilt = mapper.grid()
    assert events.last_map.origin == rebuilt.origin and events.last_map.data.shape == rebuilt.data.shape
    assert np.mean(events.last_map.data == rebuilt.data) > 0.98
    kept, walls = np.argwhere(events.last_map.data == 100), np.argwhere(rebuilt.data == 100)
    assert np.abs(kept[:, None, :] - walls[None, :, :]).max(axis=2).min(axis=1).max() <= 1
    # What a save gets: built anew at the poses now, the kept grid left as it was.
    rebuilds = mapping.map_rebuilds
    exact = mapping.build_map(exact=True)
    np.testing.assert_array_equal(exact.data, rebuilt.data)
    assert mapping.map_rebuilds == rebuilds


def test_a_failing_scan_is_warned_about_and_the_thread_goes_on(started, monkeypatch):
    truth = ring_path()
    mapping, events, holds = started()
    real = Mapper.process
    calls = []

    def flaky(self, *args):
        calls.append(1)
        if len(calls) == 1:
            raise RuntimeError("boom")
        return real(self, *args)
    monkeypatch.setattr(Mapper, "process", flaky)
    mapping.add_scan(scan(0, truth, truth))
    mapping.add_scan(scan(1, truth, truth))
    holds.wait_until(0)
    assert events.warnings == [("process", "a scan could not be processed: RuntimeError: boom")]
    assert [k.index for k in events.keyframes] == [0] and events.keyframes[0].tag == ("stamp", 1)
    assert holds.twice == 0


def test_a_failed_map_build_is_warned_about_and_releases_its_hold(started, monkeypatch):
    truth = ring_path()
    mapping, events, holds = started()
    mapping.request_map()  # no keyframe yet: no map, the hold released all the same
    holds.wait_until(0)
    assert events.maps == []

    def broken(*args):
        raise MemoryError("no room")
    monkeypatch.setattr(LogOddsGrid, "build", broken)
    mapping.add_scan(scan(0, truth, truth))
    holds.wait_until(0)
    assert events.keyframes and events.maps == []
    assert ("map", "the map could not be built: MemoryError: no room") in events.warnings
    monkeypatch.undo()
    mapping.request_map()  # the map thread is still there
    holds.wait_until(0)
    assert len(events.maps) == 1


def test_a_full_queue_drops_the_oldest_scan_and_releases_its_hold(monkeypatch):
    monkeypatch.setattr(async_mapper, "MAX_QUEUED", 3)
    truth = ring_path()
    events, holds = Recorded(), Holds()
    mapping = AsyncMapper(Mapper(MapperSettings()), events, hold=holds)  # not started: nothing is taken off
    for k in range(4):
        mapping.add_scan(scan(k, truth, truth))
    assert holds.taken == 4 and holds.outstanding == 3
    assert events.warnings == [("behind", "scan processing is 3 scans behind: dropping the oldest")]
    mapping.stop()  # what was left is dropped, its holds released
    assert holds.outstanding == 0 and holds.twice == 0


def test_a_replaced_mappers_loop_search_is_left_alone_and_the_new_one_keeps_the_sensor():
    truth = ring_path()
    events, holds = Recorded(), Holds()
    old = Mapper(MapperSettings())
    mapping = AsyncMapper(old, events, hold=holds)
    for k in range(0, len(truth), 3):
        mapping.process(scan(k, truth, truth))  # as the scan thread does, in this thread
    assert len(old.keyframes) > 30
    fresh = Mapper(MapperSettings())
    mapping.replace(fresh)
    assert mapping.mapper is fresh and fresh.defer_loops
    np.testing.assert_allclose(fresh.sensor_offset, SENSOR)
    poses = np.array(old.graph.poses).copy()
    assert mapping.close_loops(old, len(old.keyframes) - 1) is None
    np.testing.assert_array_equal(np.array(old.graph.poses), poses)
    assert fresh.keyframes == [] and events.merged == []
    mapping.stop()
    assert holds.outstanding == 0  # the loop searches queued and the map asked for, released unrun


def test_stop_is_idempotent_and_ends_the_threads(started):
    mapping, _, _ = started()
    assert [t.name for t in mapping._threads if t.is_alive()] == ["scan-processing", "loop-closing", "map-builder"]
    mapping.stop()
    mapping.stop()
    assert not any(t.is_alive() for t in mapping._threads)
