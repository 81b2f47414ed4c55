"""The controller alone over DDS, on Jazzy's terms: Jazzy-signed limits, stale stamped commands
dropped, odometry on ~/odom that a parameter set does not reset."""
from __future__ import annotations

from pathlib import Path

import pytest
import rclpy
from geometry_msgs.msg import TwistStamped
from nav_msgs.msg import Odometry
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState

from pppbot_common.ros.wait import wait_until

pytestmark = pytest.mark.ros
ROOT = Path(__file__).resolve().parents[2]
PPPBOT = str(ROOT / "pppbot")
CONTROLLERS = str(ROOT / "config" / "my_controllers.yaml")
NODE = "/diff_drive_base_controller"


def start(spawn, *params: str):
    """The controller on the wall clock with ppp_bot's file and ``params`` on top."""
    args = [PPPBOT, "run", "pppbot_control", "diff_drive_controller", "--ros-args", "--params-file", CONTROLLERS,
            "-p", "use_sim_time:=false"]
    for p in params:
        args += ["-p", p]
    child = spawn(args, name="controller")
    child.wait_for_output("odometry from wheel positions", 30)
    return child


def test_jazzy_signed_limits_are_accepted(spawn):
    child = start(spawn, "linear.x.max_deceleration:=-2.0", "linear.x.max_acceleration_reverse:=-1.0",
                  "linear.x.max_deceleration_reverse:=2.0", "angular.z.max_deceleration:=-1.5")
    assert child.running()
    assert "must be" not in child.output


def test_a_stale_stamped_command_is_dropped(ros_node, spawn):
    child = start(spawn, "use_stamped_vel:=true")
    commands: list[JointState] = []
    ros_node.create_subscription(JointState, "/joint_commands", commands.append, 10)
    pub = ros_node.create_publisher(TwistStamped, f"{NODE}/cmd_vel", 10)
    wait_until(lambda: pub.get_subscription_count() > 0, 10, "the controller on ~/cmd_vel")

    def command(age_s: float) -> TwistStamped:
        msg = TwistStamped()
        msg.twist.linear.x = 0.5
        now_ns = ros_node.get_clock().now().nanoseconds - int(age_s * 1e9)
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(now_ns, 1_000_000_000)
        return msg

    pub.publish(command(2.0))  # older than cmd_vel_timeout (0.5 s): dropped
    child.wait_for_output(r"dropping a velocity command stamped .*older than cmd_vel_timeout 0.5 s", 10)
    commands.clear()
    for _ in range(20):
        rclpy.spin_once(ros_node, timeout_sec=0.02)
    assert commands and all(max(abs(v) for v in c.velocity) == 0.0 for c in commands)

    def moving() -> bool:
        pub.publish(command(0.0))
        return bool(commands) and commands[-1].velocity[0] > 0.0

    wait_until(moving, 10, "a fresh command driving the wheels", node=ros_node)


def test_a_parameter_set_keeps_the_odometry(ros_node, spawn):
    start(spawn)
    joints = ros_node.create_publisher(JointState, "/joint_states", 10)
    odoms: list[Odometry] = []
    ros_node.create_subscription(Odometry, f"{NODE}/odom", odoms.append, 10)
    wait_until(lambda: joints.get_subscription_count() > 0, 10, "the controller on /joint_states")
    angle = [0.0]

    def roll(to_rad: float) -> None:  # both wheels forward: 0.05 m of travel per radian
        while True:
            msg = JointState(name=["left_wheel_joint", "right_wheel_joint"], position=[angle[0]] * 2,
                             velocity=[0.0, 0.0])
            msg.header.stamp = ros_node.get_clock().now().to_msg()
            joints.publish(msg)
            rclpy.spin_once(ros_node, timeout_sec=0.02)
            if angle[0] >= to_rad:
                return
            angle[0] = min(to_rad, angle[0] + 0.5)

    def republished() -> bool:
        roll(angle[0])
        return bool(odoms)

    def settled_x() -> float:
        """Odometry x once the wheels, measured again where they stand, no longer move it."""
        previous = None
        while True:
            wait_until(republished, 10, "odometry", node=ros_node)
            x = odoms[-1].pose.pose.position.x
            odoms.clear()
            if previous is not None and abs(x - previous) < 1e-9:
                return x
            previous = x

    roll(0.0)
    roll(20.0)
    before = settled_x()
    assert 0.5 < before <= 1.0 + 1e-9  # 20 rad of 0.05 m wheels (the first readings may miss a new match)

    client = ros_node.create_client(SetParameters, f"{NODE}/set_parameters")
    assert client.wait_for_service(timeout_sec=10)
    request = SetParameters.Request(parameters=[Parameter("publish_rate", value=25.0).to_parameter_msg(),
                                                Parameter("cmd_vel_timeout", value=0.4).to_parameter_msg()])
    future = client.call_async(request)
    result = wait_until(lambda: future.result() if future.done() else None, 10, "set_parameters", node=ros_node)
    assert all(r.successful for r in result.results)
    assert settled_x() == before  # the set kept the odometry
    roll(40.0)
    assert settled_x() == pytest.approx(before + 1.0)  # and it goes on from there
