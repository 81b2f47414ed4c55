"""Nav2's conditions, path nodes, selectors and decorators against fake TF, topics and services:
what each answers as the robot moves, the goal changes and the clock runs, with Nav2 Jazzy's
ports and defaults."""
from __future__ import annotations

import sys
from pathlib import Path as FilePath
from typing import Any

import pytest
from geometry_msgs.msg import PoseStamped
from nav2_msgs.action import ComputePathToPose, FollowPath
from nav2_msgs.srv import IsPathValid
from nav_msgs.msg import Odometry, Path
from sensor_msgs.msg import BatteryState
from std_msgs.msg import String

from pppbot_common.se2 import yaw_from_quaternion
from pppbot_nav.bt.ports import PORTS_KEY
from pppbot_nav.bt.tree import Blackboard, NodeConfig, Status, TreeNode, input_port
from pppbot_nav.errors import BehaviorTreeError
from pppbot_nav.ros.bt.nav2 import nav2_factory

sys.path.insert(0, str(FilePath(__file__).parent))
from bt_fakes import FakePorts, FakeService  # noqa: E402

S, F, R = Status.SUCCESS, Status.FAILURE, Status.RUNNING
ROBOT = ("map", "base_link")


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


class Count(TreeNode):
    """A leaf that counts its ticks and answers ``answer`` (SUCCESS by default)."""

    PORTS = (input_port("answer", str, "SUCCESS"),)
    ticks = 0

    def __init__(self, name: str, config: NodeConfig | None = None) -> None:
        super().__init__(name, config)
        Count.ticks = 0

    def tick(self) -> Status:
        Count.ticks += 1
        return Status[self.get_input("answer")]


def pose(x: float, y: float = 0.0, stamp_s: float = 0.0) -> PoseStamped:
    msg = PoseStamped()
    msg.header.frame_id = "map"
    msg.header.stamp.sec, msg.header.stamp.nanosec = int(stamp_s), round((stamp_s % 1) * 1e9)
    msg.pose.position.x, msg.pose.position.y = x, y
    msg.pose.orientation.w = 1.0
    return msg


def path_of(*points: tuple[float, float]) -> Path:
    msg = Path()
    msg.header.frame_id = "map"
    msg.poses = [pose(x, y) for x, y in points]
    return msg


def load(body: str, ports: FakePorts | None = None, clock: Clock | None = None, **entries: Any) -> Any:
    board = Blackboard()
    board.set(PORTS_KEY, ports or FakePorts())
    for key, value in entries.items():
        board.set(key, value)
    xml = f'<root BTCPP_format="4"><BehaviorTree ID="Main">{body}</BehaviorTree></root>'
    return nav2_factory({"Count": Count}).load(xml, name="nav.xml", clock=clock or Clock(), blackboard=board)


# -- conditions ------------------------------------------------------------------------------------

def test_goal_updated_notices_a_new_goal_or_goals_after_its_first_tick():
    tree = load("<GoalUpdated/>", goal=pose(1.0))
    assert tree.tick_once() is F  # the first tick only looks
    assert tree.tick_once() is F
    tree.blackboard.set("goal", pose(2.0))
    assert tree.tick_once() is S
    assert tree.tick_once() is F
    tree.blackboard.set("goals", [pose(3.0)])
    assert tree.tick_once() is S


def test_global_updated_goal_succeeds_first_and_remembers_through_a_halt():
    tree = load("<GlobalUpdatedGoal/>", goal=pose(1.0))
    assert [tree.tick_once(), tree.tick_once()] == [S, F]
    tree.halt()
    assert tree.tick_once() is F  # what it saw outlived the halt
    tree.blackboard.set("goal", pose(1.5))
    assert tree.tick_once() is S


