"""Nav2's action and service nodes against fake servers: the goal each sends (from its ports),
what it answers while the goal runs and when it ends, its outputs, and what halting it cancels."""
from __future__ import annotations

import sys
from pathlib import Path as FilePath
from typing import Any

import pytest
from geometry_msgs.msg import PoseStamped
from nav2_msgs.action import ComputePathToPose, FollowPath, Spin, Wait
from nav2_msgs.srv import ClearCostmapAroundRobot
from nav_msgs.msg import Path

from pppbot_nav.bt.ports import PORTS_KEY, GoalStatus
from pppbot_nav.bt.tree import Blackboard, Status
from pppbot_nav.bt.xml_tree import TreeFactory
from pppbot_nav.errors import BehaviorTreeError
from pppbot_nav.ros.bt.nav2_actions import NAV2_ACTION_NODES, RECOVERIES_KEY, duration_s

sys.path.insert(0, str(FilePath(__file__).parent))
from bt_fakes import FakeAction, FakePorts  # noqa: E402

S, F, R = Status.SUCCESS, Status.FAILURE, Status.RUNNING


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def pose(x: float, y: float) -> PoseStamped:
    msg = PoseStamped()
    msg.header.frame_id = "map"
    msg.pose.position.x, msg.pose.position.y = x, y
    return msg


def path_to(*xs: float) -> Path:
    msg = Path()
    msg.header.frame_id = "map"
    msg.poses = [pose(x, 0.0) for x in xs]
    return msg


def load(body: str, ports: FakePorts, clock: Clock | None = None, **entries: Any) -> Any:
    board = Blackboard()
    board.set(PORTS_KEY, ports)
    board.set("server_timeout", 100.0)
    for key, value in entries.items():
        board.set(key, value)
    xml = f'<root BTCPP_format="4"><BehaviorTree ID="Main">{body}</BehaviorTree></root>'
    return TreeFactory(NAV2_ACTION_NODES).load(xml, name="nav.xml", clock=clock or Clock(), blackboard=board)


def test_compute_path_to_pose_sends_the_goal_runs_until_the_result_and_writes_the_path():
    ports = FakePorts()
    tree = load('<ComputePathToPose goal="{goal}" path="{path}" planner_id="GridBased" '
                'error_code_id="{code}" error_msg="{msg}"/>', ports, goal=pose(3.0, 1.0))
    assert tree.tick_once() is R
    planner = ports.actions["compute_path_to_pose"]
    sent = planner.last.goal
    assert (sent.goal.pose.position.x, sent.planner_id, sent.use_start) == (3.0, "GridBased", False)
    assert tree.tick_once() is R  # the server has not answered
    planner.last.end(GoalStatus.SUCCEEDED, planner.result(path=path_to(0.0, 1.0, 3.0)))
    assert tree.tick_once() is S
    board = tree.blackboard
    assert [p.pose.position.x for p in board.get("path").poses] == [0.0, 1.0, 3.0]
    assert (board.get("code"), board.get("msg")) == (0, "")
    assert len(planner.goals) == 1


def test_an_aborted_plan_fails_with_the_servers_error_code_and_message_and_an_empty_path():
    ports = FakePorts()
    tree = load('<ComputePathToPose goal="{goal}" start="{start}" path="{path}" error_code_id="{code}" '
                'error_msg="{msg}"/>', ports, goal=pose(3.0, 1.0), start=pose(1.0, 1.0), path=path_to(0.0))
    tree.tick_once()
    planner = ports.actions["compute_path_to_pose"]
    assert planner.last.goal.use_start and planner.last.goal.start.pose.position.x == 1.0
    planner.last.end(GoalStatus.ABORTED, planner.result(error_code=ComputePathToPose.Result.NO_VALID_PATH,
                                                        error_msg="no path"))
    assert tree.tick_once() is F
    board = tree.blackboard
    assert (board.get("code"), board.get("msg"), board.get("path").poses) == (
        ComputePathToPose.Result.NO_VALID_PATH, "no path", [])


def test_a_canceled_goal_succeeds_as_nav2s_default():
    ports = FakePorts()
    tree = load('<Spin spin_dist="1.0"/>', ports)
    tree.tick_once()
    ports.actions["spin"].last.end(GoalStatus.CANCELED, Spin.Result())
    assert tree.tick_once() is S


def test_a_goal_the_server_does_not_acknowledge_within_server_timeout_fails_and_a_refused_one_at_once():
    clock = Clock()
    ports = FakePorts()
    ports.actions["wait"] = FakeAction(Wait, auto_accept=False)
    tree = load('<Wait wait_duration="2" server_timeout="50"/>', ports, clock)
    assert tree.tick_once() is R
    clock.now = 0.049
    assert tree.tick_once() is R
    clock.now = 0.05
    assert tree.tick_once() is F
    assert ports.actions["wait"].last.canceled  # should the server take it late, it is canceled
    tree.halt()
    assert tree.tick_once() is R  # a new goal
    ports.actions["wait"].last.refuse()
    assert tree.tick_once() is F
    assert [duration_s(call.goal.time) for call in ports.actions["wait"].goals] == [2.0, 2.0]


