"""The simulator node over DDS: topics, wheel commands (and bad ones), timeout, services, bad worlds."""
from __future__ import annotations

import math
import time
from pathlib import Path

import pytest
from nav_msgs.msg import Odometry
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState, LaserScan
from std_srvs.srv import Empty, Trigger

from pppbot_common.ros.wait import wait_for_messages, wait_until

pytestmark = pytest.mark.ros
PPPBOT = str(Path(__file__).resolve().parents[2] / "pppbot")
BOX_ROOM = str(Path(__file__).parent / "data" / "box_room.sdf")


def start_simulator(spawn, *params: str, name: str = "simulator"):
    args = [PPPBOT, "run", "pppbot_sim", "simulator", "--ros-args", "-p", f"world:={BOX_ROOM}"]
    for p in params:
        args += ["-p", p]
    child = spawn(args, name=name)
    child.wait_for_output(r"lidar 'laser': 640 beams", 30)
    return child


@pytest.fixture
def fast_sim(spawn):
    return start_simulator(spawn, "real_time_factor:=5.0")


def call(node, srv_type, name, request=None, timeout_s=10.0):
    client = node.create_client(srv_type, name)
    assert client.wait_for_service(timeout_sec=timeout_s), name
    future = client.call_async(request or srv_type.Request())
    result = wait_until(lambda: future.result() if future.done() else None, timeout_s, name, node=node)
    node.destroy_client(client)
    return result


def latest(node, msg_type, topic, timeout_s=10.0):
    return wait_for_messages(node, msg_type, topic, count=1, timeout_s=timeout_s)[0]


class SimClock:
    """The latest /clock, from one subscription kept for the whole test (so it survives pauses)."""

    def __init__(self, node):
        self.node, self.value = node, None
        node.create_subscription(Clock, "/clock", self._on_clock, 10)

    def _on_clock(self, msg):
        self.value = msg.clock.sec + msg.clock.nanosec * 1e-9

    def __call__(self) -> float:
        import rclpy
        rclpy.spin_once(self.node, timeout_sec=0.0)
        return wait_until(lambda: self.value, 10, "/clock", node=self.node)


def test_sensor_topics_look_like_gazebos(ros_node, fast_sim):
    scan = latest(ros_node, LaserScan, "/scan")
    assert scan.header.frame_id == "lidar_frame" and len(scan.ranges) == 640
    assert (scan.angle_min, scan.angle_max, scan.range_min, scan.range_max) == pytest.approx((-3.14, 3.14, 0.08, 20.0))
    assert scan.scan_time == pytest.approx(0.1)
    # In the 4 m box room every beam returns between 1.9 m and the corner distance.
    assert all(1.85 < r < 2.95 for r in scan.ranges)
    imu = latest(ros_node, Imu, "/imu")
    assert imu.header.frame_id == "imu_link"
    assert imu.linear_acceleration.z == pytest.approx(9.81, abs=0.1)
    joints = latest(ros_node, JointState, "/joint_states")
    assert list(joints.name) == ["left_wheel_joint", "right_wheel_joint"]
    assert len(joints.position) == len(joints.velocity) == 2
    odom = latest(ros_node, Odometry, "/ground_truth/odom")
    assert (odom.header.frame_id, odom.child_frame_id) == ("world", "base_link")
    assert odom.pose.pose.position.z == pytest.approx(0.05, abs=0.01)


def test_clock_runs_at_the_real_time_factor(ros_node, fast_sim):
    sim_time = SimClock(ros_node)
    t0_sim, t0_wall = sim_time(), time.monotonic()
    wait_until(lambda: time.monotonic() - t0_wall > 2.0, 5, "two wall seconds", node=ros_node)
    factor = (sim_time() - t0_sim) / (time.monotonic() - t0_wall)
    assert 3.5 < factor < 6.0


def command(pub, left, right, names=("left_wheel_joint", "right_wheel_joint")):
    pub.publish(JointState(name=list(names), velocity=[left, right]))


def test_wheel_commands_drive_the_robot_and_time_out(ros_node, fast_sim):
    sim_time = SimClock(ros_node)
    pub = ros_node.create_publisher(JointState, "/joint_commands", 10)
    wait_until(lambda: pub.get_subscription_count() > 0, 10, "the simulator's subscription")
    start = latest(ros_node, Odometry, "/ground_truth/odom").pose.pose.position.x
    speeds: list[float] = []
    ros_node.create_subscription(Odometry, "/ground_truth/odom",
                                 lambda msg: speeds.append(msg.twist.twist.linear.x), 10)
    # Keep commanding 5 rad/s on both wheels of radius 0.05 m until the robot drives at 0.25 m/s.
    # (A condition, not a duration: on a busy machine the test's commands may come late, and a
    # wheel the 0.5 s command timeout stopped meanwhile only takes longer to get there.)
    wait_until(lambda: (command(pub, 5.0, 5.0), len(speeds) > 3 and all(0.23 < v < 0.27 for v in speeds[-3:]))[1],
               30, "the robot driving at 0.25 m/s", node=ros_node)
    moved = latest(ros_node, Odometry, "/ground_truth/odom").pose.pose.position.x - start
    assert moved > 0.02
    # Silence: after the 0.5 s timeout the wheels stop by themselves. The timeout runs from the
    # last command the simulator heard, which on a busy machine may be a queued one heard well
    # after the test stopped sending: within 10 s of sim time, not 0.5 s (without the timeout the
    # wheels never stop). Judged on a /joint_states stamped in that window, not an older one.
    states: list[JointState] = []
    ros_node.create_subscription(JointState, "/joint_states", states.append, 10)
    t1 = sim_time()
    stamp = lambda msg: msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9  # noqa: E731
    stopped = lambda: bool(states) and stamp(states[-1]) > t1 and all(abs(v) < 0.2 for v in states[-1].velocity)  # noqa: E731
    wait_until(lambda: stopped() or sim_time() - t1 > 10.0, 30, "10 s without commands", node=ros_node)
    assert stopped(), states[-1].velocity


