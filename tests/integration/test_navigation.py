"""Navigation end to end in the room: launch_sim with localization and navigation, goals over DDS.

The real stack (MuJoCo simulator, controller, twist_mux, map_server, AMCL, planner_server,
controller_server, navigator) runs as launch_sim starts it; the test is an action client
and a topic user, as RViz and ``ros2 action send_goal`` are. The shipped room map is in the
world frame, so ground truth is comparable with the goal directly.
"""
from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import pytest
import yaml
from action_msgs.msg import GoalStatus
from geometry_msgs.msg import PoseStamped, Twist
from lifecycle_msgs.srv import GetState
from nav2_msgs.action import ComputePathThroughPoses, NavigateThroughPoses, NavigateToPose
from nav2_msgs.srv import GetCostmap, IsPathValid
from nav_msgs.msg import OccupancyGrid, Odometry
from nav_msgs.msg import Path as PathMsg
from rclpy.action import ActionClient
from std_srvs.srv import Trigger

from pppbot_common.process import StopTimeouts
from pppbot_common.ros.qos import LATCHED
from pppbot_common.ros.wait import call, send_goal, wait_until
from pppbot_common.se2 import quaternion_from_yaw, wrap_angle, yaw_from_quaternion

ROOT = Path(__file__).resolve().parents[2]
PPPBOT = str(ROOT / "pppbot")
#: How long a test that asserts launch_sim's clean stop gives it before escalating: the launch's own
#: ladder (sigterm_timeout, a hung node's stacks, sigkill_timeout: 5 + 1 + 5 s) and then its own exit.
LAUNCH_STOP = StopTimeouts(sigint_s=20.0, sigterm_s=5.0)


def goal_pose(x: float, y: float, yaw: float) -> PoseStamped:
    pose = PoseStamped()
    pose.header.frame_id = "map"
    pose.pose.position.x, pose.pose.position.y = x, y
    o = pose.pose.orientation
    o.x, o.y, o.z, o.w = quaternion_from_yaw(yaw)
    return pose


def truth_pose(msg: Odometry) -> tuple[float, float, float]:
    p, o = msg.pose.pose.position, msg.pose.pose.orientation
    return p.x, p.y, yaw_from_quaternion(o.x, o.y, o.z, o.w)


