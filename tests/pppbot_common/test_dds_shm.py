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
    assert segments_of(os.getpid()) == set()  # this process opened no /dev/shm lock
