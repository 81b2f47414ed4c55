"""Lockstep gives the same run to the bit on a machine as loaded as it gets: ``pppbot eval`` twice
with one seed, once beside the suite and once with both cores taken by busy loops. The busy run
has the machine to itself (``whole_machine``): no other test runs beside the busy loops (a stack
another worker's module fixture keeps up may). Not ``heavy``: as a file that takes the machine
whole it is handed out last, and the busy run waits for a short test to end, not for the other
worker's longest."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from eval_runs import box_room_map, busy_loops, run_eval

VARYING = {"wall_seconds", "real_time_factor", "out", "map", "posegraph"}


def test_lockstep_slam_is_the_same_run_on_a_busy_machine(spawn, whole_machine, tmp_path: Path):
    """Lockstep (eval's default): the same seed gives the same run to the bit, once beside the suite
    and once with both cores taken by busy loops: every recorded series (ground truth, odometry,
    SLAM's map -> odom), the saved map and the report."""
    recordings, reports, maps = [], [], []
    for name in ("first", "busy"):
        if name == "busy":
            whole_machine()
            busy_loops(spawn)
        out = tmp_path / name
        code, report, output = run_eval(spawn, out, "--seed", "3", "--wheel-slip", "0.03", "--timeout", "40",
                                        scenario="slam")
        assert report["lockstep"] is True, output
        assert "go on without" not in output and "skipped" not in output, output  # nothing by wall clock
        with np.load(out / "recording.npz") as data:
            recordings.append({key: data[key] for key in data.files})
        reports.append(report)
        maps.append((out / "map.pgm").read_bytes())
    first, busy = recordings
    assert first.keys() == busy.keys() and len(first["truth"]) > 500 and "tf_map__odom" in first
    for key in first:
        assert np.array_equal(first[key], busy[key]), key
    assert maps[0] == maps[1]
    assert {k: v for k, v in reports[0].items() if k not in VARYING} == \
           {k: v for k, v in reports[1].items() if k not in VARYING}


def test_lockstep_navigation_is_the_same_run_on_a_busy_machine(spawn, whole_machine, tmp_path: Path):
    """Navigation in lockstep (AMCL, and the planner, controller_server and navigator composed):
    the same seed gives the same run to the bit (ground-truth trajectory, goal outcomes,
    collisions), once beside the suite and once with both cores taken by busy loops."""
    map_file = box_room_map(spawn, tmp_path)
    runs = []
    for name in ("first", "busy"):
        if name == "busy":
            whole_machine()
            busy_loops(spawn)
        out = tmp_path / name
        code, report, output = run_eval(spawn, out, "--seed", "4", "--map", str(map_file), "--goals", "2",
                                        "--goal-distance", "1.5", "--start", "-0.8", "-0.8", "0",
                                        scenario="navigation")
        assert code == 0, output
        assert "go on without" not in output, output
        with np.load(out / "recording.npz") as data:
            runs.append((report, {key: data[key] for key in data.files}))
    (first, first_data), (busy, busy_data) = runs
    assert first["successes"] == busy["successes"] == 2
    assert [r["status"] for r in first["goal_results"]] == [r["status"] for r in busy["goal_results"]]
    assert first["collisions"] == busy["collisions"] == 0
    assert len(first_data["truth"]) > 300
    for key in first_data:
        assert np.array_equal(first_data[key], busy_data[key]), key
