"""``pppbot eval`` end to end in the box room (drive, slam, localization, navigation): the real stack over DDS,
reports read back. The lockstep runs on a busy machine are in test_busy_machine.py."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from eval_runs import box_room_map, run_eval
from PIL import Image

from pppbot_common.maps import OCCUPIED, load_map
from pppbot_common.param_files import check_parameter_file, node_parameters
from pppbot_eval.generated_worlds import write_world
from pppbot_eval.routes import load_routes, routes_file
from pppbot_sim.worldgen.families import Family, generate
from pppbot_slam.mapper import MapperSettings
from pppbot_slam.serialization import load_posegraph

#: A small clutter world whose straight line from the spawn to the goal is blocked.
CLUTTER_SEED = 4


def test_drive_scenario_reports_odometry_drift_against_ground_truth(spawn, tmp_path: Path):
    out = tmp_path / "report"
    code, report, output = run_eval(spawn, out, "--seed", "3", "--wheel-slip", "0.03")
    assert code == 0, output
    assert "drive box_room/loop: 100%" in output  # plain progress lines without a terminal
    # The last line of stdout is the whole report, as report.json holds it.
    assert report == json.loads((out / "report.json").read_text())
    assert report["scenario"] == "drive" and report["world"] == "box_room" and report["route"] == "loop"
    assert report["ok"] is True and report["failure"] is None
    assert report["route_completed"] is True and report["collisions"] == 0
    # The 6.4 m loop at 0.3 m/s with turns on the spot: about 25 sim seconds.
    assert 6.4 / 0.3 < report["sim_seconds"] < 120
    assert report["wall_seconds"] > 0 and report["real_time_factor"] > 0
    assert abs(report["distance_m"] - report["route_length_m"]) < 0.15 * report["route_length_m"]
    # 1.2 m from every wall, less the chassis and the tracking error.
    assert 0.6 < report["min_clearance_m"] < 1.2
    # Slipping wheels: odometry drifts (not zero), but stays in the tens of centimetres.
    assert 0.005 < report["ate_rms_m"] <= report["ate_max_m"] < 1.0
    assert 0.0 < report["ate_yaw_rms_rad"] <= report["ate_yaw_max_rad"] < 1.0
    assert report["rpe_segments"] > 100 and 0.0 < report["rpe_trans_mean_m_per_m"] < 0.5
    assert math.isfinite(report["final_position_error_m"])
    assert report["plots"] == ["error.png", "trajectory.png"]
    assert report["view"] is None and not (out / "view.rrd").exists()  # no view unless asked for
    for name in report["plots"]:
        with Image.open(out / name) as image:
            assert image.format == "PNG" and image.width > 400 and image.height > 300
    assert (out / "logs" / "simulator-1.log").read_text().count("spawned at x=-0.8 y=-0.8") == 1
    assert "process has died" not in output


def test_driving_into_a_wall_counts_a_collision_and_fails(spawn, tmp_path: Path):
    routes = tmp_path / "into_wall.routes.yaml"
    routes.write_text("routes:\n  wall:\n    start: {x: 1.0, y: 0.0, yaw: 0.0}\n    waypoints: [[3.0, 0.0]]\n")
    code, report, output = run_eval(spawn, tmp_path / "report", "--route-file", str(routes), "--timeout", "15")
    assert code == 1, output
    assert report["ok"] is False and report["route_completed"] is False
    assert report["collisions"] >= 1
    assert report["failure"].startswith("route not finished within 15")
    assert report["min_clearance_m"] == 0.0


def test_slam_scenario_maps_the_room_and_tracks_the_robot(spawn, tmp_path: Path, rrd_chunks):
    out = tmp_path / "slam"
    code, report, output = run_eval(spawn, out, "--seed", "2", "--wheel-slip", "0.03", scenario="slam", view=True)
    assert code == 0, output
    assert report["scenario"] == "slam" and report["ok"] is True and report["collisions"] == 0
    # The live view of the run, as a rerun recording beside the plots, read back by rerun's own CLI.
    assert report["view"] == "view.rrd"
    chunks = rrd_chunks(out / "view.rrd")
    for entity in ("/map", "/scan", "/tf/base_link", "/tf/odom", "/odom/trail/0", "/robot/chassis/visual_0",
                   "/slam/health"):
        assert chunks.get(entity, 0) >= 1, (entity, sorted(chunks))
    assert any(e.startswith("/slam/graph/") for e in chunks), sorted(chunks)
    # SLAM against ground truth (issue 9's targets): the map and the trajectory.
    assert report["map_f1"] >= 0.95 and report["map_precision"] >= 0.95 and report["map_recall"] >= 0.95
    assert report["ate_rms_m"] <= 0.05
    assert report["map_free_coverage"] > 0.9
    assert report["plots"] == ["error.png", "map.png", "trajectory.png"]
    # The map → odom chain was recorded and moved: SLAM corrected the slipping odometry.
    with np.load(out / "recording.npz") as recording:
        map_to_odom = recording["tf_map__odom"]
    assert len(np.unique(map_to_odom[:, 1:].round(4), axis=0)) > 3
    # The final map is saved as map_saver would (Nav2 YAML + PGM), for --map of the next scenarios.
    assert report["map"] == str(out / "map.yaml")
    saved, meta = load_map(out / "map.yaml")
    assert saved.resolution == pytest.approx(0.05) and (saved.data == OCCUPIED).sum() > 100
    # The slam node's health from /diagnostics: not lost, nothing undone.
    health = report["slam_health"]
    assert health["lost"] is False and health["keyframes"] >= 8 and health["undone_closures"] == 0, health
    # And its pose graph, as serialize_map writes it: every keyframe with its scan, for a replay.
    assert report["posegraph"] == str((out / "map.posegraph").resolve())
    graph = load_posegraph(out / "map.posegraph", MapperSettings())
    assert len(graph.keyframes) == health["keyframes"]
    assert all(np.isfinite(k.rays.ranges_m).sum() > 100 for k in graph.keyframes)
    # Its loop closures judged on ground truth (none on a loop this short: the suite's worlds close some).
    assert report["closures"] == len(graph.loop_closures) == health["loop_closures"]
    assert report["false_closures"] == 0 and report["false_closure_keyframes"] == []




def test_localization_scenario_recovers_from_a_wrong_initial_pose_on_the_rooms_map(spawn, tmp_path: Path):
    map_file = box_room_map(spawn, tmp_path)
    out = tmp_path / "localization"
    code, report, output = run_eval(spawn, out, "--seed", "1", "--map", str(map_file),
                                    "--initial-offset", "0.3", "-0.4", "0.3", scenario="localization")
    assert code == 0, output
    assert report["scenario"] == "localization" and report["ok"] is True and report["collisions"] == 0
    # Off by 0.5 m and 0.3 rad at the start; near issue 10's targets once converged (they are measured on
    # the maze and room by eval; this small room's map is drawn half a cell off its walls in places).
    assert report["initial_position_error_m"] > 0.15
    assert report["converged"] is True and report["converged_after_m"] <= 2.0
    assert report["amcl_rms_m"] <= 0.05 and report["amcl_yaw_rms_rad"] <= 0.03
    assert report["plots"] == ["error.png", "trajectory.png"]


def test_navigation_scenario_reaches_random_goals_judged_on_ground_truth(spawn, tmp_path: Path):
    map_file = box_room_map(spawn, tmp_path)
    out = tmp_path / "navigation"
    code, report, output = run_eval(spawn, out, "--seed", "4", "--map", str(map_file), "--goals", "3",
                                    "--goal-distance", "1.5", "--start", "-0.8", "-0.8", "0", scenario="navigation")
    assert code == 0, output
    assert report == json.loads((out / "report.json").read_text())
    assert report["scenario"] == "navigation" and report["ok"] is True and report["failure"] is None
    assert report["lockstep"] is True and report["target_real_time_factor"] == 0.0  # as fast as possible
    assert report["goals"] == 3 and report["successes"] == 3 and report["success_rate"] == 1.0
    assert report["collisions"] == 0 and report["min_clearance_m"] > 0.0
    results = report["goal_results"]
    previous = (-0.8, -0.8)
    for result in results:
        x, y, yaw = result["goal"]
        # Drawn in the room's free space, 0.45 m from its walls (inner faces at ±2 m), 1.5 m apart.
        assert max(abs(x), abs(y)) <= 2.0 - 0.45 and math.hypot(x - previous[0], y - previous[1]) >= 1.5
        previous = (x, y)
        assert result["status"] == "succeeded" and result["reached"] is True and result["error_code"] == 0
        # Judged on ground truth: where the robot stopped, not where the navigator thought it was.
        assert result["position_error_m"] <= 0.35 and abs(result["yaw_error_rad"]) <= 0.3
        # An empty room: the driven path is close to the shortest; the time counts the turns too.
        assert result["shortest_path_m"] >= 1.2 and result["path_length_m"] < 1.5 * result["shortest_path_m"]
        assert result["time_s"] * 0.5 >= result["shortest_path_m"] * 0.9  # at most 0.5 m/s (desired_linear_vel)
    assert report["mean_time_ratio"] >= 1.0 and report["total_time_ratio"] >= 1.0
    assert 0.0 < report["turning_in_place_s"] < report["sim_seconds"]
    assert 0.5 < report["total_time_ratio_without_turning"] < report["total_time_ratio"]
    with np.load(out / "recording.npz") as recording:  # to re-score: each goal's times and pose
        goals = recording["goals"]
    assert goals.shape == (3, 5) and np.allclose(goals[:, 2:], [r["goal"] for r in results])
    assert np.allclose(goals[:, 0], [r["start_s"] for r in results], atol=1e-3)
    assert report["ate_rms_m"] < 0.1  # AMCL along the way
    assert report["plots"] == ["trajectory.png"]
    for log in ("navigation-1.log", "localization-1.log"):  # composed: planner, controller, navigator; map_server, amcl
        assert (out / "logs" / log).is_file()
    assert "process has died" not in output


def test_navigation_without_a_map_crosses_a_clutter_field_judged_as_barn_judges(spawn, tmp_path: Path):
    world, summary = write_world(generate(Family.CLUTTER, CLUTTER_SEED, small=True), tmp_path / "worlds")
    crossing = load_routes(routes_file(world))[0]
    assert crossing.name == "crossing"
    out = tmp_path / "no_map"
    code, report, output = run_eval(spawn, out, "--world", str(world), "--no-map", scenario="navigation")
    assert code == 0, output
    assert report["ok"] is True and report["map_free"] is True and report["collisions"] == 0
    # The goal is where the world's crossing ends, facing along its last leg.
    (x0, y0), (x1, y1) = crossing.points[-2:]
    assert report["goal"] == pytest.approx([x1, y1, math.atan2(y1 - y0, x1 - x0)])
    assert report["goal"][:2] == pytest.approx(summary["goal"][:2])
    [result] = report["goal_results"]
    # Arrived (within 1 m, BARN's rule) through the field, never touching it, timed to that moment.
    assert result["reached"] is True and result["position_error_m"] <= 1.0 and result["min_clearance_m"] > 0.0
    optimal_s = result["shortest_path_m"] / report["max_speed_mps"]
    assert result["shortest_path_m"] >= math.dist((0, 0), (x1, y1)) - 1e-6
    assert result["time_s"] >= optimal_s * 0.9  # never faster than the shortest path at top speed
    assert report["barn_score"] == result["barn_score"] == pytest.approx(optimal_s / min(max(
        result["time_s"], 2 * optimal_s), 8 * optimal_s), abs=1e-3)
    # No map_server, AMCL or SLAM: Nav2 in odom, its global costmap rolling; judged on odometry.
    logs = {p.name for p in (out / "logs").iterdir()}
    assert "navigation-1.log" in logs and not {"localization-1.log", "slam_toolbox-1.log"} & logs
    params = check_parameter_file(out / "logs" / "nav2_params_map_free.yaml")
    assert node_parameters(params, "/bt_navigator")["global_frame"] == "odom"
    assert report["ate_rms_m"] < 0.1
