"""Online asynchronous mapping: one :class:`~pppbot_slam.mapper.Mapper` worked on by three threads.

slam_toolbox's "async" mode, without ROS (the ``slam`` node adapts messages and time):

* scan processing: each scan (with its odometry) is matched against the running buffer
  and may become a keyframe; scans never wait for a loop search or a map build;
* loop closing: each new keyframe's loop search, matched and solved on a copy of the
  graph outside the lock, then merged (a mapper replaced meanwhile, by a reset or a
  loaded graph, is left alone);
* map building: the grid from the keyframes' current poses, on request.

The queues are bounded: when one is full the oldest item goes (a later scan or keyframe
covers the same ground) and :attr:`AsyncMapperEvents.warn` says so.

Every piece of work takes a hold when it is queued and releases it when done, dropped or
failed: ``hold`` is given by the caller (the node passes lockstep's, so a simulation step
is answered only once its scan is processed, its loop search merged and its map built).
"""
from __future__ import annotations

import queue
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from pppbot_common.maps import OccupancyGrid
from pppbot_slam.loops import LoopMatch, solve_loops
from pppbot_slam.mapper import Mapper
from pppbot_slam.occupancy import GridCache, LogOddsGrid, ScanRays

#: Scans (with their odometry) waiting for the processing thread; beyond this the oldest goes.
MAX_QUEUED = 200
#: Keyframes waiting for their loop search; beyond this the oldest goes (a later keyframe
#: searches the same places).
MAX_LOOP_QUEUED = 50
#: How long :meth:`AsyncMapper.stop` waits for each thread.
JOIN_TIMEOUT_S = 3.0

Release = Callable[[], None]


def _no_hold() -> Release:
    return lambda: None


@dataclass(frozen=True)
class ScanInput:
    """One scan with what the mapper needs: its time, its frame, the odometry pose at its stamp
    and the sensor's pose on the robot. ``tag`` travels to :class:`KeyframeAdded` untouched
    (the node's message stamp)."""

    stamp_s: float
    frame: str
    odom_pose: np.ndarray
    sensor: np.ndarray
    rays: ScanRays
    tag: Any = None


@dataclass(frozen=True)
class KeyframeAdded:
    """A scan became keyframe ``index``; ``lost`` is the mapper's state after it, ``lost_changed``
    whether that changed, ``recovered`` whether it was found by a search over every heading."""

    index: int
    stamp_s: float
    pose: np.ndarray
    response: float
    recovered: bool
    lost: bool
    lost_changed: bool
    required_response: float
    tag: Any


@dataclass(frozen=True)
class LoopsMerged:
    """Keyframe ``index``'s loop search, solved and merged: the closures accepted, how far the
    newest keyframe moved (dx, dy, dyaw), the matches rejected (``see_through`` of them because
    their scans saw through each other's walls) and the earlier closures undone."""

    index: int
    stamp_s: float
    accepted: list[LoopMatch]
    moved: np.ndarray
    rejected: int
    see_through: int
    undone: list[tuple[int, int]]


def _ignore(*_args: Any) -> None:
    return None


@dataclass
class AsyncMapperEvents:
    """What the threads report, called from the thread that did the work."""

    keyframe: Callable[[KeyframeAdded], None] = _ignore
    loops: Callable[[LoopsMerged], None] = _ignore
    #: a map was built (the map thread; publish it there)
    map_built: Callable[[OccupancyGrid], None] = _ignore
    #: (kind, text): something went wrong or fell behind; throttle per kind
    warn: Callable[[str, str], None] = _ignore


