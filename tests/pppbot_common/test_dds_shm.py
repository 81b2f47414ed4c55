"""Fast DDS shared-memory files a dead process left: found by their unheld locks, as ``fastdds shm
clean`` finds them, and removed; a segment a living process holds, or one just made, is kept."""
from __future__ import annotations

import fcntl
import os
import time
from pathlib import Path

from pppbot_common.dds_shm import SETTLING_S, clean_stale, segments_of, stale_segments


def segment(root: Path, name: str, age_s: float = 10.0, semaphore: bool = False) -> Path:
    for path in (root / name, root / f"{name}_el", *([root / f"sem.{name}_mutex"] if semaphore else [])):
        path.write_bytes(b"\0" * 64)
        then = time.time() - age_s
        os.utime(path, (then, then))
    return root / f"{name}_el"


def test_only_segments_nobody_holds_are_stale_and_removed(tmp_path: Path) -> None:
    ours = segments_of(os.getpid())  # a ROS test before this one in this worker may hold some
    segment(tmp_path, "fastrtps_dead", semaphore=True)
    held = segment(tmp_path, "fastrtps_port7001", semaphore=True)
    segment(tmp_path, "fastrtps_young", age_s=SETTLING_S / 4)
    (tmp_path / "other_file").write_text("not Fast DDS's")
    fd = os.open(held, os.O_RDWR)
    fcntl.flock(fd, fcntl.LOCK_SH)  # as every participant using the port holds it
    try:
        assert sorted(p.name for p in stale_segments(tmp_path)) == [
            "fastrtps_dead", "fastrtps_dead_el", "sem.fastrtps_dead_mutex"]
        assert sorted(clean_stale(tmp_path)) == ["fastrtps_dead", "fastrtps_dead_el", "sem.fastrtps_dead_mutex"]
        assert sorted(p.name for p in tmp_path.iterdir()) == [
            "fastrtps_port7001", "fastrtps_port7001_el", "fastrtps_young", "fastrtps_young_el", "other_file",
            "sem.fastrtps_port7001_mutex"]
    finally:
        os.close(fd)
    assert segments_of(os.getpid()) == ours  # looking opened no /dev/shm lock


def test_a_segment_never_sized_is_stale_whoever_holds_it_but_a_lock_file_is_no_segment(tmp_path: Path) -> None:
    """0 bytes: made by a process killed before it sized it; Fast DDS would wait on it forever.
    One just made is kept while a process has it open (its maker may be sizing it right now)."""
    then = time.time() - 10 * SETTLING_S
    for name in ("fastrtps_port7411", "fastrtps_port7411_el", "sem.fastrtps_port7411_mutex",  # never sized
                 "fastrtps_port7413_sl", "fastrtps_0a1b", "fastrtps_0a1b_el"):  # a shared lock; a live segment
        (tmp_path / name).write_bytes(b"" if "7411" in name or name.endswith(("_el", "_sl")) else b"\0" * 64)
        os.utime(tmp_path / name, (then, then))
    for name in ("fastrtps_port7415", "fastrtps_port7417", "sem.fastrtps_port7417_mutex"):
        (tmp_path / name).touch()  # just made: 7415 by a process sizing it, 7417 by one killed before it could
    held = [os.open(tmp_path / name, os.O_RDWR) for name in ("fastrtps_port7411_el", "fastrtps_0a1b_el")]
    maker = os.open(tmp_path / "fastrtps_port7415", os.O_RDWR)
    try:
        for fd in held:
            fcntl.flock(fd, fcntl.LOCK_SH)
        assert sorted(clean_stale(tmp_path)) == [
            "fastrtps_port7411", "fastrtps_port7411_el", "fastrtps_port7417", "sem.fastrtps_port7411_mutex",
            "sem.fastrtps_port7417_mutex"]
        assert sorted(p.name for p in tmp_path.iterdir()) == [
            "fastrtps_0a1b", "fastrtps_0a1b_el", "fastrtps_port7413_sl", "fastrtps_port7415"]
    finally:
        for fd in (*held, maker):
            os.close(fd)
