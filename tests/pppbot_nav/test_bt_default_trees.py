"""pppbot's default navigate_to_pose and navigate_through_poses trees, ticked as bt_navigator ticks
them, against fake planner, controller, costmaps and behaviours: replanning at its rate while the
controller follows, the recoveries in Nav2's order, and the error codes a failure leaves; and trees
the tests write in the shapes of Nav2's other defaults (odometry calibration, goal patience)."""
from __future__ import annotations

import sys
from pathlib import Path as FilePath
from typing import Any

from geometry_msgs.msg import PoseStamped
from nav2_msgs.action import ComputePathThroughPoses, ComputePathToPose, FollowPath
from nav_msgs.msg import Path

from pppbot_nav.bt.ports import PORTS_KEY, GoalStatus
from pppbot_nav.bt.tree import Blackboard, Status
from pppbot_nav.ros.bt.nav2 import DEFAULT_NAV_THROUGH_POSES_BT_XML, DEFAULT_NAV_TO_POSE_BT_XML, nav2_factory
from pppbot_nav.ros.bt.nav2_actions import RECOVERIES_KEY

sys.path.insert(0, str(FilePath(__file__).parent))
from bt_fakes import FakeAction, FakePorts  # noqa: E402

TICK_S = 0.1
LOCAL = "local_costmap/clear_entirely_local_costmap"
GLOBAL = "global_costmap/clear_entirely_global_costmap"


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def pose(x: float, y: float = 0.0) -> PoseStamped:
    msg = PoseStamped()
    msg.header.frame_id = "map"
    msg.pose.position.x, msg.pose.position.y = x, y
    msg.pose.orientation.w = 1.0
    return msg


class Navigation:
    """A default tree on fakes, ticked every :data:`TICK_S` of its clock."""

    def __init__(self, xml: FilePath, planner: FakeAction, **entries: Any) -> None:
        self.clock = Clock()
        self.ports = FakePorts()
        self.ports.poses[("map", "base_link")] = (0.0, 0.0, 0.0)
        self.ports.actions[planner_name(planner)] = planner
        self.controller = self.ports.actions["follow_path"] = FakeAction(FollowPath)
        board = Blackboard()
        board.set(PORTS_KEY, self.ports)
        board.set("server_timeout", 1000.0)
        board.set(RECOVERIES_KEY, 0)
        board.set("replanning_frequency", 1.0)  # the navigator's parameters the trees read
        board.set("number_of_retries", 6)
        for name in ("compute_path_error_code", "follow_path_error_code"):  # the navigator's error_code_names
            board.set(name, 0)
        for key, value in entries.items():
            board.set(key, value)
        self.tree = nav2_factory().load(xml, clock=self.clock, blackboard=board)

    def run(self, until_s: float) -> Status:
        """Tick until the tree ends or ``until_s``; the last answer."""
        status = Status.RUNNING
        while status is Status.RUNNING and self.clock.now <= until_s + 1e-9:
            status = self.tree.tick_once()
            self.clock.now = round(self.clock.now + TICK_S, 6)
        return status

    def calls(self, service: str) -> int:
        return len(self.ports.services[service].calls) if service in self.ports.services else 0


def planner_name(planner: FakeAction) -> str:
    return "compute_path_through_poses" if planner.action_type is ComputePathThroughPoses else "compute_path_to_pose"


def planning(action: Any = ComputePathToPose) -> FakeAction:
    """A planner that answers each goal with a new straight path (its end moves 1 cm per plan, so
    the controller sees each as an update)."""
    made = [0]

    def answer(goal: Any) -> tuple[GoalStatus, Any]:
        made[0] += 1
        path = Path()
        path.header.frame_id = "map"
        path.poses = [pose(0.0), pose(1.0 + 0.01 * made[0])]
        return GoalStatus.SUCCEEDED, action.Result(path=path)
    return FakeAction(action, answer=answer)


def test_the_tree_replans_once_a_second_while_the_controller_follows_and_succeeds_with_it():
    nav = Navigation(DEFAULT_NAV_TO_POSE_BT_XML, planning(), goal=pose(3.0))
    assert nav.run(until_s=3.55) is Status.RUNNING
    planner = nav.ports.actions["compute_path_to_pose"]
    assert len(planner.goals) == 4  # at 0, 1, 2 and 3 s
    assert {call.goal.planner_id for call in planner.goals} == {"GridBased"}
    assert planner.last.goal.goal.pose.position.x == 3.0
    # each new path went to the controller as a new goal, which it takes as an update
    assert [round(c.goal.path.poses[-1].pose.position.x, 2) for c in nav.controller.goals] == [1.01, 1.02, 1.03, 1.04]
    assert {c.goal.controller_id for c in nav.controller.goals} == {"FollowPath"}
    nav.controller.last.end(GoalStatus.SUCCEEDED, FollowPath.Result())
    assert nav.run(until_s=3.75) is Status.SUCCESS
    assert nav.tree.blackboard.get(RECOVERIES_KEY) == 0 and nav.calls(LOCAL) == nav.calls(GLOBAL) == 0


