"""``./pppbot nav goto`` against a navigate_to_pose server over DDS: progress to success, and a refusal explained."""
from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
from nav2_msgs.action import NavigateToPose

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


def feedback(distance_m: float, seconds: int, recoveries: int = 0) -> NavigateToPose.Feedback:
    fb = NavigateToPose.Feedback(distance_remaining=distance_m, number_of_recoveries=recoveries)
    fb.navigation_time.sec = seconds
    return fb


def test_progress_says_nothing_stale_waits_for_the_plan_then_follows(monkeypatch):
    from pppbot_nav.ros import nav_cli

    clock = [100.0]
    monkeypatch.setattr(nav_cli.time, "monotonic", lambda: clock[0])
    lines: list[str] = []
    progress = nav_cli.Progress(lines.append)
    progress.feedback(feedback(0.0, 0))  # before the goal was accepted: nothing (was "0.00 m to go")
    progress.accepted = True
    progress.feedback(feedback(0.0, 0))  # no plan yet, just sent: nothing
    clock[0] += 1.0
    progress.feedback(feedback(0.0, 1))
    clock[0] += 1.0
    progress.feedback(feedback(2.5, 2))
    clock[0] += 0.3
    progress.feedback(feedback(2.4, 2))  # within the second: not printed
    progress.feedback(feedback(2.4, 2, recoveries=1))  # a recovery: at once
    assert lines == ["waiting for a plan (1 s): the planner has not answered yet",
                     "at (0.00, 0.00), 2.50 m to go, 2 s, 0 recoveries",
                     "recovery 1 started, 2.40 m to go",
                     "at (0.00, 0.00), 2.40 m to go, 2 s, 1 recoveries"]