@pytest.mark.ros
@pytest.mark.heavy
def test_goals_are_reached_canceled_and_taken_from_goal_pose(ros_node: Any, spawn: Any, tmp_path: Path) -> None:
    launch = spawn([PPPBOT, "launch_sim", "world:=room", "localization:=true", "use_teleop:=false",
                    "use_rviz:=false", "use_viz:=false", "lockstep:=true", "real_time_factor:=1.0"], name="launch_sim")
    launch.wait_for_output(r"ppp_bot is up in 'room'", 90)
    truths: list[Odometry] = []
    plans: list[PathMsg] = []
    costmaps: dict[str, OccupancyGrid] = {}
    commands: list[Twist] = []
    ros_node.create_subscription(Odometry, "/ground_truth/odom", truths.append, 10)
    ros_node.create_subscription(PathMsg, "/plan", plans.append, 10)
    ros_node.create_subscription(Twist, "/cmd_vel", commands.append, 10)
    for name in ("global_costmap", "local_costmap"):
        ros_node.create_subscription(OccupancyGrid, f"/{name}/costmap",
                                     lambda msg, name=name: costmaps.__setitem__(name, msg), LATCHED)
    client = ActionClient(ros_node, NavigateToPose, "navigate_to_pose")
    assert client.wait_for_server(timeout_sec=20)
    assert_nav2_up(ros_node)
    assert_plans_through_poses(ros_node)

    # 1. A goal reached: the robot ends within the goal checker's tolerances, with feedback on the way.
    feedback: list[Any] = []
    goal = NavigateToPose.Goal(pose=goal_pose(1.5, 0.5, 1.57))
    handle = send_goal(client, goal, ros_node, 20, feedback_callback=lambda msg: feedback.append(msg.feedback))
    assert handle.accepted
    assert handle.accepted
    done = handle.get_result_async()
    wait_until(done.done, 120, "the first goal's result", node=ros_node)
    assert done.result().status == GoalStatus.STATUS_SUCCEEDED, done.result().result.error_msg
    x, y, yaw = truth_pose(truths[-1])
    assert math.hypot(x - 1.5, y - 0.5) < 0.35 and abs(wrap_angle(yaw - 1.57)) < 0.35
    distances = [f.distance_remaining for f in feedback]
    assert distances and max(distances) > 1.2 and min(distances) < 0.5
    assert plans and plans[0].header.frame_id == "map" and max(len(p.poses) for p in plans) > 5
    assert any(abs(c.linear.x) > 0.2 for c in commands)
    wait_until(lambda: len(costmaps) == 2, 10, "both costmaps", node=ros_node)
    local = costmaps["local_costmap"]
    assert local.header.frame_id == "odom" and local.info.width == local.info.height == 100
    assert costmaps["global_costmap"].header.frame_id == "map"
    assert any(v == 100 for v in costmaps["global_costmap"].data)  # walls are lethal

    # 2. A goal canceled on the way: the goal ends canceled and the robot stops.
    far = NavigateToPose.Goal(pose=goal_pose(-1.5, -1.0, 0.0))
    handle = send_goal(client, far, ros_node)
    assert handle.accepted
    start = truth_pose(truths[-1])
    wait_until(lambda: math.hypot(truth_pose(truths[-1])[0] - start[0], truth_pose(truths[-1])[1] - start[1]) > 0.3,
               60, "the robot under way", node=ros_node)
    cancel = handle.cancel_goal_async()
    wait_until(cancel.done, 10, "the cancel answered", node=ros_node)
    result = handle.get_result_async()
    wait_until(result.done, 20, "the canceled goal's result", node=ros_node)
    assert result.result().status == GoalStatus.STATUS_CANCELED
    wait_until(lambda: abs(truths[-1].twist.twist.linear.x) < 0.02, 10, "the robot stopped", node=ros_node)

    # 3. A goal on /goal_pose (RViz's 2D Goal Pose) is navigated to as well.
    pub = ros_node.create_publisher(PoseStamped, "/goal_pose", 10)
    wait_until(lambda: pub.get_subscription_count() > 0, 10, "the navigator on /goal_pose", node=ros_node)
    pub.publish(goal_pose(0.0, 0.0, 0.0))
    t0 = time.monotonic()
    wait_until(lambda: math.hypot(*truth_pose(truths[-1])[:2]) < 0.3 and abs(truths[-1].twist.twist.linear.x) < 0.02
               and time.monotonic() - t0 > 1.0, 120, "the robot back at (0, 0)", node=ros_node)

    # 4. A goal no recovery can help fails at once, with Nav2's error code and no recovery run.
    status, result = run_goal(ros_node, client, 1000.0, 1000.0)
    assert status == GoalStatus.STATUS_ABORTED
    assert result.error_code == 204 and result.error_msg.endswith("(after 0 recoveries)"), result.error_msg

    # 5. A goal in the west wall (x = -2.5) is moved by the planner's tolerance (0.5 m) to the nearest
    #    free pose: reached, and the result says where it went.
    status, result = run_goal(ros_node, client, -2.5, 0.0)
    assert status == GoalStatus.STATUS_SUCCEEDED, result.error_msg
    assert "the goal (-2.50, 0.00) is in an obstacle: navigating to the nearest free pose" in result.error_msg
    x, y, _ = truth_pose(truths[-1])
    assert 0.2 < math.hypot(x + 2.5, y) < 0.6

    # 6. Through poses (BasicNavigator.goThroughPoses()): by the first, to the last; the poses
    #    remaining counted down in the feedback.
    assert_goes_through_poses(ros_node, truths, [(0.0, 0.0), (1.5, -1.0)])

    # 7. A goal's own tree (NavigateToPose's behavior_tree) runs instead of the default; a tree
    #    written wrong ends its goal, naming file and line.
    assert_a_goals_own_tree_runs(ros_node, client, truths, tmp_path)


def assert_a_goals_own_tree_runs(ros_node: Any, client: Any, truths: list[Odometry], tmp_path: Path) -> None:
    """This one turns the robot about in place."""
    x0, y0, yaw0 = truth_pose(truths[-1])
    status, result = run_goal(ros_node, client, 0.0, 0.0, behavior_tree=str(tree_file(tmp_path, "turn_about.xml",
                              '<Sequence><Spin spin_dist="3.14" is_recovery="false"/><Wait wait_duration="0.5"/>'
                              "</Sequence>")))
    assert status == GoalStatus.STATUS_SUCCEEDED, result.error_msg
    x, y, yaw = truth_pose(truths[-1])
    # turned about where it stood (by the behavior_server's odometry: the wheels slip a little on
    # a turn in place), not driven to (0, 0) as the default tree would
    assert abs(wrap_angle(yaw - yaw0)) > 2.5 and math.hypot(x - x0, y - y0) < 0.1 < math.hypot(x, y)
    bad = tree_file(tmp_path, "bad.xml", '<Sequence>\n<Fly/></Sequence>')
    status, result = run_goal(ros_node, client, 0.0, 0.0, behavior_tree=str(bad))
    assert status == GoalStatus.STATUS_ABORTED  # taken and ended, as Nav2 Jazzy's
    assert result.error_msg.startswith(f"the behavior_tree cannot be loaded: {bad}:3: unknown node 'Fly'; known: ")


