"""``pppbot eval batch``: the same reports with 1 worker, 2 workers and on a local Ray instance;
a summary per family, a CSV, resuming, and Ctrl-C stopping every stack."""
from __future__ import annotations

import csv
import json
import os
import shutil
import signal
import tempfile
from pathlib import Path
from typing import Any

import pytest

from pppbot_common.process import listening_addresses
from pppbot_common.ros.wait import wait_until
from pppbot_eval.batch_summary import comparable_reports as reports

from .eval_runs import BOX_ROOM, PPPBOT

pytestmark = pytest.mark.ros

SEEDS = (1, 2)


def spec(tmp_path: Path, seeds: tuple[int, ...] = SEEDS, mapping: bool = False, slow: bool = False) -> Path:
    """Short drives in the box room (a 1.2 m route), one per seed; with ``mapping``, also a chain:
    a short SLAM run, then its saved map scored (the map scenario takes the slam run's map and start);
    ``slow``: instead, 20 sim seconds of the room's loop at 1x, without lockstep (to be interrupted;
    long enough that no run ends before the Ctrl-C reaches it through Ray on a busy machine)."""
    route = tmp_path / "short.routes.yaml"
    route.write_text("world: box_room\nroutes:\n  short:\n    start: {x: -0.8, y: -0.8, yaw: 0.0}\n"
                     "    waypoints:\n      - [0.4, -0.8]\n")
    path = tmp_path / "drives.yaml"
    chain = (f"  - world: {BOX_ROOM}\n    steps:\n      - {{scenario: slam, timeout: 8}}\n"
             "      - {scenario: map, map: '${slam.map}', map_pose: '${slam.start}'}\n") if mapping else ""
    defaults = ("{lockstep: false, real_time_factor: 1, timeout: 20}" if slow
                else f"{{route_file: {route}, wheel_slip: 0.03}}")
    path.write_text(f"defaults: {defaults}\n"
                    f"runs:\n  - scenario: drive\n    world: {BOX_ROOM}\n    seed: {list(seeds)}\n{chain}")
    return path


def run_batch(spawn: Any, spec_file: Path, out: Path, *flags: str,
              env: dict[str, str] | None = None) -> tuple[int, dict[str, Any]]:
    batch = spawn([PPPBOT, "eval", "batch", str(spec_file), "--out", str(out), *flags], name="batch", env=env)
    code = batch.wait(timeout_s=300)
    return code, json.loads(batch.output.strip().splitlines()[-1])




def test_one_worker_two_workers_and_ray_give_the_same_reports(spawn, tmp_path):
    spec_file = spec(tmp_path, mapping=True)
    one, two, ray = tmp_path / "one", tmp_path / "two", tmp_path / "ray"
    code, summary = run_batch(spawn, spec_file, one, "--workers", "1")
    assert summary["runs"] == 4 and not summary["interrupted"]
    assert summary["families"]["box_room"]["drive"]["runs"] == 2
    assert list(reports(one)) == ["box_room/map", "box_room/seed=1/drive", "box_room/seed=2/drive", "box_room/slam"]
    scored = reports(one)["box_room/map"]
    assert scored["map_f1"] > 0.3 and scored["map"] == "<out>/box_room/slam/map.yaml"  # the slam run's map
    first = reports(one)["box_room/seed=1/drive"]
    assert first["ok"] and first["seed"] == 1 and first["wheel_slip"] == 0.03 and first["route"] == "short"
    assert first["ate_rms_m"] > 0  # slip made the odometry drift: a run that measured something
    assert reports(one)["box_room/seed=1/drive"] != reports(one)["box_room/seed=2/drive"]  # the seed mattered

    assert run_batch(spawn, spec_file, two, "--workers", "2")[0] == 0
    assert reports(two) == reports(one)
    # Ray's session files in a temporary folder of their own (short: Ray's socket paths stay under 108 bytes)
    ray_files = tempfile.mkdtemp(prefix="ray-")
    try:
        code, summary = run_batch(spawn, spec_file, ray, "--ray", "local", env={**os.environ, "RAY_TMPDIR": ray_files})
    finally:
        shutil.rmtree(ray_files, ignore_errors=True)
    assert code == 0, summary["failures"]
    assert reports(ray) == reports(one)
    assert json.loads((ray / "box_room/seed=2/drive/report.json").read_text())["out"] == str(
        ray / "box_room/seed=2/drive")  # paths point where the files now are
    assert (ray / "box_room/slam/map.pgm").read_bytes() == (one / "box_room/slam/map.pgm").read_bytes()

    with open(one / "summary.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [(r["id"], r["seed"], r["ok"]) for r in rows][:2] == [("box_room/seed=1/drive", "1", "True"),
                                                                ("box_room/seed=2/drive", "2", "True")]
    assert float(rows[0]["ate_rms_m"]) == first["ate_rms_m"]
    assert json.loads((one / "summary.json").read_text())["overall"] == summary["overall"] | {
        "wall_seconds": json.loads((one / "summary.json").read_text())["overall"]["wall_seconds"]}

    # Resumed, a finished batch runs nothing again: every report stays the file it was.
    before = {p: p.stat().st_mtime_ns for p in one.glob("**/report.json")}
    code, summary = run_batch(spawn, spec_file, one, "--resume")
    assert summary["runs"] == 4 and summary["failures"] == json.loads((one / "summary.json").read_text())["failures"]
    assert {p: p.stat().st_mtime_ns for p in one.glob("**/report.json")} == before