def test_goal_reached_within_the_navigators_tolerance_in_the_goals_frame():
    ports = FakePorts()
    tree = load('<GoalReached goal="{goal}"/>', ports, goal=pose(2.0, 1.0))
    assert tree.tick_once() is F  # no robot pose yet
    ports.poses[ROBOT] = (1.8, 1.0, 0.0)
    assert tree.tick_once() is S  # 0.2 m: within Nav2's 0.25
    ports.poses[ROBOT] = (1.7, 1.0, 0.0)
    assert tree.tick_once() is F
    tree.blackboard.set("goal_reached_tol", 0.5)
    assert tree.tick_once() is S


def test_is_path_valid_asks_the_planner_and_waits_for_its_answer():
    clock = Clock()
    ports = FakePorts()
    service = ports.services["is_path_valid"] = FakeService(IsPathValid)
    tree = load('<IsPathValid path="{path}" server_timeout="100"/>', ports, clock, path=path_of((0, 0), (1, 0)))
    assert tree.tick_once() is R
    assert len(service.calls[0].request.path.poses) == 2
    service.calls[0].respond(IsPathValid.Response(is_valid=False, invalid_pose_indices=[1]))
    assert tree.tick_once() is F
    assert tree.tick_once() is R
    service.calls[1].respond(IsPathValid.Response(is_valid=True))
    assert tree.tick_once() is S
    tree.tick_once()
    clock.now = 0.1
    assert tree.tick_once() is F  # no answer within server_timeout


def odometry(stamp_s: float, speed: float) -> Odometry:
    msg = Odometry()
    msg.header.stamp.sec, msg.header.stamp.nanosec = int(stamp_s), round((stamp_s % 1) * 1e9)
    msg.twist.twist.linear.x = speed
    return msg


def test_is_stuck_on_a_stop_harder_than_braking():
    ports = FakePorts()
    tree = load("<IsStuck/>", ports)
    ports.topics["odom"] = odometry(1.0, 0.5)
    assert tree.tick_once() is F
    ports.topics["odom"] = odometry(1.1, 0.4)  # 1 m/s²: braking
    assert tree.tick_once() is F
    ports.topics["odom"] = odometry(1.12, 0.0)  # 20 m/s²: hit something
    assert tree.tick_once() is S


def test_time_expired_and_distance_traveled_count_from_their_last_success():
    clock = Clock()
    tree = load('<TimeExpired seconds="1.0"/>', clock=clock)
    answers = []
    for now in (0.0, 0.5, 1.0, 1.5, 2.0):
        clock.now = now
        answers.append(tree.tick_once())
    assert answers == [F, F, S, F, S]
    ports = FakePorts()
    tree = load('<DistanceTraveled distance="1.0"/>', ports)
    answers = []
    for x in (0.0, 0.6, 1.0, 1.5, 2.1):
        ports.poses[ROBOT] = (x, 0.0, 0.0)
        answers.append(tree.tick_once())
    assert answers == [F, F, S, F, S]


def test_transform_available_once_and_for_good_and_both_frames_are_needed():
    ports = FakePorts()
    tree = load('<TransformAvailable child="laser" parent="base_link"/>', ports)
    assert tree.tick_once() is F
    ports.poses[("base_link", "laser")] = (0.1, 0.0, 0.0)
    assert tree.tick_once() is S
    del ports.poses[("base_link", "laser")]
    assert tree.tick_once() is S
    with pytest.raises(BehaviorTreeError, match=r"child and parent frames must both be named \(child = 'laser', "
                                                r"parent = ''\)"):
        load('<TransformAvailable child="laser"/>').tick_once()


def test_initial_pose_received_reads_the_blackboard_and_battery_conditions_the_newest_message():
    assert load("<InitialPoseReceived/>", initial_pose_received=False).tick_once() is F
    assert load("<InitialPoseReceived/>", initial_pose_received=True).tick_once() is S
    ports = FakePorts()
    low = load('<IsBatteryLow min_battery="0.2"/>', ports)
    assert low.tick_once() is F  # nothing heard
    ports.topics["/battery_status"] = BatteryState(percentage=0.15, voltage=11.0)
    assert low.tick_once() is S
    assert load('<IsBatteryLow min_battery="10.5" is_voltage="true"/>', ports).tick_once() is F
    charging = load("<IsBatteryCharging/>", ports)
    assert charging.tick_once() is F
    ports.topics["/battery_status"] = BatteryState(power_supply_status=BatteryState.POWER_SUPPLY_STATUS_CHARGING)
    assert charging.tick_once() is S


