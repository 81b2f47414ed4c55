"""Localization off the executor's thread: one :class:`~pppbot_slam.localizer.Localizer` and its worker.

The ``slam`` node in ``mode: localization`` hands each scan (with its odometry) to a thread of its
own, so TF keeps flowing in and ``map → odom`` out while a scan is matched (tens of milliseconds).
The queue is bounded: when it is full the oldest scan goes (a later one says more about where the
robot is now) and :attr:`LocalizerEvents.warn` says so. Each scan takes a hold when it is queued
and releases it when it is done, dropped or failed (the node passes lockstep's: a simulation step
is answered once its scan is localized). No ROS here.
"""
from __future__ import annotations

import queue
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from pppbot_slam.async_mapper import (
    JOIN_TIMEOUT_S,
    Release,
    ScanInput,
    clear_queued,
    put_dropping_oldest,
    release_queued,
)
from pppbot_slam.localizer import LocalizedPose, Localizer

#: Scans waiting for the worker; beyond this the oldest goes.
MAX_QUEUED = 50


def _no_hold() -> Release:
    return lambda: None


def _ignore(*_args: Any) -> None:
    return None


@dataclass
class LocalizerEvents:
    """What the worker reports, called from its thread: a taken scan's pose with the scan's ``tag``
    (the node's message stamp), and warnings (kind, text; throttle per kind)."""

    localized: Callable[[LocalizedPose, Any], None] = _ignore
    warn: Callable[[str, str], None] = _ignore


class AsyncLocalizer:
    """A localizer (None until a pose graph is loaded) and its worker thread. Call :meth:`start`
    once and :meth:`stop` at the end."""

    def __init__(self, localizer: Localizer | None, events: LocalizerEvents | None = None,
                 hold: Callable[[], Release] = _no_hold) -> None:
        self._localizer = localizer
        self.events = events or LocalizerEvents()
        self.hold = hold
        self.lock = threading.Lock()  # the localizer: the worker writes it, the node reads it
        #: The current map → odom (x, y, yaw; None until a scan is localized), set after each scan: the
        #: node reads it without the lock, so publishing it never waits for a match.
        self.map_to_odom: np.ndarray | None = None if localizer is None else localizer.map_to_odom()
        self._scans: queue.Queue[tuple[Release, ScanInput] | None] = queue.Queue(maxsize=MAX_QUEUED)
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._serve, name="localization", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        """End the worker (scans still queued are dropped, their holds released); idempotent."""
        self._stopping.set()
        put_dropping_oldest(self._scans, None)
        if self._thread.is_alive():
            self._thread.join(timeout=JOIN_TIMEOUT_S)
        release_queued(self._scans)

    # ------------------------------------------------------------ the state
    def replace(self, localizer: Localizer | None) -> None:
        """Localize with ``localizer`` from now on (a pose graph loaded, or None: forgotten); the
        scans waiting are dropped, being meant for the one before."""
        self.clear_queue()
        with self.lock:
            self._localizer = localizer
            self.map_to_odom = None

    @property
    def loaded(self) -> bool:
        """Whether a pose graph is loaded (read without the lock)."""
        return self._localizer is not None

    def read(self, what: Callable[[Localizer], Any], default: Any = None) -> Any:
        """``what(localizer)`` under the lock, or ``default`` while none is loaded."""
        with self.lock:
            return default if self._localizer is None else what(self._localizer)

    def relocalize(self, pose: np.ndarray) -> bool:
        """The next scan is placed at ``pose`` (x, y, yaw in the map) and matched from there; False
        while no pose graph is loaded.

        Raises:
            LocalizerError: not three finite numbers.
        """
        with self.lock:
            if self._localizer is None:
                return False
            self._localizer.relocalize(pose)
            return True

    # ---------------------------------------------------------------- scans
    def add_scan(self, scan: ScanInput) -> None:
        """Queue a scan for the worker."""
        if put_dropping_oldest(self._scans, (self.hold(), scan)):
            self.events.warn("behind", f"localization is {MAX_QUEUED} scans behind: dropping the oldest")

    def clear_queue(self) -> int:
        """Drop the scans waiting for the worker; returns how many went."""
        return clear_queued(self._scans)

    def process(self, scan: ScanInput) -> LocalizedPose | None:
        """Localize one scan (the worker does this for each queued scan); None when it was not taken
        (no pose graph, or odometry has not moved enough)."""
        with self.lock:
            if self._localizer is None:
                return None
            localized = self._localizer.process(scan.stamp_s, scan.odom_pose, scan.rays, scan.sensor)
            self.map_to_odom = self._localizer.map_to_odom()
        if localized is not None:
            self.events.localized(localized, scan.tag)
        return localized

    def _serve(self) -> None:
        while True:
            item = self._scans.get()
            if item is None or self._stopping.is_set():
                if item is not None:
                    item[0]()
                return
            release, scan = item
            try:
                self.process(scan)
            except Exception as exc:  # noqa: BLE001 - one bad scan must not stop localization
                self.events.warn("process", f"a scan could not be localized: {type(exc).__name__}: {exc}")
            finally:
                release()
