"""The BasicNavigator examples against a running stack: each script in ``examples/`` is run as a
user runs it (``python examples/<script>.py``), in the order a session would, against one
``launch_sim world:=room localization:=true``; each must exit 0 and say what it did.

The scripts make nav2_simple_commander's calls in its order (``waitUntilNav2Active``: the
localizer's and the navigator's ``get_state``, the initial pose until an ``amcl_pose``; then the
task's action or service by Nav2's name), through Nav2's own ``BasicNavigator`` where installed
and ``examples/robot_navigator.py`` (the same calls) here.
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from nav_msgs.msg import Odometry

from pppbot_common.dds_participants import participant_ids
from pppbot_common.ros.wait import wait_for_messages

ROOT = Path(__file__).resolve().parents[2]
PPPBOT = str(ROOT / "pppbot")
EXAMPLES = ROOT / "examples"

pytestmark = [pytest.mark.ros, pytest.mark.heavy]


@pytest.fixture(scope="module")
def stack(module_spawn: Any) -> Iterator[Any]:
    launch = module_spawn([PPPBOT, "launch_sim", "world:=room", "localization:=true", "use_teleop:=false",
                           "use_rviz:=false", "use_viz:=false", "lockstep:=true", "real_time_factor:=1.0"],
                          name="launch_sim")
    launch.wait_for_output(r"ppp_bot is up in 'room'", 120)
    yield launch


def run_example(name: str, *args: str, timeout_s: float = 300.0) -> str:
    """Run ``examples/<name>.py``; its output, once it exited 0."""
    try:
        done = subprocess.run([sys.executable, str(EXAMPLES / f"{name}.py"), *args], capture_output=True,
                              text=True, timeout=timeout_s, check=False)
    except subprocess.TimeoutExpired as exc:  # what it said, to see where it waited
        said = "".join(part.decode() if isinstance(part, bytes) else part for part in (exc.stdout, exc.stderr) if part)
        domain = int(os.environ.get("ROS_DOMAIN_ID", "0") or 0)
        pytest.fail(f"{name} did not end within {timeout_s:.0f} s (participant IDs in domain {domain}: "
                    f"{participant_ids(domain)}):\n"
                    f"{said[-3000:]}")
    output = done.stdout + done.stderr
    assert done.returncode == 0, f"{name} exited {done.returncode}:\n{output[-3000:]}"
    return output


def robot_xy(node: Any) -> tuple[float, float]:
    truth = wait_for_messages(node, Odometry, "/ground_truth/odom", 1, timeout_s=10)[-1]
    return truth.pose.pose.position.x, truth.pose.pose.position.y


def test_go_to_a_pose(stack, ros_node):
    output = run_example("example_nav_to_pose")
    assert "Nav2 is ready for use!" in output and "result: SUCCEEDED" in output
    assert re.search(r"distance remaining: \d+\.\d\d m", output)
    x, y = robot_xy(ros_node)
    assert abs(x - 1.5) < 0.35 and abs(y - 0.5) < 0.35


def test_go_through_poses(stack, ros_node):
    output = run_example("example_nav_through_poses")
    assert "result: SUCCEEDED" in output and "poses remaining: 2" in output
    x, y = robot_xy(ros_node)
    assert abs(x + 1.0) < 0.35 and abs(y + 0.5) < 0.35


def test_follow_waypoints(stack, ros_node):
    output = run_example("example_waypoint_follower")
    assert "result: SUCCEEDED" in output and "missed waypoints: []" in output
    assert "executing waypoint 3/3" in output or "executing waypoint 2/3" in output
    x, y = robot_xy(ros_node)
    assert abs(x) < 0.35 and abs(y) < 0.35  # the last waypoint: back at the start


def test_spin_back_up_and_drive_on_heading(stack):
    output = run_example("example_behaviors")
    assert output.count("result: SUCCEEDED") == 3


def test_get_a_path_through_poses_and_smooth_it(stack):
    output = run_example("example_get_path")
    lengths = {name: float(m) for name, m in re.findall(r"^(path|path through poses|smoothed path): \d+ poses, "
                                                          r"(\d+\.\d+) m", output, re.MULTILINE)}
    assert set(lengths) == {"path", "path through poses", "smoothed path"}, output
    assert 1.75 < lengths["path"] < 3.0  # (0, 0) → (-1.5, -1.0): 1.80 m straight
    assert lengths["path through poses"] > lengths["path"]  # by (1.5, 0.5) first
    assert abs(lengths["smoothed path"] - lengths["path"]) < 0.3


def test_get_the_costmaps_and_clear_them(stack):
    output = run_example("example_costmaps")
    found = dict(re.findall(r"^(global|local) costmap: (\d+ × \d+ cells of [\d.]+ m in '\w+')", output, re.MULTILINE))
    assert found["local"] == "100 × 100 cells of 0.05 m in 'odom'", output
    assert found["global"].endswith("in 'map'")
    lethal = re.search(r"global costmap: .* (\d+) lethal", output)
    assert lethal is not None and int(lethal.group(1)) > 0  # the room's walls
    assert "costmaps cleared" in output


def test_change_the_map(stack):
    assert "map changed to" in run_example("example_change_map", str(ROOT / "maps" / "room.yaml"))
    missing = subprocess.run([sys.executable, str(EXAMPLES / "example_change_map.py"), "/nowhere/map.yaml"],
                             capture_output=True, text=True, timeout=120, check=False)
    assert missing.returncode == 1 and "map not changed" in missing.stdout
