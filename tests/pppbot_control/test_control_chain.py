"""Over DDS with the simulator: priorities through twist_mux, 1 m through the whole chain,
odometry against ground truth, and the controller's handling of bad input."""
from __future__ import annotations

import math
from pathlib import Path

import pytest
import rclpy
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState

from pppbot_common.ros.wait import wait_for_messages, wait_until

pytestmark = pytest.mark.ros
ROOT = Path(__file__).resolve().parents[2]
PPPBOT = str(ROOT / "pppbot")
CONTROLLERS = str(ROOT / "config" / "my_controllers.yaml")
TWIST_MUX = str(ROOT / "config" / "twist_mux.yaml")
#: teleop's twist_mux timeout here (sim s): ppp_bot's 0.5 s is 0.25 s of wall time at the chain's
#: 2x, shorter than a stall of the test or of twist_mux on a busy machine, after which navigation
#: rightly gets through; 3 s (1.5 s of wall time) keeps the priority test about priorities.
TELEOP_TIMEOUT_S = 3.0


@pytest.fixture(scope="module")
def chain(request):
    """simulator (empty world, 2x real time) + diff_drive_base_controller + twist_mux."""
    from pppbot_common.process import ChildProcess, StopTimeouts

    children = [
        ChildProcess([PPPBOT, "run", "pppbot_sim", "simulator", "--ros-args", "-p", "world:=empty",
                      "-p", "real_time_factor:=2.0"], name="simulator", timeouts=StopTimeouts(3, 3)),
        ChildProcess([PPPBOT, "run", "pppbot_control", "diff_drive_controller", "--ros-args",
                      "--params-file", CONTROLLERS, "-p", "use_sim_time:=true"], name="controller",
                     timeouts=StopTimeouts(3, 3)),
        ChildProcess([PPPBOT, "run", "pppbot_control", "twist_mux", "--ros-args", "--params-file", TWIST_MUX,
                      "-p", "use_sim_time:=true", "-p", f"topics.teleop.timeout:={TELEOP_TIMEOUT_S}",
                      "-r", "cmd_vel_out:=/diff_drive_base_controller/cmd_vel_unstamped"],
                     name="twist_mux", timeouts=StopTimeouts(3, 3)),
    ]
    try:
        children[0].wait_for_output("lidar 'laser'", 30)
        children[1].wait_for_output("odometry from wheel positions", 30)
        children[2].wait_for_output("inputs: navigation", 30)
        yield {c.name: c for c in children}
    finally:
        for child in children:
            child.stop()


def distance(a: Odometry, b: Odometry) -> float:
    pa, pb = a.pose.pose.position, b.pose.pose.position
    return math.hypot(pa.x - pb.x, pa.y - pb.y)


def publisher(node, topic):
    pub = node.create_publisher(Twist, topic, 10)
    wait_until(lambda: pub.get_subscription_count() > 0, 10, f"a subscriber on {topic}")
    return pub


def twist(v: float, w: float = 0.0) -> Twist:
    msg = Twist()
    msg.linear.x, msg.angular.z = v, w
    return msg


def test_teleop_overrides_navigation_then_expires(ros_node, chain):
    nav = publisher(ros_node, "/cmd_vel")
    tele = publisher(ros_node, "/cmd_vel_teleop")
    seen: list[float] = []
    ros_node.create_subscription(Twist, "/diff_drive_base_controller/cmd_vel_unstamped",
                                 lambda m: seen.append(m.linear.x), 10)
    wait_until(lambda: (nav.publish(twist(0.2)), 0.2 in seen)[1], 10, "navigation through the mux", node=ros_node)
    seen.clear()
    # Both talk: only teleop's twists come out.
    for _ in range(20):
        nav.publish(twist(0.2))
        tele.publish(twist(-0.1))
        rclpy.spin_once(ros_node, timeout_sec=0.02)
    wait_until(lambda: -0.1 in seen, 5, "teleop's twist", node=ros_node)
    first_teleop = seen.index(-0.1)
    assert 0.2 not in seen[first_teleop:]
    # Teleop goes quiet: after its timeout (TELEOP_TIMEOUT_S of sim time) navigation gets through again.
    seen.clear()
    wait_until(lambda: (nav.publish(twist(0.2)), 0.2 in seen)[1], 10, "navigation again", node=ros_node)
    nav.publish(twist(0.0))