@pytest.mark.parametrize(("node", "code", "answer"), [
    ("WouldAPlannerRecoveryHelp", ComputePathToPose.Result.NO_VALID_PATH, S),
    ("WouldAPlannerRecoveryHelp", ComputePathToPose.Result.START_OCCUPIED, F),
    ("WouldAControllerRecoveryHelp", FollowPath.Result.FAILED_TO_MAKE_PROGRESS, S),
    ("WouldAControllerRecoveryHelp", FollowPath.Result.INVALID_PATH, F),
    ("WouldAControllerRecoveryHelp", FollowPath.Result.NONE, F),
])
def test_would_a_recovery_help_knows_nav2s_codes(node, code, answer):
    assert load(f'<{node} error_code="{{code}}"/>', code=code).tick_once() is answer


def test_are_error_codes_present_reads_a_list_and_refuses_what_is_not_one():
    assert load('<AreErrorCodesPresent error_code="{code}" error_codes_to_check="104;105"/>',
                code=105).tick_once() is S
    assert load('<AreErrorCodesPresent error_code="{code}" error_codes_to_check="104;105"/>',
                code=106).tick_once() is F
    with pytest.raises(BehaviorTreeError, match=r"'104;x' is not a list of error codes"):
        load('<AreErrorCodesPresent error_code="{code}" error_codes_to_check="104;x"/>', code=1)


def test_path_expiring_timer_restarts_on_a_new_path():
    clock = Clock()
    tree = load('<PathExpiringTimer seconds="2" path="{path}"/>', clock=clock, path=path_of((0, 0)))
    answers = []
    for now, new_path in ((0.0, False), (1.5, False), (1.75, True), (3.0, False), (3.75, False)):
        clock.now = now
        if new_path:
            tree.blackboard.set("path", path_of((1, 0)))
        answers.append(tree.tick_once())
    assert answers == [F, F, F, F, S]


# -- paths and goals -----------------------------------------------------------------------------------

def test_truncate_path_drops_the_end_within_distance_and_faces_the_goal():
    path = path_of(*[(0.5 * i, 0.0) for i in range(11)])  # 0 … 5 m
    tree = load('<TruncatePath input_path="{path}" distance="1.0" output_path="{short}"/>', path=path)
    assert tree.tick_once() is S
    short = tree.blackboard.get("short")
    assert [p.pose.position.x for p in short.poses] == [0.5 * i for i in range(9)]  # to 4 m
    o = short.poses[-1].pose.orientation
    assert yaw_from_quaternion(o.x, o.y, o.z, o.w) == pytest.approx(0.0)
    tree = load('<TruncatePath input_path="{path}" distance="100" output_path="{short}"/>', path=path)
    tree.tick_once()
    assert len(tree.blackboard.get("short").poses) == 2  # never fewer than two
    assert path.poses[-1].pose.position.x == 5.0  # the input untouched


def test_truncate_path_local_keeps_the_stretch_around_the_robot():
    ports = FakePorts()
    ports.poses[("map", "base_link")] = (3.1, 0.2, 0.0)
    path = path_of(*[(float(i), 0.0) for i in range(11)])
    tree = load('<TruncatePathLocal input_path="{path}" distance_forward="2" distance_backward="1" '
                'output_path="{local}"/>', ports, path=path)
    assert tree.tick_once() is S
    assert [p.pose.position.x for p in tree.blackboard.get("local").poses] == [2.0, 3.0, 4.0, 5.0]


