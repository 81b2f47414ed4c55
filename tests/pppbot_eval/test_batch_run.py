"""A batch's pieces without a stack: resuming only the same run, generated worlds written once and
whole, a Ray task's folder moved home, and the summary per family."""
from __future__ import annotations

import csv
import io
import json
import tarfile
import threading
from pathlib import Path

from pppbot_eval.batch import Chain, Step, World
from pppbot_eval.batch_run import FINGERPRINT, fingerprint, finished_report, world_file
from pppbot_eval.batch_summary import RunResult, summarize, table, write_files
from pppbot_eval.ros.batch_ray import _unpack

MAZE = World("maze")


def step(flags: dict, world: World = MAZE, run_id: str = "maze/seed=1/drive") -> Step:
    return Step(run_id, "drive", "drive", world, flags, {"seed": 1})


def finish(out: Path, s: Step, report: dict) -> None:
    (out / s.id).mkdir(parents=True)
    (out / s.id / "report.json").write_text(json.dumps(report))
    (out / s.id / FINGERPRINT).write_text(json.dumps(fingerprint(s)))


def test_resume_keeps_a_report_only_for_the_same_run(tmp_path):
    ran = step({"seed": 1, "speed": 0.3})
    finish(tmp_path, ran, {"ok": True, "failure": None})
    assert finished_report(tmp_path, ran) == {"ok": True, "failure": None}
    assert finished_report(tmp_path, step({"seed": 1, "speed": 0.4})) is None  # the spec changed: run again
    assert finished_report(tmp_path, step({"seed": 1, "speed": 0.3}, World("office_000", "office", 0))) is None
    (tmp_path / ran.id / "report.json").write_text(json.dumps({"ok": False, "failure": "interrupted"}))
    assert finished_report(tmp_path, ran) is None  # an interrupted run is no result
    (tmp_path / ran.id / FINGERPRINT).unlink()
    (tmp_path / ran.id / "report.json").write_text(json.dumps({"ok": True, "failure": None}))
    assert finished_report(tmp_path, ran) is None  # a report without its run's record: not this batch's


def test_a_generated_world_is_written_once_and_whole_by_runs_that_start_together(tmp_path):
    world = World("corridor_small_000", "corridor", 0, small=True)
    paths: list[str] = []
    threads = [threading.Thread(target=lambda: paths.append(world_file(step({}, world), tmp_path)))
               for _ in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert paths == [str(tmp_path / "corridor_small_000.sdf")] * 3
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith(".")) == [
        "corridor_small_000.routes.yaml", "corridor_small_000.sdf"]
    assert "pppbot eval batch (family corridor, seed 0, small)" in (tmp_path / "corridor_small_000.sdf").read_text()


def test_a_ray_task_s_folder_lands_in_out_with_its_paths_pointing_there(tmp_path):
    remote = tmp_path / "remote" / "out"
    run = remote / "maze" / "slam"
    run.mkdir(parents=True)
    (run / "report.json").write_text(json.dumps({"map": str(run / "map.yaml"), "out": str(run)}))
    (run / "map.yaml").write_text("image: map.pgm\n")
    archive = io.BytesIO()
    with tarfile.open(fileobj=archive, mode="w:gz") as tar:
        tar.add(remote, arcname=".")
    out = tmp_path / "out"
    (out / "maze" / "slam").mkdir(parents=True)
    (out / "maze" / "slam" / "stale.png").write_text("from an earlier run")
    _unpack(str(remote), archive.getvalue(), out, Chain((Step("maze/slam", "slam", "slam", World("maze"), {}),)))
    report = json.loads((out / "maze" / "slam" / "report.json").read_text())
    assert report == {"map": str(out / "maze/slam/map.yaml"), "out": str(out / "maze/slam")}
    assert sorted(p.name for p in (out / "maze" / "slam").iterdir()) == ["map.yaml", "report.json"]


def test_the_summary_counts_per_family_and_scenario_and_the_csv_has_a_row_per_run(tmp_path):
    results = [
        RunResult("maze_000/navigation", "navigation", "maze_000", "maze", {"seed": 0},
                  {"ok": True, "collisions": 0, "success_rate": 1.0, "sim_seconds": 100.0, "wall_seconds": 20.0,
                   "barn_score": 0.5, "goal_results": [{"reached": True}, {"reached": True}]}),
        RunResult("maze_001/navigation", "navigation", "maze_001", "maze", {"seed": 1},
                  {"ok": False, "failure": "1 collision(s)", "collisions": 1, "success_rate": 0.5,
                   "sim_seconds": 80.0, "wall_seconds": 16.0, "barn_score": 0.1,
                   "goal_results": [{"reached": True}, {"reached": False}]}),
        RunResult("room/drive", "drive", "room", "room", {}, {"ok": True, "collisions": 0, "ate_rms_m": 0.02}),
    ]
    summary = summarize(results, wall_seconds=36.0)
    maze = summary["families"]["maze"]["navigation"]
    assert (maze["runs"], maze["ok"], maze["collisions"], maze["goals"], maze["goals_reached"]) == (2, 1, 1, 4, 3)
    assert maze["success_rate_median"] == 0.75 and maze["sim_seconds"] == 180.0
    assert maze["barn_score_mean"] == 0.3  # BARN's figure is the mean score
    assert summary["overall"]["runs"] == 3 and summary["runs_per_hour"] == 300.0
    assert summary["failures"] == {"maze_001/navigation": "1 collision(s)"}
    lines = table(summary).splitlines()
    assert lines[0].split()[:5] == ["family", "scenario", "runs", "ok", "collisions"]
    assert [line.split()[:2] for line in lines[1:]] == [["maze", "navigation"], ["room", "drive"], ["all", "3"]]
    assert json.loads(write_files(tmp_path, results, summary)) == summary
    with open(tmp_path / "summary.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [(r["id"], r["ok"], r["seed"], r["success_rate"]) for r in rows] == [
        ("maze_000/navigation", "True", "0", "1.0"), ("maze_001/navigation", "False", "1", "0.5"),
        ("room/drive", "True", "null", "")]
