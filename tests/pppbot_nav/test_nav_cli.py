"""``./pppbot nav goto`` against a navigate_to_pose server over DDS: progress to success, and a refusal explained."""
from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

PPPBOT = str(Path(__file__).resolve().parents[2] / "pppbot")

pytestmark = pytest.mark.ros


def goto(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([PPPBOT, "nav", "goto", *args], capture_output=True, text=True, timeout=120)


def test_a_goal_is_followed_to_its_end(spawn, python_script):
    spawn(python_script("navigate_to_pose_server.py"), name="nav_server").wait_for_output("ready", 30)
    done = goto("2.0", "1.0", "0.0")
    assert done.returncode == 0, done.stderr
    assert "navigating to (2.0, 1.0, 0.0) in 'map'" in done.stdout
    assert done.stdout.rstrip().endswith("goal succeeded")


def test_a_refused_goal_says_the_navigator_takes_goals_only_while_active(spawn, python_script):
    spawn(python_script("navigate_to_pose_server.py", "--reject"), name="nav_server").wait_for_output("ready", 30)
    done = goto("2.0", "1.0", "0.0")
    assert done.returncode == 1
    assert "bt_navigator refused the goal; it takes goals only while active" in done.stderr