def test_remove_passed_goals_drops_those_reached_at_the_front_but_never_the_last():
    ports = FakePorts()
    goals = [pose(1.0), pose(2.0), pose(3.0)]
    tree = load('<RemovePassedGoals input_goals="{goals}" output_goals="{goals}" radius="0.5"/>', ports, goals=goals)
    assert tree.tick_once() is F  # no robot pose
    ports.poses[ROBOT] = (1.3, 0.0, 0.0)
    assert tree.tick_once() is S
    assert [g.pose.position.x for g in tree.blackboard.get("goals")] == [2.0, 3.0]
    ports.poses[ROBOT] = (3.0, 0.0, 0.0)
    tree.tick_once()
    assert [g.pose.position.x for g in tree.blackboard.get("goals")] == [2.0, 3.0]  # (2, 0) is 1 m away
    ports.poses[ROBOT] = (2.2, 0.0, 0.0)
    tree.tick_once()
    tree.tick_once()
    assert [g.pose.position.x for g in tree.blackboard.get("goals")] == [3.0]


def test_get_pose_from_path_counts_from_the_end_when_negative():
    tree = load('<GetPoseFromPath path="{path}" index="-1" pose="{end}"/>', path=path_of((0, 0), (4, 1)))
    assert tree.tick_once() is S and tree.blackboard.get("end").pose.position.x == 4.0
    assert load('<GetPoseFromPath path="{path}" index="2" pose="{end}"/>', path=path_of((0, 0))).tick_once() is F


def test_a_selector_gives_its_default_until_a_name_comes_on_its_latched_topic():
    ports = FakePorts()
    tree = load('<PlannerSelector default_planner="GridBased" selected_planner="{planner}"/>', ports)
    assert tree.tick_once() is S and tree.blackboard.get("planner") == "GridBased"
    assert ports.subscribed == {"planner_selector": True}
    ports.topics["planner_selector"] = String(data="SmacPlanner")
    tree.tick_once()
    assert tree.blackboard.get("planner") == "SmacPlanner"
    assert load('<ControllerSelector selected_controller="{c}"/>').tick_once() is F  # no default, nothing heard


def test_goal_updater_takes_a_newer_goal_from_its_topic():
    ports = FakePorts()
    tree = load('<GoalUpdater input_goal="{goal}" output_goal="{goal}"><Count/></GoalUpdater>', ports,
                goal=pose(1.0, stamp_s=10.0))
    ports.topics["goal_update"] = pose(5.0, stamp_s=9.0)
    assert tree.tick_once() is S and tree.blackboard.get("goal").pose.position.x == 1.0  # older: ignored
    ports.topics["goal_update"] = pose(6.0, stamp_s=11.0)
    tree.tick_once()
    assert tree.blackboard.get("goal").pose.position.x == 6.0


# -- decorators ----------------------------------------------------------------------------------------

def test_distance_controller_ticks_its_child_each_distance_travelled():
    ports = FakePorts()
    ports.poses[ROBOT] = (0.0, 0.0, 0.0)
    tree = load('<DistanceController distance="1.0"><Count/></DistanceController>', ports)
    answers = []
    for x in (0.0, 0.5, 1.0, 1.4, 2.0):
        ports.poses[ROBOT] = (x, 0.0, 0.0)
        answers.append(tree.tick_once())
    assert answers == [S, R, S, R, S] and Count.ticks == 3