def standstill(node, tele, odoms: list[Odometry], truths: list[Odometry]) -> tuple[Odometry, Odometry]:
    """Stop the robot; (odometry, ground truth) once it stands still, the odometry no older than the
    truth (both then describe the same pose)."""
    wait_until(lambda: (tele.publish(twist(0.0)), len(truths) > 5
                        and all(abs(t.twist.twist.linear.x) < 1e-3 for t in truths[-5:]))[1], 10, "standstill",
               node=node)
    truth = truths[-1]
    still = truth.header.stamp
    wait_until(lambda: odoms and (odoms[-1].header.stamp.sec, odoms[-1].header.stamp.nanosec)
               >= (still.sec, still.nanosec), 5, "odometry at the standstill", node=node)
    return odoms[-1], truth


@pytest.mark.exclusive  # free running: a late stop overshoots
def test_one_metre_through_the_whole_chain(ros_node, chain):
    tele = publisher(ros_node, "/cmd_vel_teleop")
    odoms: list[Odometry] = []
    truths: list[Odometry] = []
    ros_node.create_subscription(Odometry, "/diff_drive_base_controller/odom", odoms.append, 10)
    ros_node.create_subscription(Odometry, "/ground_truth/odom", truths.append, 10)
    # The previous test may leave the robot rolling: start from a standstill, like the end.
    odom0, truth0 = standstill(ros_node, tele, odoms, truths)
    v, decel = 0.3, 1.0  # ppp_bot: linear.x.max_acceleration 1.0 (also the deceleration)
    stop_at = 1.0 - v * v / (2 * decel)
    wait_until(lambda: (tele.publish(twist(v)), distance(odoms[-1], odom0) >= stop_at)[1], 30,
               "0.95 m of odometry", node=ros_node)
    seen = distance(odoms[-1], odom0)  # where the test saw the robot when it sent the stop
    odom1, truth1 = standstill(ros_node, tele, odoms, truths)
    travelled = distance(truth1, truth0)
    measured = distance(odom1, odom0)
    # Free running, the stop goes out when this test sees 0.955 m: on a busy machine it sees that
    # late (clean-clone runs on loaded machines stopped at 1.030 and 1.107 m), each 0.1 s 3 cm
    # more. The robot drove its metre and stopped within 0.2 m of where the stop went out (0.045 m
    # of braking, the rest the commands and odometry on their way).
    assert 0.97 <= travelled <= seen + 0.2
    assert measured == pytest.approx(travelled, rel=0.01)  # what the chain must get right: odometry


def test_controller_publishes_odometry_tf_and_wheel_commands(ros_node, chain):
    (odom,) = wait_for_messages(ros_node, Odometry, "/diff_drive_base_controller/odom", timeout_s=10)
    assert (odom.header.frame_id, odom.child_frame_id) == ("odom", "base_link")
    assert odom.pose.covariance[0] == pytest.approx(0.001) and odom.pose.covariance[35] == pytest.approx(0.01)
    (cmd,) = wait_for_messages(ros_node, JointState, "/joint_commands", timeout_s=10)
    assert list(cmd.name) == ["left_wheel_joint", "right_wheel_joint"]


def test_non_finite_command_is_dropped_with_a_warning(ros_node, chain):
    pub = ros_node.create_publisher(Twist, "/diff_drive_base_controller/cmd_vel_unstamped", 10)
    wait_until(lambda: pub.get_subscription_count() > 0, 10, "the controller")
    pub.publish(twist(math.nan))
    chain["controller"].wait_for_output(r"dropping a velocity command with non-finite values \(v=nan", 10)
    assert chain["controller"].running()


@pytest.mark.parametrize("param, message", [
    ("wheel_radius:=0.0", "parameter 'wheel_radius' = 0.0: must be a finite number in (0.0, 1000.0]"),
    ("linear.x.max_acceleration:=-1.0", "parameter 'linear.x.max_acceleration' = -1.0: must be positive"),
    # Jazzy's signs: a Humble-style positive deceleration is refused, naming it, as Jazzy's validation does.
    ("linear.x.max_deceleration:=2.0", "parameter 'linear.x.max_deceleration' = 2.0: must be negative"),
    ("left_wheel_names:=['']", "parameter 'left_wheel_names' = ['']: must be a non-empty list of joint names"),
])
def test_bad_parameters_stop_the_controller(spawn, param, message):
    child = spawn([PPPBOT, "run", "pppbot_control", "diff_drive_controller", "--ros-args", "-p", param],
                  name="bad-controller")
    assert child.wait(30) == 1
    assert message in child.output