def _batch_processes(out: Path) -> list[str]:
    """The processes of a batch into ``out``: the batch, its evals and their stacks (their files are in
    ``out``, or on Ray in a task's folder)."""
    return _processes_naming(str(out)) + _processes_naming("pppbot-batch-")


def _processes_naming(text: str) -> list[str]:
    found = []
    for entry in Path("/proc").iterdir():
        try:
            cmdline = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        if entry.name.isdigit() and text in cmdline:
            found.append(f"{entry.name}: {cmdline}")
    return found


@pytest.mark.parametrize("where", ["workers", "ray"])
def test_ctrl_c_stops_every_stack_and_resume_runs_what_did_not_finish(spawn, tmp_path, where):
    spec_file = spec(tmp_path, seeds=(3, 4), slow=True)
    out = tmp_path / "out"
    ray_files = tempfile.mkdtemp(prefix="ray-")
    flags = ["--workers", "1"] if where == "workers" else ["--ray", "local"]
    env = {**os.environ, "RAY_TMPDIR": ray_files}
    try:
        batch = spawn([PPPBOT, "eval", "batch", str(spec_file), "--out", str(out), *flags], name="batch", env=env)
        wait_until(lambda: [p for p in _batch_processes(out) if "simulator" in p], 120, "the first run's simulator")
        os.kill(batch.pid, signal.SIGINT)
        assert batch.wait(timeout_s=200) == 130
        summary = json.loads(batch.output.strip().splitlines()[-1])
        assert summary["interrupted"] and summary["runs"] == 0 and summary["not_run"] == 2
        assert list(out.glob("**/report.json")) == []  # an interrupted run is no result
        assert _batch_processes(out) == []  # no eval, simulator or node left behind

        _, summary = run_batch(spawn, spec_file, out, "--resume", *flags, env=env)
        assert summary["runs"] == 2 and not summary["interrupted"]
        seeds = [json.loads((out / f"box_room/seed={s}/drive/report.json").read_text())["seed"] for s in (3, 4)]
        assert seeds == [3, 4]
    finally:
        shutil.rmtree(ray_files, ignore_errors=True)


def test_a_local_ray_instance_listens_on_127_0_0_1_only(spawn, tmp_path):
    ray_files = tempfile.mkdtemp(prefix="ray-")
    try:
        child = spawn([PPPBOT, "env", "python", "-c",
                       "import time; from pppbot_eval.ros.batch_ray import connect; connect('local'); "
                       "print('up', flush=True); time.sleep(120)"],
                      name="ray_local", env={**os.environ, "RAY_TMPDIR": ray_files})
        child.wait_for_output(r"^up$", 120)
        ray_processes = {int(p.split(":")[0]) for p in _processes_naming(ray_files)} | {child.pid}
        listening = listening_addresses(ray_processes)
        assert len(listening) >= 3  # the GCS, the raylet, workers: something was looked at
        assert [a for a in listening if a[0] != "127.0.0.1"] == []
        child.stop()
    finally:
        shutil.rmtree(ray_files, ignore_errors=True)