def test_speed_controller_ticks_faster_as_the_robot_goes_faster():
    clock = Clock()
    ports = FakePorts()
    tree = load('<SpeedController min_rate="0.5" max_rate="2" min_speed="0" max_speed="1"><Count/>'
                "</SpeedController>", ports, clock, goal=pose(5.0))
    ports.topics["odom"] = odometry(0.0, 0.0)
    ticked = []
    for step in range(41):  # 4 s at 10 Hz, standing still: 0.5 Hz after the first period of 1/max_rate
        clock.now = step * 0.1
        before = Count.ticks
        tree.tick_once()
        ticked.append(Count.ticks > before)
    standing = [round(i * 0.1, 1) for i, t in enumerate(ticked) if t]
    assert standing == [0.0, 0.5, 2.5]
    ports.topics["odom"] = odometry(0.0, 1.0)
    tree.blackboard.set("goal", pose(6.0))  # a new goal: anew, at full speed 2 Hz
    ticks = []
    for step in range(41, 71):
        clock.now = step * 0.1
        before = Count.ticks
        tree.tick_once()
        if Count.ticks > before:
            ticks.append(round(step * 0.1, 1))
    assert ticks == [4.1, 4.6, 5.1, 5.6, 6.1, 6.6]


def test_goal_updated_controller_ticks_its_child_only_for_a_new_goal():
    tree = load("<GoalUpdatedController><Count/></GoalUpdatedController>", goal=pose(1.0))
    assert [tree.tick_once(), tree.tick_once(), tree.tick_once()] == [S, R, R] and Count.ticks == 1
    tree.blackboard.set("goal", pose(2.0))
    assert tree.tick_once() is S and Count.ticks == 2


def test_path_longer_on_approach_ticks_its_child_when_a_near_goal_gets_a_much_longer_path():
    near = path_of((0, 0), (1, 0), (2, 0))  # 2 m: within prox_len 3
    detour = path_of((0, 0), (0, 2), (2, 2), (2, 0))  # 6 m to the same end: over 2 × 2 m
    tree = load('<PathLongerOnApproach path="{path}"><Count answer="RUNNING"/></PathLongerOnApproach>', path=near)
    assert tree.tick_once() is S and Count.ticks == 0  # nothing to compare with yet
    tree.blackboard.set("path", detour)
    assert tree.tick_once() is R and Count.ticks == 1
    far = path_of((0, 0), (5, 0), (9, 0))
    tree = load('<PathLongerOnApproach path="{path}"><Count/></PathLongerOnApproach>', path=far)
    tree.tick_once()
    tree.blackboard.set("path", path_of((0, 0), (0, 9), (9, 9), (9, 0)))
    assert tree.tick_once() is S and Count.ticks == 0  # not on approach: 9 m out


def test_every_node_nav2_jazzy_registers_by_default_is_known():
    names = set(nav2_factory().nodes)
    nav2 = {
        "ComputePathToPose", "ComputePathThroughPoses", "FollowPath", "SmoothPath", "Spin", "BackUp",
        "DriveOnHeading", "Wait", "AssistedTeleop", "ClearEntireCostmap", "ClearCostmapAroundRobot",
        "ClearCostmapExceptRegion", "ReinitializeGlobalLocalization", "TruncatePath", "TruncatePathLocal",
        "RemovePassedGoals", "GoalUpdater", "NavigateToPose", "NavigateThroughPoses", "PlannerSelector",
        "ControllerSelector", "GoalCheckerSelector", "ProgressCheckerSelector", "SmootherSelector", "CancelControl",
        "CancelBackUp", "CancelSpin", "CancelWait", "CancelDriveOnHeading", "CancelAssistedTeleop",
        "GoalUpdated", "GlobalUpdatedGoal", "GoalReached", "IsPathValid", "IsStuck", "TimeExpired",
        "DistanceTraveled", "TransformAvailable", "InitialPoseReceived", "IsBatteryLow", "IsBatteryCharging",
        "AreErrorCodesPresent", "WouldAPlannerRecoveryHelp", "WouldAControllerRecoveryHelp",
        "WouldASmootherRecoveryHelp", "PathExpiringTimer", "PipelineSequence", "RecoveryNode", "RoundRobin",
        "RateController", "DistanceController", "SpeedController", "GoalUpdatedController", "PathLongerOnApproach",
        "SingleTrigger", "GetPoseFromPath",
    }
    assert nav2 <= names, sorted(nav2 - names)