def tree_file(folder: Path, name: str, body: str) -> Path:
    """A BehaviorTree.CPP 4 file of one tree, ``body``."""
    path = folder / name
    path.write_text(f'<root BTCPP_format="4">\n<BehaviorTree ID="MainTree">{body}</BehaviorTree>\n</root>\n')
    return path


def assert_nav2_up(node: Any) -> None:
    """Up as BasicNavigator sees it: amcl and bt_navigator active (waitUntilNav2Active), the
    lifecycle managers say so, and the costmaps answer getGlobalCostmap() / getLocalCostmap()."""
    for name in ("map_server", "amcl", "planner_server", "controller_server", "bt_navigator"):
        assert lifecycle_state(node, name) == "active", name
    for manager in ("lifecycle_manager_localization", "lifecycle_manager_navigation"):
        assert call(node, Trigger, f"/{manager}/is_active", Trigger.Request()).success, manager
    def costmap(name: str) -> Any:  # empty until the costmap's first update (the robot's pose in its frame)
        answer = call(node, GetCostmap, f"/{name}/get_costmap", GetCostmap.Request()).map
        return answer if answer.metadata.size_x else None

    global_map = wait_until(lambda: costmap("global_costmap"), 20, "the global costmap", node=node)
    local_map = wait_until(lambda: costmap("local_costmap"), 20, "the local costmap", node=node)
    assert global_map.header.frame_id == "map" and 254 in bytes(global_map.data)  # walls are lethal
    assert len(global_map.data) == global_map.metadata.size_x * global_map.metadata.size_y > 0
    assert local_map.header.frame_id == "odom" and (local_map.metadata.size_x, local_map.metadata.size_y) == (100, 100)


def assert_plans_through_poses(node: Any) -> None:
    """compute_path_through_poses (BasicNavigator.getPathThroughPoses()): one path through each
    goal in turn, ending at the last; none without goals, with Nav2's error code."""
    client = ActionClient(node, ComputePathThroughPoses, "compute_path_through_poses")
    assert client.wait_for_server(timeout_sec=20)
    via, end = (1.5, 0.5), (-1.5, -1.0)  # free places of the room (goals of the test below)
    goal = ComputePathThroughPoses.Goal(goals=[goal_pose(*via, 0.0), goal_pose(*end, 1.57)])
    handle = send_goal(client, goal, node)
    assert handle.accepted
    done = handle.get_result_async()
    result = wait_until(lambda: done.result() if done.done() else None, 30, "the path through poses", node=node).result
    assert result.error_code == ComputePathThroughPoses.Result.NONE, result.error_msg
    xy = [(p.pose.position.x, p.pose.position.y) for p in result.path.poses]
    assert min(math.hypot(x - via[0], y - via[1]) for x, y in xy) < 0.05  # through the first goal
    assert math.hypot(xy[-1][0] - end[0], xy[-1][1] - end[1]) < 0.05
    last = result.path.poses[-1].pose.orientation
    assert abs(yaw_from_quaternion(last.x, last.y, last.z, last.w) - 1.57) < 1e-3
    # is_path_valid (the planner server's, Nav2's IsPathValid): the plan is; a straight line
    # from the robot at (0, 0) through the room's west wall (x = -2.5) is not, from its poses
    # within the robot's radius of the wall on
    assert call(node, IsPathValid, "/is_path_valid", IsPathValid.Request(path=result.path)).is_valid
    line = PathMsg()
    line.header.frame_id = "map"
    line.poses = [goal_pose(-0.1 * i, 0.0, 0.0) for i in range(30)]  # 0 … -2.9 m
    answer = call(node, IsPathValid, "/is_path_valid", IsPathValid.Request(path=line))
    assert not answer.is_valid and answer.invalid_pose_indices and 20 < answer.invalid_pose_indices[0] < 26
    empty = send_goal(client, ComputePathThroughPoses.Goal(), node).get_result_async()
    failed = wait_until(lambda: empty.result() if empty.done() else None, 30, "no goals' answer", node=node)
    assert failed.result.error_code == ComputePathThroughPoses.Result.NO_VIAPOINTS_GIVEN