def test_a_path_not_followed_clears_the_local_costmap_then_recovers_and_navigates_again():
    nav = Navigation(DEFAULT_NAV_TO_POSE_BT_XML, planning(), goal=pose(3.0))
    stuck = FollowPath.Result(error_code=FollowPath.Result.FAILED_TO_MAKE_PROGRESS)
    nav.controller.answer = lambda goal: (GoalStatus.ABORTED, stuck) if len(nav.controller.goals) <= 2 else None
    assert nav.run(until_s=0.5) is Status.RUNNING
    # followed, failed, local costmap cleared, followed again, failed: the first recovery of the
    # round robin (both costmaps cleared) and navigation again, planning anew
    assert (nav.calls(LOCAL), nav.calls(GLOBAL)) == (2, 1)
    assert len(nav.controller.goals) == 3 and len(nav.ports.actions["compute_path_to_pose"].goals) == 2
    assert nav.tree.blackboard.get("follow_path_error_code") == FollowPath.Result.FAILED_TO_MAKE_PROGRESS
    assert nav.tree.blackboard.get(RECOVERIES_KEY) == 3  # each clearing counts, as Nav2's
    nav.controller.last.end(GoalStatus.SUCCEEDED, FollowPath.Result())
    assert nav.run(until_s=1.0) is Status.SUCCESS


def test_the_recoveries_go_round_robin_and_the_goal_fails_after_six():
    nav = Navigation(DEFAULT_NAV_TO_POSE_BT_XML, planning(), goal=pose(3.0))
    stuck = FollowPath.Result(error_code=FollowPath.Result.NO_VALID_CONTROL)
    nav.controller.answer = lambda goal: (GoalStatus.ABORTED, stuck)
    for name in ("spin", "wait", "backup"):
        nav.ports.action(name, None).answer = lambda goal: (GoalStatus.SUCCEEDED, None)
    assert nav.run(until_s=60.0) is Status.FAILURE
    behaviours = {name: len(nav.ports.actions[name].goals) for name in ("spin", "wait", "backup")}
    # 6 recoveries in turn: clear, spin, wait, backup, clear, spin
    assert behaviours == {"spin": 2, "wait": 1, "backup": 1}
    assert nav.calls(GLOBAL) == 2 and nav.calls(LOCAL) == 7 + 2  # each round's follow retry, and two clears
    assert len(nav.controller.goals) == 14  # 7 rounds, followed twice each
    spin = nav.ports.actions["spin"].goals[0].goal
    assert round(spin.target_yaw, 2) == 1.57
    backup = nav.ports.actions["backup"].goals[0].goal
    assert (round(backup.target.x, 2), round(backup.speed, 2)) == (0.3, 0.05)


def test_a_plan_no_recovery_can_help_fails_the_goal_at_once_with_the_planners_code():
    refused = ComputePathToPose.Result(error_code=ComputePathToPose.Result.START_OCCUPIED)
    planner = FakeAction(ComputePathToPose, answer=lambda goal: (GoalStatus.ABORTED, refused))
    nav = Navigation(DEFAULT_NAV_TO_POSE_BT_XML, planner, goal=pose(3.0))
    assert nav.run(until_s=1.0) is Status.FAILURE
    assert len(planner.goals) == 1 and not nav.controller.goals and nav.calls(GLOBAL) == 0
    assert nav.tree.blackboard.get("compute_path_error_code") == ComputePathToPose.Result.START_OCCUPIED


def test_the_through_poses_tree_plans_through_the_poses_still_ahead_at_its_replanning_frequency():
    nav = Navigation(DEFAULT_NAV_THROUGH_POSES_BT_XML, planning(ComputePathThroughPoses),
                     goals=[pose(0.5), pose(2.0), pose(3.0)], replanning_frequency=0.333)
    assert nav.run(until_s=3.15) is Status.RUNNING
    planner = nav.ports.actions["compute_path_through_poses"]
    assert len(planner.goals) == 2  # at 0 and 3.1 s (0.333 Hz)
    # the robot at (0, 0) had come within 0.7 m of the first pose: planned through the other two
    assert [[g.pose.position.x for g in call.goal.goals] for call in planner.goals] == [[2.0, 3.0], [2.0, 3.0]]
    nav.ports.poses[("map", "base_link")] = (1.9, 0.0, 0.0)
    nav.run(until_s=6.25)  # the next plan at 6.2 s
    assert [g.pose.position.x for g in planner.last.goal.goals] == [3.0]
    assert [g.pose.position.x for g in nav.tree.blackboard.get("goals")] == [3.0]