class AsyncMapper:
    """A mapper and its three threads. Call :meth:`start` once and :meth:`stop` at the end."""

    def __init__(self, mapper: Mapper, events: AsyncMapperEvents | None = None,
                 hold: Callable[[], Release] = _no_hold, map_frame: str = "map") -> None:
        mapper.defer_loops = True  # the loop thread closes loops, not process()
        self._mapper = mapper
        self.events = events or AsyncMapperEvents()
        self.hold = hold
        self.map_frame = map_frame
        self.lock = threading.Lock()  # the mapper: scans write it, the loop and map threads read it
        self._scan_frame: str | None = None
        # Work for the scan and loop threads, each item with its hold's release; None stops a thread.
        self._scans: queue.Queue[tuple[Release, ScanInput] | None] = queue.Queue(maxsize=MAX_QUEUED)
        self._loops: queue.Queue[tuple[Release, Mapper, int] | None] = queue.Queue(maxsize=MAX_LOOP_QUEUED)
        self._map_wake = threading.Event()
        self._map_holds: list[Release] = []
        self._map_lock = threading.Lock()
        self._grid = GridCache()  # the map so far: each update draws only the new keyframes
        self._grid_lock = threading.Lock()  # the kept grid: one build_map at a time
        self._stopping = threading.Event()
        self._threads = [
            threading.Thread(target=self._serve, args=(self._scans, self.process, "process",
                                                       "a scan could not be processed"),
                             name="scan-processing", daemon=True),
            threading.Thread(target=self._serve, args=(self._loops, self.close_loops, "loops",
                                                       "a loop search failed"),
                             name="loop-closing", daemon=True),
            threading.Thread(target=self._map_loop, name="map-builder", daemon=True)]

    # ------------------------------------------------------------ lifecycle
    def start(self) -> None:
        for thread in self._threads:
            thread.start()

    def stop(self) -> None:
        """End the threads (work still queued is dropped, its holds released); idempotent."""
        self._stopping.set()
        self._map_wake.set()
        put_dropping_oldest(self._scans, None)
        put_dropping_oldest(self._loops, None)
        for thread in self._threads:
            if thread.is_alive():
                thread.join(timeout=JOIN_TIMEOUT_S)
        for work in (self._scans, self._loops):
            release_queued(work)
        with self._map_lock:
            releases, self._map_holds = self._map_holds, []
        for release in releases:
            release()

    # -------------------------------------------------------------- the map
    @property
    def mapper(self) -> Mapper:
        return self._mapper

    def replace(self, mapper: Mapper) -> None:
        """Map on with ``mapper`` (a reset or a loaded pose graph); it keeps the sensor's pose.
        Loop searches of the old one are dropped."""
        mapper.defer_loops = True
        with self.lock:
            mapper.sensor_offset = self._mapper.sensor_offset
            self._mapper = mapper
        self.request_map()

    def read(self, what: Callable[[Mapper], Any]) -> Any:
        """``what(mapper)`` under the lock: a consistent reading while the threads work."""
        with self.lock:
            return what(self._mapper)

    # --------------------------------------------------------------- scans
    def add_scan(self, scan: ScanInput) -> None:
        """Queue a scan for the processing thread."""
        if put_dropping_oldest(self._scans, (self.hold(), scan)):
            self.events.warn("behind", f"scan processing is {MAX_QUEUED} scans behind: dropping the oldest")

    def clear_queue(self) -> int:
        """Drop the scans waiting for the processing thread (slam_toolbox's ``clear_queue``);
        their holds are released. Returns how many went."""
        return clear_queued(self._scans)

    def process(self, scan: ScanInput) -> KeyframeAdded | None:
        """Match one scan (the processing thread does this for each queued scan)."""
        with self.lock:
            mapper = self._mapper
            if self._scan_frame != scan.frame or not np.allclose(mapper.sensor_offset, scan.sensor):
                mapper.sensor_offset = scan.sensor
                self._scan_frame = scan.frame
            recoveries, was_lost = mapper.recoveries, mapper.lost
            keyframe = mapper.process(scan.stamp_s, scan.odom_pose, scan.rays)
            if keyframe is None:
                return None
            added = KeyframeAdded(
                index=keyframe.index, stamp_s=scan.stamp_s, pose=mapper.predict(scan.odom_pose),
                response=mapper.last_response, recovered=mapper.recoveries > recoveries, lost=mapper.lost,
                lost_changed=mapper.lost != was_lost,
                required_response=mapper.settings.link_match_minimum_response_fine, tag=scan.tag)
        self.events.keyframe(added)
        if added.index == 0:
            self.request_map()  # a first map at once
        if mapper.settings.do_loop_closing and put_dropping_oldest(self._loops,
                                                                    (self.hold(), mapper, added.index)):
            self.events.warn("loops behind", f"loop closing is {MAX_LOOP_QUEUED} keyframes behind: the oldest "
                                             "keyframe's search is skipped")
        return added

    # ---------------------------------------------------------- loop closure
    def close_loops(self, mapper: Mapper, index: int) -> LoopsMerged | None:
        """Keyframe ``index``'s loop search: taken from the mapper under the lock, matched and
        solved outside it (scans go on), merged under it. Nothing when ``mapper`` has been
        replaced meanwhile or nothing matched."""
        with self.lock:
            if mapper is not self._mapper:
                return None
            search = mapper.loop_search(index)
        matches = search.run(mapper.settings) if search is not None else []
        if not matches:
            return None
        with self.lock:
            if mapper is not self._mapper:
                return None
            graph = mapper.graph.copy()
        solution = solve_loops(graph, matches)
        with self.lock:
            if mapper is not self._mapper:
                return None
            moved = mapper.merge_loops(solution)
            stamp = mapper.keyframes[index].stamp_s
        merged = LoopsMerged(
            index=index, stamp_s=stamp, accepted=list(solution.accepted), moved=moved, rejected=solution.rejected,
            see_through=solution.why.get("see_through", 0),
            undone=sorted(solution.undone))
        self.events.loops(merged)
        return merged

    # ------------------------------------------------------------------ maps
    def request_map(self) -> None:
        """A map build by the map thread (reported through ``events.map_built``)."""
        with self._map_lock:
            self._map_holds.append(self.hold())
        self._map_wake.set()

    def build_map(self, exact: bool = False) -> OccupancyGrid | None:
        """The grid from the keyframes' current poses, built outside the lock (scans go on);
        None before the first keyframe. Only keyframes new since the last build are drawn; a
        redraw at the keyframes' poses replaces the grid once a correction moved a drawn one by
        over half a cell (over several builds for a large map), a keyframe left the map, or the
        mapper was replaced (:class:`GridCache`). ``exact``: built anew from every keyframe at
        its pose now, leaving the kept grid alone (a saved map)."""
        with self.lock:
            if not self._mapper.keyframes:
                return None
            inputs = self._mapper.grid_inputs()
        if exact:
            return LogOddsGrid.build(*inputs).to_occupancy_grid(self.map_frame)
        with self._grid_lock:
            return self._grid.update(*inputs).to_occupancy_grid(self.map_frame)

    @property
    def map_rebuilds(self) -> int:
        """Maps redrawn from every keyframe so far (the other updates drew only new keyframes)."""
        return self._grid.rebuilds

    @property
    def map_stale_keyframes(self) -> int:
        """Keyframes the last map drew over half a cell from their pose at that build, until
        the redraw under way replaces it (:class:`GridCache`)."""
        return self._grid.stale

    def _map_loop(self) -> None:
        while not self._stopping.is_set():
            self._map_wake.wait()
            self._map_wake.clear()
            with self._map_lock:
                releases, self._map_holds = self._map_holds, []
            try:
                grid = None if self._stopping.is_set() else self.build_map()
                if grid is not None:
                    self.events.map_built(grid)
            except Exception as exc:  # noqa: BLE001 - a failed build must not stop the map thread
                self.events.warn("map", f"the map could not be built: {type(exc).__name__}: {exc}")
            finally:
                for release in releases:
                    release()

    # --------------------------------------------------------------- threads
    def _serve(self, work: queue.Queue[Any], handle: Callable[..., Any], kind: str, failure: str) -> None:
        """A thread's loop: ``handle`` each item of ``work`` until the stop sign; one that fails
        is warned about (``failure``, per ``kind``) and the thread goes on. The item's hold is
        released when it is done."""
        while True:
            item = work.get()
            if item is None or self._stopping.is_set():
                if item is not None:
                    item[0]()
                return
            release, *args = item
            try:
                handle(*args)
            except Exception as exc:  # noqa: BLE001 - one bad scan or search must not stop the thread
                self.events.warn(kind, f"{failure}: {type(exc).__name__}: {exc}")
            finally:
                release()


def put_dropping_oldest(work: queue.Queue[Any], item: Any) -> bool:
    """Put ``item``, first dropping the oldest entries while ``work`` is full (releasing the hold
    each carries); whether any went."""
    dropped = False
    while True:
        try:
            work.put_nowait(item)
            return dropped
        except queue.Full:
            try:
                old = work.get_nowait()
                dropped = True
                if old is not None:
                    old[0]()
            except queue.Empty:
                pass


def clear_queued(work: queue.Queue[Any]) -> int:
    """Drop the items waiting in ``work`` (each a tuple whose first element releases its hold), keeping
    a stop sign (None) if one is there; returns how many went."""
    dropped, stop = 0, False
    while True:
        try:
            item = work.get_nowait()
        except queue.Empty:
            break
        if item is None:
            stop = True
            continue
        item[0]()
        dropped += 1
    if stop:
        put_dropping_oldest(work, None)
    return dropped


def release_queued(work: queue.Queue[Any]) -> None:
    """Release the holds of whatever is left in ``work``."""
    while True:
        try:
            item = work.get_nowait()
        except queue.Empty:
            return
        if item is not None:
            item[0]()
