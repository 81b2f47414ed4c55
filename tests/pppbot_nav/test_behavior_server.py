"""The behavior_server over DDS: Nav2's behaviour actions, their feedback and error codes, on a
robot that moves as it is commanded (its odom → base_link integrated from ``cmd_vel``)."""
from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from geometry_msgs.msg import Twist
from nav2_msgs.action import AssistedTeleop, BackUp, DriveOnHeading, Spin, Wait
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from rclpy.action import ActionClient
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import Empty
from user_plugins import install_user_plugins

from pppbot_common.maps import OccupancyGrid
from pppbot_common.params import ParameterError
from pppbot_common.ros.maps import grid_message
from pppbot_common.ros.qos import LATCHED
from pppbot_common.ros.wait import send_goal, wait_until
from pppbot_nav.behaviors import INSCRIBED_OCCUPANCY
from pppbot_nav.ros.behavior_server import BehaviorServer, BehaviorServerParameters

pytestmark = pytest.mark.ros


class Robot(Node):
    """Moves the server's robot: the last ``cmd_vel`` integrated into odom → base_link every 20 ms
    of ROS time (``frozen``: it stays where it is whatever it is told)."""

    def __init__(self, server: BehaviorServer, pose: tuple[float, float, float]) -> None:
        super().__init__("behavior_test_robot")
        self.server, self.pose, self.frozen = server, pose, False
        self.command = (0.0, 0.0)
        self.commands: list[tuple[float, float]] = []
        self.create_subscription(Twist, "cmd_vel", self._on_cmd, 10)
        self._last_s = self._now_s()
        self._publish()
        self.create_timer(0.02, self._move)

    def _now_s(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _on_cmd(self, msg: Twist) -> None:
        self.command = (msg.linear.x, msg.angular.z)
        self.commands.append(self.command)

    def _move(self) -> None:
        now = self._now_s()
        dt, self._last_s = now - self._last_s, now
        if not self.frozen:
            x, y, yaw = self.pose
            v, w = self.command
            self.pose = (x + v * dt * math.cos(yaw), y + v * dt * math.sin(yaw), yaw + w * dt)
        self._publish()

    def _publish(self) -> None:
        self.server.tf.set_transform("odom", "base_link", self._now_s(), self.pose)


def wall_costmap(stamp: Any) -> OccupancyGridMsg:
    """4 × 4 m around the origin of 'odom' (0.05 m cells): a wall at x = 1 m, inscribed from x = 0.7 m."""
    data = np.zeros((80, 80), dtype=np.int8)
    xs = -2.0 + (np.arange(80) + 0.5) * 0.05
    data[:, np.abs(xs - 1.0) < 0.3] = INSCRIBED_OCCUPANCY
    data[:, np.abs(xs - 1.0) < 0.05] = 100
    msg = grid_message(OccupancyGrid(data=data, resolution=0.05, origin=(-2.0, -2.0, 0.0)), stamp)
    msg.header.frame_id = "odom"
    return msg


@pytest.fixture
def stack(ros_node: Node, spin_in_background: Callable[..., Any]) -> Callable[..., tuple[BehaviorServer, Robot]]:
    """``stack(pose=(0, 0, 0), active=True, parameters={})``: a behavior_server with the parameters
    and its robot at ``pose``; the wall's costmap published."""
    costmap_pub = ros_node.create_publisher(OccupancyGridMsg, "local_costmap/costmap", LATCHED)
    costmap_pub.publish(wall_costmap(ros_node.get_clock().now().to_msg()))

    def start(pose: tuple[float, float, float] = (0.0, 0.0, 0.0), active: bool = True,
              parameters: dict[str, Any] | None = None) -> tuple[BehaviorServer, Robot]:
        server = BehaviorServer(parameter_overrides=[Parameter(k, value=v) for k, v in (parameters or {}).items()])
        robot = Robot(server, pose)
        spin_in_background(server, robot)
        if active:
            server.trigger_configure()
            server.trigger_activate()
        wait_until(lambda: server._costmap is not None, 10, "the costmap at the server", node=ros_node)
        return server, robot
    return start


def run(node: Node, action: Any, name: str, goal: Any, timeout_s: float = 30.0) -> tuple[int, Any, list[Any]]:
    """Send ``goal`` and wait for its end: (status, result, feedback messages)."""
    client = ActionClient(node, action, name)
    assert client.wait_for_server(timeout_sec=10)
    feedback: list[Any] = []
    handle = send_goal(client, goal, node, feedback_callback=lambda msg: feedback.append(msg.feedback))
    assert handle.accepted
    result = ended(node, handle, timeout_s)
    return result.status, result.result, feedback


def ended(node: Node, handle: Any, timeout_s: float = 10.0, while_waiting: Callable[[], Any] = lambda: None) -> Any:
    """The goal's result (status and result) once it has ended; ``while_waiting`` runs between polls."""
    done = handle.get_result_async()
    wait_until(lambda: (while_waiting(), done.done())[1], timeout_s, "the goal's end", node=node)
    return done.result()


SUCCEEDED, CANCELED, ABORTED = 4, 5, 6


def allowance(seconds: float) -> Any:
    return Duration(seconds=seconds).to_msg()


def test_an_inactive_server_refuses_goals(ros_node, stack):
    stack(active=False)
    client = ActionClient(ros_node, Spin, "spin")
    assert client.wait_for_server(timeout_sec=10)
    assert not send_goal(client, Spin.Goal(target_yaw=1.0), ros_node).accepted


def test_spin_turns_its_angle_with_feedback_and_stops(ros_node, stack):
    _, robot = stack()
    status, result, feedback = run(ros_node, Spin, "spin", Spin.Goal(target_yaw=-1.2, time_allowance=allowance(10)))
    assert status == SUCCEEDED and result.error_code == Spin.Result.NONE
    assert robot.pose[2] == pytest.approx(-1.2, abs=0.1)
    assert feedback and feedback[-1].angular_distance_traveled > 0.8
    assert robot.commands[-1] == (0.0, 0.0)


def test_backup_drives_backwards_and_drive_on_heading_forwards(ros_node, stack):
    _, robot = stack()
    goal = BackUp.Goal(speed=0.1, time_allowance=allowance(10))
    goal.target.x = 0.2
    status, result, feedback = run(ros_node, BackUp, "backup", goal)
    assert status == SUCCEEDED and result.error_code == BackUp.Result.NONE
    assert robot.pose[0] == pytest.approx(-0.2, abs=0.03) and feedback[-1].distance_traveled > 0.1
    drive = DriveOnHeading.Goal(speed=0.2, time_allowance=allowance(10))
    drive.target.x = 0.3
    status, result, _ = run(ros_node, DriveOnHeading, "drive_on_heading", drive)
    assert status == SUCCEEDED and robot.pose[0] == pytest.approx(0.1, abs=0.04)


def test_drive_on_heading_refuses_a_sideways_target_and_mismatched_signs(ros_node, stack):
    _, robot = stack()
    sideways = DriveOnHeading.Goal(speed=0.2)
    sideways.target.x, sideways.target.y = 0.3, 0.1
    status, result, _ = run(ros_node, DriveOnHeading, "drive_on_heading", sideways)
    assert status == ABORTED and result.error_code == DriveOnHeading.Result.INVALID_INPUT
    assert "target.y" in result.error_msg
    backwards = DriveOnHeading.Goal(speed=0.2)
    backwards.target.x = -0.3
    status, result, _ = run(ros_node, DriveOnHeading, "drive_on_heading", backwards)
    assert status == ABORTED and result.error_code == DriveOnHeading.Result.INVALID_INPUT
    assert "signs" in result.error_msg and robot.pose == (0.0, 0.0, 0.0)


def test_driving_at_a_wall_stops_with_collision_ahead_short_of_it(ros_node, stack):
    _, robot = stack(pose=(0.0, 0.0, 0.0))
    drive = DriveOnHeading.Goal(speed=0.25, time_allowance=allowance(20))
    drive.target.x = 2.0
    status, result, _ = run(ros_node, DriveOnHeading, "drive_on_heading", drive)
    assert status == ABORTED and result.error_code == DriveOnHeading.Result.COLLISION_AHEAD
    assert "collision ahead" in result.error_msg
    # Stopped with the wall's inscribed zone (x ≥ 0.7) about simulate_ahead_time · speed ahead.
    ahead = BehaviorServerParameters().simulate_ahead_time * 0.25
    assert 0.7 - ahead - 0.1 <= robot.pose[0] < 0.7
    assert robot.commands[-1] == (0.0, 0.0)


def test_a_spin_where_the_footprint_touches_the_wall_is_refused(ros_node, stack):
    _, robot = stack(pose=(0.75, 0.0, 0.0))
    status, result, _ = run(ros_node, Spin, "spin", Spin.Goal(target_yaw=1.0, time_allowance=allowance(10)))
    assert status == ABORTED and result.error_code == Spin.Result.COLLISION_AHEAD
    assert robot.pose[2] == pytest.approx(0.0, abs=0.05)


def test_a_stuck_robot_times_out(ros_node, stack):
    _, robot = stack()
    robot.frozen = True
    status, result, _ = run(ros_node, Spin, "spin", Spin.Goal(target_yaw=1.0, time_allowance=allowance(0.5)))
    assert status == ABORTED and result.error_code == Spin.Result.TIMEOUT
    assert "time allowance of 0.5 s" in result.error_msg


def test_wait_counts_down_and_a_cancel_ends_it(ros_node, stack):
    stack()
    status, result, feedback = run(ros_node, Wait, "wait", Wait.Goal(time=allowance(0.5)))
    assert status == SUCCEEDED and result.total_elapsed_time.sec * 1e9 + result.total_elapsed_time.nanosec >= 0.5e9
    left = [f.time_left.sec + f.time_left.nanosec * 1e-9 for f in feedback]
    assert left == sorted(left, reverse=True) and left[0] <= 0.5
    client = ActionClient(ros_node, Wait, "wait")
    assert client.wait_for_server(timeout_sec=10)
    handle = send_goal(client, Wait.Goal(time=allowance(60.0)), ros_node)
    cancel = handle.cancel_goal_async()
    wait_until(lambda: cancel.done() or None, 10, "the cancel", node=ros_node)
    result = ended(ros_node, handle)
    assert result.status == CANCELED


def test_a_new_behaviour_preempts_the_running_one(ros_node, stack):
    stack()
    client = ActionClient(ros_node, Wait, "wait")
    assert client.wait_for_server(timeout_sec=10)
    long_wait = send_goal(client, Wait.Goal(time=allowance(60.0)), ros_node)
    status, _, _ = run(ros_node, Spin, "spin", Spin.Goal(target_yaw=0.3, time_allowance=allowance(10)))
    assert status == SUCCEEDED
    result = ended(ros_node, long_wait)
    assert result.status == ABORTED and "preempted by a spin goal" in result.result.error_msg


def test_assisted_teleop_slows_towards_the_wall_and_ends_on_preempt(ros_node, stack):
    _, robot = stack(pose=(0.0, 0.0, 0.0))
    teleop = ros_node.create_publisher(Twist, "cmd_vel_teleop", 10)
    preempt = ros_node.create_publisher(Empty, "preempt_teleop", 10)
    client = ActionClient(ros_node, AssistedTeleop, "assisted_teleop")
    assert client.wait_for_server(timeout_sec=10)
    handle = send_goal(client, AssistedTeleop.Goal(time_allowance=allowance(60)), ros_node)
    command = Twist()
    command.linear.x = 0.5

    def near_the_wall() -> bool | None:
        teleop.publish(command)
        return robot.pose[0] > 0.45 or None
    wait_until(near_the_wall, 30, "the robot near the wall", node=ros_node)
    # Going on at 0.5 m/s would put the footprint on the wall within the 1 s projection: slower.
    wait_until(lambda: (teleop.publish(command), 0.0 < robot.command[0] < 0.5)[1] or None, 10,
               "a scaled-down command", node=ros_node)
    wait_until(lambda: (teleop.publish(command), robot.command == (0.0, 0.0))[1] or None, 30,
               "a stop short of the wall", node=ros_node)
    assert robot.pose[0] < 0.7  # never inside the inscribed zone
    preempt.publish(Empty())
    result = ended(ros_node, handle, while_waiting=lambda: preempt.publish(Empty()))
    assert result.status == SUCCEEDED and result.result.error_code == AssistedTeleop.Result.NONE


def test_bad_settings_are_refused_naming_the_parameter(ros_node):
    with pytest.raises(Exception, match="'dance.plugin'.*must name the plugin's type"):  # no type, no default
        BehaviorServer(parameter_overrides=[Parameter("behavior_plugins", value=["spin", "dance"])])
    with pytest.raises(Exception, match="cycle_frequency"):
        BehaviorServer(parameter_overrides=[Parameter("cycle_frequency", value=0.0)])


def test_a_users_behaviour_is_found_by_its_type_name_and_runs(ros_node, stack, tmp_path, monkeypatch):
    install_user_plugins(tmp_path / "site", monkeypatch)
    with pytest.raises(ParameterError, match=r"'turn.yaw_rate' = 5.0"):  # its parameters, under its name
        BehaviorServer(parameter_overrides=[Parameter("behavior_plugins", value=["turn"]),
                                            Parameter("turn.plugin", value="pppbot_test_plugins::Turn"),
                                            Parameter("turn.yaw_rate", value=5.0)])
    _, robot = stack(parameters={"behavior_plugins": ["spin", "turn"],
                                 "turn.plugin": "pppbot_test_plugins/Turn",  # pluginlib's other spelling
                                 "turn.yaw_rate": 0.5})
    # Its own meaning of a Wait goal: turn at yaw_rate for the time, counting down.
    status, result, feedback = run(ros_node, Wait, "turn", Wait.Goal(time=allowance(1.0)))
    assert status == SUCCEEDED
    assert robot.pose[2] == pytest.approx(0.5, abs=0.1) and robot.pose[:2] == (0.0, 0.0)
    assert robot.commands[-1] == (0.0, 0.0)  # stopped by the server at the end
    left = [f.time_left.sec + f.time_left.nanosec * 1e-9 for f in feedback]
    assert left and left == sorted(left, reverse=True) and left[0] <= 1.0
    # What it refuses ends the goal with its reason (Wait has no INVALID_INPUT code: 0).
    status, result, _ = run(ros_node, Wait, "turn", Wait.Goal(time=allowance(0.0)))
    assert status == ABORTED and result.error_code == 0 and "the time must be positive" in result.error_msg
    # pppbot's own behaviours serve beside it.
    status, _, _ = run(ros_node, Spin, "spin", Spin.Goal(target_yaw=-0.5, time_allowance=allowance(10)))
    assert status == SUCCEEDED and robot.pose[2] == pytest.approx(0.0, abs=0.15)


def test_an_unknown_behaviour_type_names_the_group_and_what_is_installed(ros_node, tmp_path, monkeypatch):
    install_user_plugins(tmp_path / "site", monkeypatch)
    with pytest.raises(ParameterError) as refused:
        BehaviorServer(parameter_overrides=[Parameter("behavior_plugins", value=["dock"]),
                                            Parameter("dock.plugin", value="opennav_docking::Dock")])
    message = str(refused.value)
    assert "'dock.plugin' = 'opennav_docking::Dock'" in message and "'pppbot_nav.behaviors'" in message
    installed = message.split("installed: ")[1]
    for type_name in ("nav2_behaviors::Spin", "nav2_behaviors::BackUp", "nav2_behaviors::DriveOnHeading",
                      "nav2_behaviors::Wait", "nav2_behaviors::AssistedTeleop", "pppbot_test_plugins::Turn"):
        assert type_name in installed