def test_bad_commands_are_rejected_with_a_warning(ros_node, fast_sim):
    pub = ros_node.create_publisher(JointState, "/joint_commands", 10)
    wait_until(lambda: pub.get_subscription_count() > 0, 10, "the simulator's subscription")
    start = latest(ros_node, Odometry, "/ground_truth/odom").pose.pose.position.x
    command(pub, 5.0, 5.0, names=("left_wheel_joint", "typo_joint"))
    fast_sim.wait_for_output(r"rejecting a joint command: not a driven joint: typo_joint", 10)
    command(pub, math.nan, 5.0)
    fast_sim.wait_for_output(r"non-finite velocity command: left_wheel_joint=nan", 10)
    pub.publish(JointState(name=["left_wheel_joint"], velocity=[]))
    fast_sim.wait_for_output(r"rejecting a joint command with 1 names and 0 velocities", 10)
    assert fast_sim.running()
    assert abs(latest(ros_node, Odometry, "/ground_truth/odom").pose.pose.position.x - start) < 0.01


def test_pause_step_unpause_and_reset(ros_node, spawn):
    sim = start_simulator(spawn, "real_time_factor:=2.0", "step_count:=50", name="sim-services")
    sim_time = SimClock(ros_node)
    sim_time()
    call(ros_node, Empty, "/pause_physics")
    t_wall = time.monotonic()
    wait_until(lambda: time.monotonic() - t_wall > 0.5, 2, "half a second", node=ros_node)
    paused_at = sim_time()
    wait_until(lambda: time.monotonic() - t_wall > 1.0, 2, "another half second", node=ros_node)
    assert sim_time() == paused_at  # no /clock while paused
    reply = call(ros_node, Trigger, "/step_physics")
    assert reply.success, reply.message
    assert "stepped 50 step(s)" in reply.message
    stepped_to = float(reply.message.rsplit("t = ", 1)[1].split()[0])
    assert stepped_to == pytest.approx(paused_at + 50 * 0.002, abs=0.0105)
    call(ros_node, Empty, "/unpause_physics")
    assert not call(ros_node, Trigger, "/step_physics").success
    # Drive away, then reset: back at the spawn pose, with time still going forward.
    pub = ros_node.create_publisher(JointState, "/joint_commands", 10)
    wait_until(lambda: pub.get_subscription_count() > 0, 10, "subscription")
    t0 = sim_time()
    wait_until(lambda: (command(pub, 8.0, 4.0), sim_time() - t0 > 1.0)[1], 20, "driving", node=ros_node)
    before_reset = sim_time()
    call(ros_node, Empty, "/reset_world")
    sim.wait_for_output(r"robot reset to its spawn pose", 10)
    odom = wait_for_messages(ros_node, Odometry, "/ground_truth/odom", timeout_s=10,
                             predicate=lambda m: m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 > before_reset)[0]
    assert math.hypot(odom.pose.pose.position.x, odom.pose.pose.position.y) < 0.01


@pytest.mark.exclusive  # the speed reached by the wall clock
def test_runtime_real_time_factor_change(ros_node, spawn):
    start_simulator(spawn, "real_time_factor:=1.0", name="sim-rtf")
    sim_time = SimClock(ros_node)
    request = SetParameters.Request(parameters=[Parameter("real_time_factor", value=8.0).to_parameter_msg()])
    (result,) = call(ros_node, SetParameters, "/simulator/set_parameters", request).results
    assert result.successful
    bad = SetParameters.Request(parameters=[Parameter("real_time_factor", value=-1.0).to_parameter_msg()])
    (refused,) = call(ros_node, SetParameters, "/simulator/set_parameters", bad).results
    assert not refused.successful and "real_time_factor" in refused.reason
    t0_sim, t0_wall = sim_time(), time.monotonic()
    wait_until(lambda: time.monotonic() - t0_wall > 1.5, 5, "1.5 wall seconds", node=ros_node)
    assert (sim_time() - t0_sim) / (time.monotonic() - t0_wall) > 5.0


@pytest.mark.parametrize("param, message", [
    ("world:=atlantis",
     "unknown world 'atlantis'; known worlds: cones, empty, maze, maze_boxes, office, room, room_boxes"),
    ("real_time_factor:=-2.0", "parameter 'real_time_factor' = -2.0: must be a finite number in [0.0, 1000.0]"),
    ("robot_description:=/no/such.urdf", "cannot read '/no/such.urdf'"),
])
def test_bad_start_stops_with_a_clear_message(spawn, param, message):
    child = spawn([PPPBOT, "run", "pppbot_sim", "simulator", "--ros-args", "-p", param], name="bad-sim")
    assert child.wait(30) == 1
    assert message in child.output