# ------------------------------------------------------------------ trees a user writes, shaped as Nav2's
def written(tmp_path: FilePath, body: str) -> FilePath:
    path = tmp_path / "tree.xml"
    path.write_text(f'<root BTCPP_format="4" main_tree_to_execute="Main"><BehaviorTree ID="Main">{body}'
                    "</BehaviorTree></root>")
    return path


#: A square driven three times, as Nav2's odometry calibration tree drives one: behaviours only.
SQUARE = """<Repeat num_cycles="3"><Sequence>
  <DriveOnHeading dist_to_travel="2.0" speed="0.2" time_allowance="12"/>
  <Spin spin_dist="1.5708"/>
</Sequence></Repeat>"""


def test_a_repeat_of_behaviours_drives_its_square_three_times_in_order(tmp_path):
    nav = Navigation(written(tmp_path, SQUARE), planning())
    order: list[str] = []

    def done(name: str) -> Any:
        def answer(goal: Any) -> tuple[GoalStatus, None]:
            order.append(name)
            return GoalStatus.SUCCEEDED, None
        return answer

    for name in ("drive_on_heading", "spin"):
        nav.ports.action(name, None).answer = done(name)
    assert nav.run(until_s=10.0) is Status.SUCCESS
    assert order == ["drive_on_heading", "spin"] * 3
    drive = nav.ports.actions["drive_on_heading"].goals[0].goal
    assert (drive.target.x, round(drive.speed, 3), drive.time_allowance.sec) == (2.0, 0.2, 12)
    assert round(nav.ports.actions["spin"].goals[0].goal.target_yaw, 4) == 1.5708
    assert not nav.ports.actions["compute_path_to_pose"].goals  # no planning in this tree


#: Nav2's goal patience: close to the goal, a new path much longer than the one followed (the way
#: blocked) stops the robot and waits for the way to clear before following the long way round.
PATIENCE = """<PipelineSequence>
  <RateController hz="1.0"><ComputePathToPose goal="{goal}" path="{path}" planner_id="GridBased"/></RateController>
  <ReactiveSequence>
    <PathLongerOnApproach path="{path}" prox_len="3.0" length_factor="2.0">
      <RetryUntilSuccessful num_attempts="1"><SequenceWithMemory>
        <CancelControl/>
        <Wait wait_duration="5.0"/>
      </SequenceWithMemory></RetryUntilSuccessful>
    </PathLongerOnApproach>
    <FollowPath path="{path}" controller_id="FollowPath"/>
  </ReactiveSequence>
</PipelineSequence>"""


def path_through(*points: tuple[float, float]) -> Path:
    path = Path()
    path.header.frame_id = "map"
    path.poses = [pose(x, y) for x, y in points]
    return path


def test_goal_patience_stops_and_waits_when_the_way_near_the_goal_becomes_much_longer(tmp_path):
    straight, detour = path_through((0, 0), (1, 0)), path_through((0, 0), (0, 1.5), (1, 1.5), (1, 0))
    plans = [straight, detour, detour]
    planner = FakeAction(ComputePathToPose, answer=lambda goal: (GoalStatus.SUCCEEDED, ComputePathToPose.Result(
        path=plans.pop(0) if len(plans) > 1 else plans[0])))
    nav = Navigation(written(tmp_path, PATIENCE), planner, goal=pose(1.0))
    waiting = nav.ports.action("wait", None)
    assert nav.run(until_s=0.55) is Status.RUNNING
    assert len(nav.controller.goals) == 1 and not waiting.goals  # following the straight path
    assert nav.run(until_s=1.55) is Status.RUNNING  # the detour came at 1 s: 4 m for 1 m, within 3 m of the goal
    assert nav.controller.cancel_all_calls == 1 and nav.controller.goals[0].canceled
    assert [round(w.goal.time.sec) for w in waiting.goals] == [5]
    assert len(nav.controller.goals) == 1  # not following while it waits
    waiting.last.end(GoalStatus.SUCCEEDED, None)
    assert nav.run(until_s=2.55) is Status.RUNNING
    assert len(waiting.goals) == 1  # the same detour again is no news: no second wait
    # the long way round, after the wait (the same path planned at 2 s is no update for the controller)
    assert [len(g.goal.path.poses) for g in nav.controller.goals] == [2, 4]