def test_follow_path_sends_a_new_path_as_a_new_goal_and_halting_it_cancels_the_goal():
    ports = FakePorts()
    tree = load('<FollowPath path="{path}" controller_id="FollowPath" goal_checker_id="general_goal_checker"/>',
                ports, path=path_to(0.0, 1.0))
    assert tree.tick_once() is R
    controller = ports.actions["follow_path"]
    assert tree.tick_once() is R and len(controller.goals) == 1  # the same path: nothing sent
    tree.blackboard.set("path", path_to(0.0, 2.0))
    assert tree.tick_once() is R
    assert [[p.pose.position.x for p in call.goal.path.poses] for call in controller.goals] == [[0.0, 1.0], [0.0, 2.0]]
    assert controller.last.goal.goal_checker_id == "general_goal_checker"
    tree.halt()
    assert controller.last.canceled and not controller.goals[0].canceled  # only the goal that runs


def test_a_behaviour_run_as_a_recovery_counts_in_number_recoveries():
    ports = FakePorts()
    tree = load('<Sequence><BackUp backup_dist="0.3" backup_speed="0.05"/>'
                '<Spin spin_dist="1.57" time_allowance="7" is_recovery="false"/></Sequence>', ports)
    tree.tick_once()
    backup = ports.actions["backup"]
    assert (backup.last.goal.target.x, backup.last.goal.speed) == pytest.approx((0.3, 0.05))
    backup.last.end(GoalStatus.SUCCEEDED, backup.result())
    tree.tick_once()
    spin = ports.actions["spin"].last.goal
    assert spin.target_yaw == pytest.approx(1.57) and duration_s(spin.time_allowance) == 7.0
    assert tree.blackboard.get(RECOVERIES_KEY) == 1  # the spin was not a recovery


def test_a_failed_behaviour_says_why():
    ports = FakePorts()
    tree = load('<Spin error_code_id="{code}" error_msg="{msg}"/>', ports)
    tree.tick_once()
    spin = ports.actions["spin"]
    spin.last.end(GoalStatus.ABORTED, spin.result(error_code=Spin.Result.COLLISION_AHEAD, error_msg="a wall"))
    assert tree.tick_once() is F
    assert (tree.blackboard.get("code"), tree.blackboard.get("msg")) == (Spin.Result.COLLISION_AHEAD, "a wall")


def test_the_server_name_port_picks_the_server():
    ports = FakePorts()
    load('<FollowPath path="{path}" server_name="other_controller"/>', ports, path=path_to(0.0)).tick_once()
    assert list(ports.actions) == ["other_controller"] and ports.actions["other_controller"].action_type is FollowPath


def test_service_nodes_call_once_and_succeed_on_the_response_or_fail_after_server_timeout():
    clock = Clock()
    ports = FakePorts()
    tree = load('<ClearCostmapAroundRobot service_name="local_costmap/clear_around_local_costmap" '
                'reset_distance="2.5"/>', ports, clock)
    assert tree.tick_once() is S
    service = ports.services["local_costmap/clear_around_local_costmap"]
    assert service.service_type is ClearCostmapAroundRobot and service.calls[0].request.reset_distance == 2.5
    silent = FakePorts()
    silent.service("global_costmap/clear_entirely_global_costmap", object).answer = None
    tree = load('<ClearEntireCostmap service_name="global_costmap/clear_entirely_global_costmap"/>', silent, clock)
    assert tree.tick_once() is R
    clock.now = 0.1
    assert tree.tick_once() is F


def test_cancel_nodes_cancel_every_goal_of_their_server():
    ports = FakePorts()
    load('<Sequence><FollowPath path="{path}"/></Sequence>', ports, path=path_to(0.0)).tick_once()
    assert load("<CancelControl/>", ports).tick_once() is S
    assert ports.actions["follow_path"].cancel_all_calls == 1 and ports.actions["follow_path"].last.canceled


def test_a_tree_without_ports_says_what_it_needs():
    xml = '<root BTCPP_format="4"><BehaviorTree ID="Main"><Spin/></BehaviorTree></root>'
    tree = TreeFactory(NAV2_ACTION_NODES).load(xml, name="nav.xml")
    with pytest.raises(BehaviorTreeError, match=r"needs the navigator's ports \(blackboard entry 'ports'\)"):
        tree.tick_once()


def test_a_wait_of_a_negative_time_waits_its_opposite_and_one_not_a_number_is_refused():
    ports = FakePorts()
    load('<Wait wait_duration="-1.5"/>', ports).tick_once()
    assert duration_s(ports.actions["wait"].last.goal.time) == 1.5
    with pytest.raises(BehaviorTreeError, match=r"Wait 'Wait': wait_duration = nan: a finite number"):
        load('<Wait wait_duration="nan"/>', FakePorts()).tick_once()


def test_a_pipeline_ticks_a_finished_plan_again_and_it_answers_its_end_without_planning_again():
    ports = FakePorts()
    tree = load('<PipelineSequence><ComputePathToPose goal="{goal}" path="{path}"/><FollowPath path="{path}"/>'
                "</PipelineSequence>", ports, goal=pose(3.0, 1.0))
    assert tree.tick_once() is R
    planner = ports.actions["compute_path_to_pose"]
    planner.last.end(GoalStatus.SUCCEEDED, planner.result(path=path_to(0.0, 3.0)))
    assert [tree.tick_once(), tree.tick_once(), tree.tick_once()] == [R, R, R]
    assert len(planner.goals) == 1 and len(ports.actions["follow_path"].goals) == 1


def test_a_literal_on_an_output_port_is_refused_at_load():
    with pytest.raises(BehaviorTreeError, match=r"^nav\.xml:1: ComputePathToPose 'ComputePathToPose': output port "
                                                r"'path' must name a blackboard entry \(\{key\}\), not 'path'$"):
        load('<ComputePathToPose goal="{goal}" path="path"/>', FakePorts())
