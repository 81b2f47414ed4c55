"""EvalConfig: pppbot eval's flags as one checked value, without ROS."""
from __future__ import annotations

import argparse
import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from pppbot_bringup.parameter_files import map_free_navigation_problem
from pppbot_common.errors import ArgumentError
from pppbot_common.param_files import check_parameter_file, node_parameters
from pppbot_eval.config import EvalConfig, ScoredParameters, map_free_params
from pppbot_eval.ros.cli import add_arguments
from pppbot_eval.scenarios import Scenario

MAX_SLIP = 0.05
ROOT = Path(__file__).resolve().parents[2]


def flags(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    return parser.parse_args(list(argv))


def test_every_flag_of_the_command_line_is_a_field():
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    assert {a.dest for a in parser._actions} - {"help"} == {f.name for f in dataclasses.fields(EvalConfig)}


@pytest.mark.parametrize("argv, rtf", [(["slam"], 0.0), (["slam", "--no-lockstep"], 3.0),
                                       (["navigation", "--no-lockstep"], 1.0),
                                       (["slam", "--no-lockstep", "--real-time-factor", "5"], 5.0)])
def test_the_real_time_factor_default_depends_on_lockstep_and_scenario(argv: list[str], rtf: float):
    config = EvalConfig.from_flags(flags(*argv), MAX_SLIP)
    assert config.real_time_factor == rtf and config.scenario is Scenario(argv[0])


def test_flags_become_typed_values():
    config = EvalConfig.from_flags(flags("navigation", "--start", "1", "2", "0.5", "--map", "m.yaml",
                                         "--goals", "3"), MAX_SLIP)
    assert config.start == (1.0, 2.0, 0.5) and config.map == Path("m.yaml") and config.goals == 3
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.goals = 4  # type: ignore[misc]  # the point: it is frozen


@pytest.mark.parametrize("argv, words", [
    (["slam", "--real-time-factor", "-1"], "--real-time-factor -1.0: must be in [0, 1000]"),
    (["slam", "--speed", "3"], "--speed 3.0: must be in (0, 2] m/s"),
    (["slam", "--wheel-slip", "0.2"], "--wheel-slip 0.2: must be in [0, 0.05]"),
    (["slam", "--map-pose", "0", "nan", "0"], "--map-pose 0.0 nan 0.0: must be three finite numbers"),
    (["navigation", "--start", "inf", "0", "0"], "--start inf 0.0 0.0: must be three finite numbers"),
    (["map"], "--map: the map scenario needs it"),
    (["slam", "--map", "m.yaml"], "--map: only the map, localization and navigation scenarios take it, not slam"),
    (["navigation", "--goals", "0"], "--goals 0: must be at least 1"),
    (["navigation", "--goal-distance", "-1"], "--goal-distance -1.0: must be a non-negative number"),
    (["navigation", "--min-success-rate", "1.5"], "--min-success-rate 1.5: must be in [0, 1]"),
    (["slam", "--seed", "-3"], "--seed -3: must be a non-negative integer"),
    (["slam", "--timeout", "0"], "--timeout 0.0: must be a positive number of sim seconds"),
    (["localization", "--no-map"], "--no-map: only the navigation scenario takes it, not localization"),
    (["slam", "--goal", "1", "2", "0"], "--goal: only the navigation scenario takes it, not slam"),
    (["slam", "--through-poses"], "--through-poses: only the navigation scenario takes it"),
    (["navigation", "--goal", "1", "nan", "0"], "--goal 1.0 nan 0.0: must be three finite numbers"),
    (["navigation", "--no-map", "--map", "m.yaml"], "--map and --no-map: a run navigates on a map or without one"),
])
def test_a_bad_flag_is_refused_naming_it_its_value_and_the_rule(argv: list[str], words: str):
    with pytest.raises(ArgumentError) as caught:
        EvalConfig.from_flags(flags(*argv), MAX_SLIP)
    assert words in str(caught.value)


def test_a_config_made_in_code_is_checked_the_same_way():
    assert math.isclose(EvalConfig(Scenario.DRIVE, speed=0.5).checked(MAX_SLIP).speed, 0.5)
    with pytest.raises(ArgumentError, match="--speed 0"):
        EvalConfig(Scenario.DRIVE, speed=0.0).checked(MAX_SLIP)


def test_map_free_parameters_navigate_in_odom_and_the_bringup_takes_them(tmp_path: Path):
    default = ROOT / "config" / "nav2_params.yaml"
    problem = map_free_navigation_problem(default)
    assert problem is not None
    for words in ("bt_navigator global_frame: map (not odom)", "global_costmap/global_costmap rolling_window: False",
                  "global_costmap plugins include static_layer"):
        assert words in problem
    made = map_free_params(default, tmp_path / "free.yaml", 24)
    assert map_free_navigation_problem(made) is None
    nodes = check_parameter_file(made)
    costmap = node_parameters(nodes, "/global_costmap/global_costmap")
    assert (costmap["width"], costmap["height"], costmap["plugins"]) == (24, 24, ["obstacle_layer", "inflation_layer"])
    assert "static_layer.plugin" not in costmap and costmap["obstacle_layer.scan.topic"] == "/scan"
    # What the score reads is unchanged: the stack and the scoring agree whichever file runs.
    assert ScoredParameters.read(made).max_speed_mps == ScoredParameters.read(default).max_speed_mps
    assert node_parameters(nodes, "/controller_server") == node_parameters(check_parameter_file(default),
                                                                           "/controller_server")


def test_a_static_layer_is_known_by_its_plugin_type_whatever_its_name(tmp_path: Path):
    text = (ROOT / "config" / "nav2_params.yaml").read_text().replace('"static_layer"', '"map_layer"').replace(
        "      static_layer:\n", "      map_layer:\n")
    renamed = tmp_path / "renamed.yaml"
    renamed.write_text(text)
    assert "global_costmap plugins include map_layer" in (map_free_navigation_problem(renamed) or "")
    made = map_free_params(renamed, tmp_path / "free.yaml", 20)
    assert map_free_navigation_problem(made) is None
    costmap = node_parameters(check_parameter_file(made), "/global_costmap/global_costmap")
    assert costmap["plugins"] == ["obstacle_layer", "inflation_layer"] and "map_layer.plugin" not in costmap


def test_one_goal_must_be_reachable_and_without_a_map_within_the_rolling_windows_reach():
    from pppbot_common.maps import FREE, OCCUPIED, OccupancyGrid
    from pppbot_eval.ros.cli import MAX_WINDOW_M, _one_goal

    data = np.full((40, 800), FREE, dtype=np.int8)  # a hall 40 m long, 2 m wide at 0.05 m, walled
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = OCCUPIED
    data[:, 400] = OCCUPIED  # a wall across it at x = 20 m
    hall = OccupancyGrid(data, 0.05, origin=(-1.0, -1.0, 0.0))
    free = EvalConfig.from_flags(flags("navigation", "--no-map", "--goal", "15", "0", "0"), MAX_SLIP)
    assert _one_goal((15.0, 0.0, 0.0), free, hall) == (15.0, 0.0, 0.0)
    with pytest.raises(ArgumentError, match=r"goal \(25, 0\): ppp_bot cannot reach it from the start \(0, 0\)"):
        _one_goal((25.0, 0.0, 0.0), free, hall)
    data[:, 400] = FREE
    far = (MAX_WINDOW_M / 2 + 1.0, 0.0, 0.0)
    with pytest.raises(ArgumentError, match=f"at most {MAX_WINDOW_M} m across"):
        _one_goal(far, free, OccupancyGrid(data, 0.05, origin=(-1.0, -1.0, 0.0)))
    on_map = EvalConfig.from_flags(flags("navigation", "--goal", "29", "0", "0"), MAX_SLIP)
    assert _one_goal(far, on_map, OccupancyGrid(data, 0.05, origin=(-1.0, -1.0, 0.0))) == far  # a map has no window
