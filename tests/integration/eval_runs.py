"""Running ``pppbot eval`` in the box room from a test: the real stack as a child process, its
report read back (shared by the eval tests)."""
from __future__ import annotations

import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pppbot_common.process import ChildProcess

ROOT = Path(__file__).resolve().parents[2]
PPPBOT = str(ROOT / "pppbot")
BOX_ROOM = str(ROOT / "tests" / "pppbot_sim" / "data" / "box_room.sdf")


def run_eval(spawn: Callable[..., ChildProcess], out: Path, *extra: str,
             scenario: str = "drive", view: bool = False) -> tuple[int, dict[str, Any], str]:
    """Exit code, the report from stdout, and stderr (progress, node warnings). ``view``: ``--view``
    (the live view's recording is tested once, in the slam run; the others run on the default, none)."""
    stderr = out.parent / f"{out.name}.stderr"
    child = spawn(["bash", "-c", f'exec "$0" "$@" 2>"{stderr}"', PPPBOT, "eval", scenario, "--world", BOX_ROOM,
                   "--out", str(out), "--json", *(("--view",) if view else ()), *extra], name="eval")
    code = child.wait(timeout_s=240)
    stdout_lines = child.output.strip().splitlines()
    assert len(stdout_lines) == 1, child.output  # with --json, stdout is the report alone
    return code, json.loads(stdout_lines[0]), stderr.read_text()


def box_room_map(spawn: Callable[..., ChildProcess], folder: Path) -> Path:
    """The room's ground-truth map, as maps/<world>.yaml would hold it."""
    saver = spawn([PPPBOT, "run", "pppbot_sim", "ground_truth_map", f"world:={BOX_ROOM}",
                   f"output:={folder / 'box_room'}"], name="ground_truth_map")
    assert saver.wait(timeout_s=120) == 0, saver.output
    return folder / "box_room.yaml"


def busy_loops(spawn: Callable[..., ChildProcess]) -> None:
    """Two busy loops, one pinned to each core: the machine as loaded as it gets (they end with the test)."""
    for core in (0, 1):
        spawn(["taskset", "-c", str(core), sys.executable, "-c", "while True: pass"], name=f"busy_loop_{core}")
