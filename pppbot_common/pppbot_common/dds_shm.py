"""Fast DDS's shared-memory files that a dead process left behind, found and removed as
``fastdds shm clean`` does.

Each Fast DDS participant keeps its segments in ``/dev/shm``: ``fastrtps_<id>`` (its own),
``fastrtps_port<N>`` (a port, shared), each with a lock file ``<name>_el`` that every process
using it holds with ``flock`` while it lives, and a semaphore ``sem.<name>_mutex`` for ports.
A process that exits removes what it alone used; one killed (SIGKILL, a segfault, the OOM
killer) cannot, and its files stay until someone cleans them. A lock file nobody holds marks
a segment whose users are all gone.

A process killed between creating a segment's file and sizing it leaves a file of 0 bytes, and
that one is worse than litter: Fast DDS (through Boost.Interprocess) waits for its creator to
size it, forever, so every later participant that picks the same port in that domain hangs in
its creation (a CI run lost six bringups to one such file). A segment file of 0 bytes past the
settling time is stale whoever holds it. No ROS in here: the launch's supervisor and the test
harness use it.
"""
from __future__ import annotations

import contextlib
import fcntl
import os
import time
from pathlib import Path

from pppbot_common.process import open_file_targets

SHM = Path("/dev/shm")
#: A lock file younger than this (s) may belong to a participant still setting up its segment.
SETTLING_S = 2.0
#: Fast DDS's lock files (exclusive, shared): empty by nature, never segments.
LOCK_SUFFIXES = ("_el", "_sl")


def _unheld(lock: Path) -> bool:
    try:
        fd = os.open(lock, os.O_RDWR)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return False  # a living process holds it
    finally:
        os.close(fd)  # (closing releases the lock just taken)
    return True


def _files_of(root: Path, segment: str) -> list[Path]:
    """A segment's files that exist: the segment, its lock file and its semaphore."""
    return [p for p in (root / segment, root / f"{segment}_el", root / f"sem.{segment}_mutex") if p.exists()]


def _open_anywhere(root: Path) -> set[str]:
    """The files under ``root`` that some process has open (every process's descriptors)."""
    prefix = f"{root}/"
    return {target for pid in os.listdir("/proc") if pid.isdigit()
            for target in open_file_targets(int(pid)) if target.startswith(prefix)}


def stale_segments(root: Path = SHM) -> list[Path]:
    """The files of Fast DDS segments nobody uses any more (their lock nobody holds), or that
    were never sized (0 bytes past the settling time, or that no process has open any more):
    segment, lock file and semaphore."""
    stale: set[Path] = set()
    if not root.is_dir():
        return []
    now = time.time()
    young_unsized: list[Path] = []
    for path in root.glob("fastrtps_*"):
        with contextlib.suppress(OSError):
            info = path.stat()
            settled = now - info.st_mtime >= SETTLING_S
            if path.name.endswith(LOCK_SUFFIXES):
                if path.name.endswith("_el") and settled and _unheld(path):
                    stale.update(_files_of(root, path.name.removesuffix("_el")))
            elif info.st_size == 0:
                if settled:
                    stale.update(_files_of(root, path.name))
                else:
                    young_unsized.append(path)
    if young_unsized:
        # Its maker holds it open from the moment it made it: one that no process has open any
        # more lost its maker before the sizing. (A process respawned at once takes the same
        # port, so it cannot wait out the settling time.) Still 0 bytes after the look: not sized since.
        opened = _open_anywhere(root)
        for path in young_unsized:
            with contextlib.suppress(OSError):
                if str(path) not in opened and path.stat().st_size == 0:
                    stale.update(_files_of(root, path.name))
    return sorted(stale)


def clean_stale(root: Path = SHM) -> list[str]:
    """Remove :func:`stale_segments`; the names removed."""
    removed = []
    for path in stale_segments(root):
        with contextlib.suppress(FileNotFoundError):
            path.unlink()
            removed.append(path.name)
    return removed


def segments_of(pid: int) -> set[str]:
    """The Fast DDS segments process ``pid`` holds the lock of (its own, and the ports it uses)."""
    return {Path(target).name.removesuffix("_el") for target in open_file_targets(pid)
            if target.startswith(f"{SHM}/fastrtps_") and target.endswith("_el")}
