"""A robot that tips over is named, not scored: the simulator reports it in its log and on
/diagnostics, the navigator ends a goal with it, and an evaluation fails with it as the reason."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
from action_msgs.msg import GoalStatus
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from nav2_msgs.action import NavigateToPose
from rclpy.action import ActionClient
from sensor_msgs.msg import JointState

from pppbot_common.ros.wait import send_goal, wait_until

pytestmark = pytest.mark.ros
ROOT = Path(__file__).resolve().parents[2]
PPPBOT = str(ROOT / "pppbot")
#: ppp_bot on a 0.5 m stage 2 m across: driving forward from its middle takes it over the edge.
STAGE = """<?xml version="1.0"?>
<sdf version="1.9"><world name="stage">
  <physics name="1ms" type="ignored"><max_step_size>0.002</max_step_size></physics>
  <model name="ground_plane"><static>true</static><link name="link"><collision name="c">
    <geometry><plane><normal>0 0 1</normal><size>40 40</size></plane></geometry></collision></link></model>
  <model name="stage"><static>true</static><pose>0 0 0.25 0 0 0</pose><link name="l"><collision name="c">
    <geometry><box><size>2 2 0.5</size></box></geometry></collision></link></model>
  <model name="walls"><static>true</static><link name="l">
    <collision name="n"><pose>0 4 1 0 0 0</pose><geometry><box><size>8 0.2 2</size></box></geometry></collision>
    <collision name="s"><pose>0 -4 1 0 0 0</pose><geometry><box><size>8 0.2 2</size></box></geometry></collision>
    <collision name="e"><pose>4 0 1 0 0 0</pose><geometry><box><size>0.2 8 2</size></box></geometry></collision>
    <collision name="w"><pose>-4 0 1 0 0 0</pose><geometry><box><size>0.2 8 2</size></box></geometry></collision>
  </link></model>
</world></sdf>
"""


@pytest.fixture
def stage(tmp_path: Path) -> Path:
    path = tmp_path / "stage.sdf"
    path.write_text(STAGE)
    (tmp_path / "stage.routes.yaml").write_text(
        "routes:\n  off_the_edge:\n    start: {x: 0.0, y: 0.0, yaw: 0.0}\n    waypoints: [[3.0, 0.0]]\n")
    return path


def test_simulator_reports_the_tip_on_diagnostics_and_in_its_log(ros_node, spawn, stage: Path) -> None:
    sim = spawn([PPPBOT, "run", "pppbot_sim", "simulator", "--ros-args", "-p", f"world:={stage}",
                 "-p", "real_time_factor:=3.0", "-p", "command_timeout:=0.0"], name="simulator")
    sim.wait_for_output(r"spawned at x=0.0 y=0.0 z=0.55", 30)  # put down on the stage, not in it
    statuses: list[DiagnosticStatus] = []
    ros_node.create_subscription(DiagnosticArray, "/diagnostics", lambda m: statuses.extend(m.status), 10)
    wait_until(lambda: statuses, 10, "a first /diagnostics", node=ros_node)
    assert (statuses[0].name, statuses[0].level, statuses[0].message) == ("ppp_bot: upright", DiagnosticStatus.OK,
                                                                          "upright")
    commands = ros_node.create_publisher(JointState, "/joint_commands", 10)
    forward = JointState(name=["left_wheel_joint", "right_wheel_joint"], velocity=[10.0, 10.0])
    tipped = wait_until(lambda: commands.publish(forward) or next(
        (s for s in statuses if s.level == DiagnosticStatus.ERROR), None), 30, "the tip reported", node=ros_node)
    assert tipped.message == "tipped over (beyond 0.5 rad)" and tipped.hardware_id == "ppp_bot"
    assert abs(float({v.key: v.value for v in tipped.values}["pitch"])) > 0.5
    sim.wait_for_output(r"robot 'ppp_bot' tipped over \(beyond 0.5 rad\) \(roll .* pitch .*\)", 10)
    assert sim.output.count("tipped over (beyond") == 1  # one tip, said once
    assert sim.running() and "Traceback" not in sim.output  # the report never ends the simulator


def test_navigator_ends_a_goal_when_the_robot_is_not_upright(ros_node, spawn) -> None:
    spawn([PPPBOT, "run", "pppbot_nav", "bt_navigator"], name="bt_navigator")
    spawn([PPPBOT, "run", "pppbot_nav", "lifecycle_manager", "--ros-args", "-p", "node_names:=[bt_navigator]",
           "-p", "autostart:=true"], name="lifecycle_manager").wait_for_output("Managed nodes are active", 60)
    diagnostics = ros_node.create_publisher(DiagnosticArray, "/diagnostics", 10)
    report = DiagnosticArray(status=[DiagnosticStatus(level=DiagnosticStatus.ERROR, name="ppp_bot: upright",
                                                      message="tipped over (beyond 0.5 rad)")])
    wait_until(lambda: diagnostics.get_subscription_count() > 0, 10, "the navigator on /diagnostics", node=ros_node)
    diagnostics.publish(report)
    client = ActionClient(ros_node, NavigateToPose, "navigate_to_pose")
    assert client.wait_for_server(timeout_sec=20)
    goal = PoseStamped()
    goal.header.frame_id = "map"
    goal.pose.orientation.w = 1.0
    handle = send_goal(client, NavigateToPose.Goal(pose=goal), ros_node)
    done = handle.get_result_async()
    wait_until(done.done, 20, "the goal's end", node=ros_node)
    assert done.result().status == GoalStatus.STATUS_ABORTED
    assert done.result().result.error_msg == "ppp_bot is not upright: tipped over (beyond 0.5 rad)"


def test_eval_fails_a_run_whose_robot_tips_over(spawn, stage: Path, tmp_path: Path) -> None:
    out = tmp_path / "report"
    child = spawn([PPPBOT, "eval", "drive", "--world", str(stage), "--out", str(out), "--json", "--no-view",
                   "--timeout", "60"], name="eval")
    code = child.wait(timeout_s=240)
    report = json.loads(child.output.strip().splitlines()[-1])
    assert code == 1 and report["ok"] is False
    assert report["failure"].startswith("the robot is not upright: tipped over (beyond 0.5 rad)"), report["failure"]