def assert_goes_through_poses(node: Any, truths: list[Odometry], poses: list[tuple[float, float]]) -> None:
    client = ActionClient(node, NavigateThroughPoses, "navigate_through_poses")
    assert client.wait_for_server(timeout_sec=20)
    feedback: list[Any] = []
    passed: list[float] = []  # how close the robot came to the first pose
    goal = NavigateThroughPoses.Goal(poses=[goal_pose(x, y, 0.0) for x, y in poses])
    handle = send_goal(client, goal, node, feedback_callback=lambda msg: feedback.append(msg.feedback))
    assert handle.accepted
    done = handle.get_result_async()

    def ended() -> bool:
        x, y, _ = truth_pose(truths[-1])
        passed.append(math.hypot(x - poses[0][0], y - poses[0][1]))
        return done.done()

    wait_until(ended, 180, "the end of the through-poses goal", node=node)
    assert done.result().status == GoalStatus.STATUS_SUCCEEDED, done.result().result.error_msg
    assert min(passed) < 0.6  # by the first pose (within Nav2's passed-goal radius and a margin)
    x, y, _ = truth_pose(truths[-1])
    assert math.hypot(x - poses[-1][0], y - poses[-1][1]) < 0.35
    remaining = [fb.number_of_poses_remaining for fb in feedback]
    assert remaining[0] == 2 and remaining[-1] == 1 and remaining == sorted(remaining, reverse=True)


def lifecycle_state(node: Any, name: str) -> str:
    """What ``ros2 lifecycle get /<name>`` says."""
    return str(call(node, GetState, f"/{name}/get_state", GetState.Request()).current_state.label)


def run_goal(node: Any, client: Any, x: float, y: float, behavior_tree: str = "") -> tuple[int, Any]:
    handle = send_goal(client, NavigateToPose.Goal(pose=goal_pose(x, y, 0.0), behavior_tree=behavior_tree), node)
    assert handle.accepted
    done = handle.get_result_async()
    wait_until(done.done, 120, f"the result of ({x}, {y})", node=node)
    return done.result().status, done.result().result


# A Nav2 params file that configures less still runs: ppp_bot's own nav2_params.yaml (Humble's shape:
# no collision_monitor section), further stripped of every section a node can run without, brings
# localization and navigation up and takes the robot to a goal. The collision monitor is left out, its
# commands bridged; every other node without a section runs on Nav2's defaults; one line says which.
#: ppp_bot's file's sections a node runs without (its defaults: Nav2's)
OPTIONAL = ("bt_navigator", "smoother_server", "behavior_server", "waypoint_follower", "velocity_smoother")


@pytest.mark.ros
def test_ppp_bots_file_without_optional_sections_brings_navigation_up(ros_node: Any, spawn: Any,
                                                                       tmp_path: Path) -> None:
    document = yaml.safe_load((ROOT / "tests" / "data" / "ppp_bot" / "nav2_params.yaml").read_text())
    assert "collision_monitor" not in document and set(OPTIONAL) <= set(document)  # ppp_bot's, as published
    for section in OPTIONAL:
        del document[section]
    params = tmp_path / "nav2_params.yaml"
    params.write_text(yaml.safe_dump(document))
    launch = spawn([PPPBOT, "launch_sim", "world:=room", "localization:=true", f"params_file:={params}",
                    "use_teleop:=false", "use_rviz:=false", "use_viz:=false", "lockstep:=true",
                    "real_time_factor:=0"], name="launch_sim")
    launch.wait_for_output(r"ppp_bot is up in 'room'", 120)
    notes = [line for line in launch.output.splitlines() if "has no section for" in line]
    assert len(notes) == 1, notes
    assert "nav2_params.yaml has no section for 7 node(s): collision_monitor left out" in notes[0]
    defaults = notes[0].rpartition("; ")[2]
    assert defaults.endswith("on Nav2's defaults") and all(name in defaults for name in ("map_server", *OPTIONAL))
    for name in ("bt_navigator", "velocity_smoother", "behavior_server", "waypoint_follower", "smoother_server"):
        assert lifecycle_state(ros_node, name) == "active", name
    truths: list[Odometry] = []
    ros_node.create_subscription(Odometry, "/ground_truth/odom", truths.append, 10)
    client = ActionClient(ros_node, NavigateToPose, "navigate_to_pose")
    assert client.wait_for_server(timeout_sec=20)
    handle = send_goal(client, NavigateToPose.Goal(pose=goal_pose(1.5, 0.5, 0.0)), ros_node, 20)
    done = handle.get_result_async()
    wait_until(done.done, 180, "the goal's result", node=ros_node)
    assert done.result().status == GoalStatus.STATUS_SUCCEEDED, done.result().result.error_msg
    x, y, _ = truth_pose(truths[-1])
    assert math.hypot(x - 1.5, y - 0.5) < 0.4
