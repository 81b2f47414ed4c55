"""The autonomy suite: its smallest configuration (two small worlds) end to end in lockstep, and its
aggregate on constructed figures."""
from __future__ import annotations

import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml

from pppbot_common.maps import OCCUPIED, load_map
from pppbot_common.process import ChildProcess
from pppbot_eval.batch import filled, load_batch
from pppbot_eval.ros.batch_cli import eval_parser
from pppbot_eval.scenarios import Scenario
from pppbot_sim.wheel_slip import MAX_SLIP_STDDEV

ROOT = Path(__file__).resolve().parents[2]
SUITE = str(ROOT / "benchmarks" / "autonomy_suite.py")


@pytest.fixture(scope="module")
def suite(load_benchmark):
    return load_benchmark("autonomy_suite")


def world(name: str, family: str, f1: float | None, ate: float | None, ate_max: float | None, amcl: float | None,
          reached: int, goals: int, collisions: int = 0, false_closures: int = 0) -> dict[str, Any]:
    return {"world": name, "family": family,
            "slam": {"ok": f1 is not None, "map_f1": f1, "ate_rms_m": ate, "ate_max_m": ate_max, "collisions": 0,
                     "false_closures": false_closures, "wall_seconds": 10.0},
            "localization": {"ok": amcl is not None, "converged": amcl is not None, "amcl_rms_m": amcl,
                             "collisions": collisions, "wall_seconds": 5.0},
            "navigation": {"ok": reached == goals, "goals": goals, "reached": reached, "collisions": 0,
                           "wall_seconds": 5.0}}


def test_the_suite_is_a_batch_spec_and_the_shipped_one_is_its_held_out_set(suite):
    shipped = ROOT / "benchmarks" / "batches" / "autonomy_held_out.yaml"
    assert yaml.safe_load(shipped.read_text()) == suite.suite_spec(["held_out"], 10)
    batch = load_batch(shipped, eval_parser(), [s.value for s in Scenario], MAX_SLIP_STDDEV)
    assert len(batch.chains) == 21 and len(batch.steps) == 63
    slam, localization, navigation = batch.chains[0].steps
    assert [slam.id, localization.id, navigation.id] == ["maze_100/slam", "maze_100/localization",
                                                          "maze_100/navigation"]
    assert filled(navigation, {"slam": {"map": "/m.yaml", "start": [1.0, 2.0, 0.0]}}) == {
        "lockstep": True, "wheel_slip": 0.01, "view": False, "seed": 100, "map": "/m.yaml",
        "map_pose": [1.0, 2.0, 0.0], "start": [1.0, 2.0, 0.0], "goals": 10}
    # a few worlds: one entry each, the ci set's small worlds among them
    picked = suite.suite_spec(["ci"], 3, {"office_small_001"})
    assert [r["world"] for r in picked["runs"]] == [{"family": "office", "seed": 1, "small": True}]


def test_the_aggregate_counts_worlds_against_each_target(suite):
    worlds = [world("a", "maze", 0.99, 0.03, 0.1, 0.02, 10, 10),
              world("b", "maze", 0.96, 0.06, 0.2, 0.04, 9, 10, false_closures=2),  # ATE RMS over 5 cm
              world("c", "hall", 0.97, 0.02, 0.7, None, 10, 10, collisions=1),  # peak over 0.5 m; AMCL lost
              world("d", "hall", None, None, None, None, 0, 0)]  # SLAM failed: counts against every target
    figures = suite.aggregate(worlds)
    assert figures["worlds"] == 4
    assert figures["map_good_fraction"] == 0.5 and figures["amcl_good_fraction"] == 0.5
    assert figures["worlds_ate_max_over_limit"] == ["c", "d"]
    assert figures["goals"] == 30 and figures["goals_reached"] == 29 and figures["goal_rate"] == pytest.approx(0.9667)
    assert figures["collisions"] == 1 and figures["map_f1_min"] == 0.96 and figures["ate_max_m_max"] == 0.7
    assert figures["false_closures"] == 2
    targets = figures["targets"]
    assert not any(t["met"] for t in targets.values())
    good = suite.aggregate(worlds[:1])
    assert all(t["met"] for t in good["targets"].values())
    assert suite.aggregate([])["map_good_fraction"] is None


@pytest.mark.ros
@pytest.mark.heavy
@pytest.mark.timeout(2400)
def test_the_smallest_suite_maps_localizes_and_navigates_two_small_worlds_in_lockstep(
        spawn: Callable[..., ChildProcess], tmp_path: Path):
    out = tmp_path / "suite"
    child = spawn([sys.executable, SUITE, "--set", "ci", "--goals", "3", "--out", str(out)], name="autonomy_suite")
    assert child.wait(timeout_s=2300) == 0, child.output[-3000:]
    result = json.loads(child.output.strip().splitlines()[-1])
    assert result["lockstep"] is True and result["wheel_slip"] == 0.01 and list(result["sets"]) == ["ci"]
    ci = result["sets"]["ci"]
    assert [w["world"] for w in ci["worlds"]] == ["looped_maze_small_000", "office_small_001"]
    for figures in ci["worlds"]:
        name = figures["world"]
        assert (out / "worlds" / f"{name}.sdf").is_file() and (out / "worlds" / f"{name}.routes.yaml").is_file()
        slam, localization, navigation = figures["slam"], figures["localization"], figures["navigation"]
        assert slam["ok"] and localization["ok"] and navigation["ok"], figures
        # Deliver 3's targets, world by world.
        assert slam["map_f1"] >= 0.95 and slam["ate_rms_m"] <= 0.05 and slam["ate_max_m"] <= 0.5, slam
        assert slam["closures"] is not None and slam["false_closures"] == 0, slam  # judged on ground truth
        assert localization["converged"] and localization["amcl_rms_m"] <= 0.05, localization
        assert navigation["goals"] == 3 and navigation["reached"] == 3 and navigation["collisions"] == 0, navigation
        # AMCL and navigation ran on the map SLAM saved.
        grid, _ = load_map(out / name / "slam" / "map.yaml")
        assert (grid.data == OCCUPIED).sum() > 200
        for stage in ("localization", "navigation"):
            report = json.loads((out / name / stage / "report.json").read_text())
            assert report["lockstep"] is True and report["ok"] is True
    assert all(t["met"] for t in ci["aggregate"]["targets"].values()), ci["aggregate"]
    assert set(ci["families"]) == {"looped_maze", "office"}
    # --resume takes the reports already there: the same figures, nothing run again.
    again = spawn([sys.executable, SUITE, "--set", "ci", "--goals", "3", "--out", str(out), "--resume"],
                  name="autonomy_suite_resume")
    assert again.wait(timeout_s=300) == 0, again.output[-3000:]
    resumed = json.loads(again.output.strip().splitlines()[-1])
    assert resumed["sets"]["ci"]["worlds"] == ci["worlds"]
