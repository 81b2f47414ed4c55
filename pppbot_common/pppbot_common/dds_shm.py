"""Fast DDS's shared-memory files that a dead process left behind, found and removed as
``fastdds shm clean`` does.

Each Fast DDS participant keeps its segments in ``/dev/shm``: ``fastrtps_<id>`` (its own),
``fastrtps_port<N>`` (a port, shared), each with a lock file ``<name>_el`` that every process
using it holds with ``flock`` while it lives, and a semaphore ``sem.<name>_mutex`` for ports.
A process that exits removes what it alone used; one killed (SIGKILL, a segfault, the OOM
killer) cannot, and its files stay until someone cleans them. A lock file nobody holds marks
a segment whose users are all gone. No ROS in here: the launch's supervisor uses it.
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


def stale_segments(root: Path = SHM) -> list[Path]:
    """The files of Fast DDS segments nobody uses any more: segment, lock file and semaphore."""
    stale: list[Path] = []
    if not root.is_dir():
        return stale
    now = time.time()
    for lock in root.glob("fastrtps_*_el"):
        with contextlib.suppress(OSError):
            if now - lock.stat().st_mtime < SETTLING_S or not _unheld(lock):
                continue
            segment = lock.name.removesuffix("_el")
            stale += [p for p in (root / segment, lock, root / f"sem.{segment}_mutex") if p.exists()]
    return stale


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
