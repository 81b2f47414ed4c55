"""The score follows the parameters the stack ran with: ``--params-file`` is read once, handed to
the stack, and its scored values (AMCL's transform tolerance, the controller's speed) used."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from pppbot_common.errors import ArgumentError
from pppbot_common.maps import OccupancyGrid
from pppbot_common.param_files import check_parameter_file, node_parameters
from pppbot_eval.config import SMOOTHER_MAX_X_DEFAULT, EvalConfig, ScoredParameters
from pppbot_eval.ros.cli import Run, default_nav2_params
from pppbot_eval.ros.run_report import navigation_report
from pppbot_eval.scenarios import GoalAnswer, GoalRecord, Scenario
from pppbot_nav.controller.dwb import DWBSettings
from pppbot_nav.controller.plugin_settings import RPP
from pppbot_nav.ros.velocity_smoother import VelocitySmootherParameters

from .test_config import MAX_SLIP, flags


def params_file(tmp_path: Path, text: str, name: str = "nav2.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_the_shipped_file_gives_the_values_written_in_it():
    shipped = yaml.safe_load(default_nav2_params().read_text())
    scored = ScoredParameters.read(default_nav2_params())
    assert scored.amcl_transform_tolerance == shipped["amcl"]["ros__parameters"]["transform_tolerance"]
    controller = shipped["controller_server"]["ros__parameters"]
    assert scored.max_speed_mps == min(controller["FollowPath"]["desired_linear_vel"],
                                       shipped["velocity_smoother"]["ros__parameters"]["max_velocity"][0])


def test_a_node_s_own_name_wins_over_a_wildcard_wherever_it_is_in_the_file(tmp_path):
    path = params_file(tmp_path, """
/amcl:
  ros__parameters: {transform_tolerance: 0.7}
/**:
  ros__parameters: {transform_tolerance: 0.3}
controller_server:
  ros__parameters:
    controller_plugins: ["Track"]
    Track:
      plugin: "dwb_core::DWBLocalPlanner"
      max_vel_x: 0.4
velocity_smoother:
  ros__parameters: {max_velocity: [0.35, 0.0, 2.0]}
""")
    scored = ScoredParameters.read(path)
    assert scored.amcl_transform_tolerance == 0.7
    assert scored.max_speed_mps == 0.35  # DWB's max_vel_x, capped by the smoother
    assert node_parameters(check_parameter_file(path), "/planner_server") == {"transform_tolerance": 0.3}
    assert node_parameters(check_parameter_file(path), "/ns/amcl") == {"transform_tolerance": 0.3}


def test_where_the_file_is_silent_the_stack_s_defaults_are_scored(tmp_path):
    """No plugin for FollowPath: Nav2's default controller, DWB, at its default 0.26 m/s; no smoother
    section: its default cap."""
    scored = ScoredParameters.read(params_file(tmp_path, "amcl:\n  ros__parameters: {}\n"))
    assert scored.max_speed_mps == DWBSettings().max_vel_x == 0.26
    assert scored.amcl_transform_tolerance == 1.0
    assert VelocitySmootherParameters().max_velocity[0] == SMOOTHER_MAX_X_DEFAULT


def test_a_scored_value_that_is_no_positive_number_is_refused_naming_it(tmp_path):
    path = params_file(tmp_path, "amcl:\n  ros__parameters: {transform_tolerance: -1.0}\n")
    with pytest.raises(ArgumentError, match=r"nav2\.yaml: amcl transform_tolerance = -1\.0: .*positive number"):
        ScoredParameters.read(path)
    with pytest.raises(ArgumentError, match=r"--params-file .*nav2\.yaml: line 2, column 1: not valid YAML"):
        ScoredParameters.read(params_file(tmp_path, "amcl: [\n"))


def _navigation_score(tmp_path: Path, speed: float) -> dict:
    """The navigation report of one recorded goal, scored with a params file giving ``speed``."""
    path = params_file(tmp_path, f"controller_server:\n  ros__parameters:\n    FollowPath:\n"
                                 f"      plugin: {RPP}\n      desired_linear_vel: {speed}\n", f"nav2_{speed}.yaml")
    config = EvalConfig.from_flags(flags("navigation", "--world", "box_room", "--goals", "1",
                                         "--params-file", str(path)), MAX_SLIP)
    free = OccupancyGrid(np.zeros((60, 60), dtype=np.int8), 0.1, (-3.0, -3.0, 0.0))
    out = tmp_path / f"out_{speed}"
    out.mkdir()
    run = Run(config, Path("box_room.sdf"), None, out, free, [(2.0, 0.0, 0.0)], scored=ScoredParameters.read(path))
    assert run.config.scenario is Scenario.NAVIGATION
    assert run._launch_args().params_file == str(path)  # the stack runs with the file that is scored
    t = np.linspace(0.0, 10.0, 101)
    run.recording.truth_rows = [(float(s), float(s) / 5.0, 0.0, 0.0) for s in t]  # 2 m in 10 s
    run.recording.edge_rows = {("map", "odom"): [(float(s), 0.0, 0.0, 0.0) for s in t],  # AMCL's estimate
                               ("odom", "base_link"): list(run.recording.truth_rows)}
    run.recording.goals = [GoalRecord((2.0, 0.0, 0.0), 0.0, 10.0, GoalAnswer.SUCCEEDED, shortest_path_m=2.0)]
    return navigation_report(run, free)


def test_the_navigation_score_follows_the_speed_in_the_params_file(tmp_path):
    slow, fast = _navigation_score(tmp_path, 0.25), _navigation_score(tmp_path, 0.5)
    assert slow["ok"] and fast["ok"], (slow["failure"], fast["failure"])
    assert slow["max_speed_mps"] == 0.25 and fast["max_speed_mps"] == 0.5
    # 10 s for 2 m: 1.25 times the shortest time at 0.25 m/s, 2.5 times at 0.5 m/s
    assert slow["total_time_ratio"] == pytest.approx(1.25) and fast["total_time_ratio"] == pytest.approx(2.5)
