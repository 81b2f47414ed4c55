"""`./pppbot` dispatch, `run` and `topic list/info/echo/hz` against live publishers."""
from __future__ import annotations

import os
import re
import subprocess
from pathlib import Path

import pytest
import yaml

pytestmark = pytest.mark.ros

PPPBOT = str(Path(__file__).resolve().parents[2] / "pppbot")


def pppbot(*args: str, timeout_s: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run([PPPBOT, *args], capture_output=True, text=True, timeout=timeout_s)


@pytest.fixture
def talker(spawn, python_script):
    child = spawn(python_script("publish_tf_and_particles.py", "20"), name="talker")
    child.wait_for_output(r"^ready$", timeout_s=20)
    return child


def test_help_lists_verbs():
    result = pppbot("--help")
    assert result.returncode == 0
    for verb in ("run", "topic", "teleop", "launch_sim", "bag", "eval", "nav", "map_saver", "setup", "env"):
        assert re.search(rf"^\s+{verb}\s", result.stdout, re.M), verb


def test_unknown_verb_fails_with_choices():
    result = pppbot("flyaway")
    assert result.returncode == 2
    assert "invalid choice: 'flyaway'" in result.stderr


def test_env_runs_a_command_in_the_environment():
    result = pppbot("env", "python", "-c", "import tf2_msgs.msg, nav2_msgs.action, rclpy, mujoco; print('ok')")
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "ok"


def test_run_reports_missing_package_and_executable():
    result = pppbot("run", "no_such_pkg", "x")
    assert result.returncode == 1 and "package 'no_such_pkg' not found" in result.stderr
    result = pppbot("run", "pppbot_bringup", "nope")
    assert result.returncode == 1
    assert "no executable 'nope' in package 'pppbot_bringup' (it has: launch_sim, pppbot)" in result.stderr


def test_run_executes_a_package_executable():
    result = pppbot("run", "pppbot_bringup", "pppbot", "topic", "--help")
    assert result.returncode == 0, result.stderr
    assert "usage: pppbot topic" in result.stdout


def test_topic_list_shows_a_live_topic(talker):
    result = pppbot("topic", "list", "-t")
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert "/tf [tf2_msgs/msg/TFMessage]" in lines
    assert "/particle_cloud [nav2_msgs/msg/ParticleCloud]" in lines


def test_topic_list_without_publishers_lacks_the_topic():
    result = pppbot("topic", "list")
    assert result.returncode == 0
    lines = result.stdout.splitlines()
    assert "/parameter_events" in lines  # the list works (its own node's topic) ...
    assert "/particle_cloud" not in lines  # ... and has nobody else's


def test_topic_info_counts_publishers(talker):
    result = pppbot("topic", "info", "/particle_cloud", "-v")
    assert result.returncode == 0, result.stderr
    assert "Type: nav2_msgs/msg/ParticleCloud" in result.stdout
    assert "Publisher count: 1" in result.stdout
    assert "Node name: tf_particle_talker" in result.stdout


def test_topic_echo_once_prints_yaml(talker):
    result = pppbot("topic", "echo", "/tf", "--once")
    assert result.returncode == 0, result.stderr
    body, sep, _ = result.stdout.partition("---\n")
    assert sep
    data = yaml.safe_load(body)
    (transform,) = data["transforms"]
    assert transform["header"]["frame_id"] == "odom"
    assert transform["child_frame_id"] == "base_link"
    assert transform["transform"]["translation"]["x"] == pytest.approx(0.01 * transform["header"]["stamp"]["nanosec"])


def test_topic_echo_field(talker):
    result = pppbot("topic", "echo", "/particle_cloud", "--once", "--field", "header.frame_id")
    assert result.returncode == 0, result.stderr
    assert result.stdout == "map\n---\n"


def test_topic_echo_unknown_topic_without_type_says_how(talker):
    result = pppbot("topic", "echo", "/nobody", "--spin-time", "1")
    assert result.returncode == 1
    assert "give it: pppbot topic echo /nobody <package/msg/Type>" in result.stderr


def test_topic_hz_measures_the_rate(spawn, talker):
    hz = spawn([PPPBOT, "topic", "hz", "/tf"], name="hz")
    reports = hz.wait_for_lines(r"average rate: ([\d.]+)", count=3, timeout_s=30)
    # The talker publishes at 20 Hz; the first report may cover a partial second.
    assert 15.0 < float(reports[-1].group(1)) < 25.0
    assert re.search(r"min: [\d.]+s max: [\d.]+s std dev: [\d.]+s window: \d+", hz.output)


def test_a_design_verb_not_built_yet_says_so_instead_of_pretending(monkeypatch, capsys):
    from pppbot_bringup import cli

    monkeypatch.setitem(cli.NOT_YET, "fly", "flying over the map")
    assert cli.main(["fly", "--high"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and "pppbot fly: flying over the map is not built yet in this checkout" in err


def test_map_saver_is_a_verb_and_an_executable_of_pppbot_nav():
    result = pppbot("map_saver", "--help")
    assert result.returncode == 0, result.stderr
    assert "usage: pppbot map_saver [-h] [-f PATH] [-t MAP_TOPIC] [--occ T] [--free T]" in result.stdout
    result = pppbot("run", "pppbot_nav", "map_saver_cli", "--help")  # Nav2's name, for `ros2 run`
    assert result.returncode == 0, result.stderr
    assert "usage: map_saver_cli [-h] [-f PATH]" in result.stdout


@pytest.mark.parametrize("args, message", [
    (["--goals", "0"], "--goals 0: must be at least 1"),
    (["--goal-distance", "100"], "no goal candidate is 100.0 m from (0.00, 0.00) m"),
    (["--start", "9.5", "0", "0"], "start (9.5, 0.0) m is not in free space"),  # in the room's east wall
    (["--min-success-rate", "1.5"], "--min-success-rate 1.5: must be in [0, 1]"),
])
def test_eval_navigation_refuses_bad_goal_arguments_before_starting_anything(tmp_path, args, message):
    result = pppbot("eval", "navigation", "--world", "room", "--out", str(tmp_path / "out"), *args)
    assert result.returncode == 2, result.stderr
    assert message in result.stderr and result.stdout == ""
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("value", ["233", "-1", "seven"])
def test_a_domain_id_dds_cannot_use_is_refused_by_name(value):
    result = subprocess.run([PPPBOT, "topic", "list"], capture_output=True, text=True, timeout=60,
                            env={**os.environ, "ROS_DOMAIN_ID": value})
    assert result.returncode == 2
    assert f"ROS_DOMAIN_ID='{value}' must be a whole number from 0 to 232" in result.stderr
    assert result.stdout == ""
