"""The controller alone over DDS: odometry from wheel positions carries the wheels' stamp.

(Its own module: the simulator of test_control_chain would feed it joint states.)"""
from __future__ import annotations

from pathlib import Path

import pytest
import rclpy
from builtin_interfaces.msg import Time
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from pppbot_common.ros.wait import wait_until

pytestmark = pytest.mark.ros
ROOT = Path(__file__).resolve().parents[2]
PPPBOT = str(ROOT / "pppbot")
CONTROLLERS = str(ROOT / "config" / "my_controllers.yaml")


def test_odometry_is_stamped_when_the_wheels_were_measured(ros_node, spawn):
    # From wheel positions the pose is the robot's at the joint states' stamp, not at the
    # controller's later update: odom → base_link at a scan's stamp is where it scanned.
    controller = spawn([PPPBOT, "run", "pppbot_control", "diff_drive_controller", "--ros-args", "--params-file",
                        CONTROLLERS, "-p", "use_sim_time:=true"], name="controller")
    controller.wait_for_output("odometry from wheel positions", 30)
    clock = ros_node.create_publisher(Clock, "/clock", 10)
    joints = ros_node.create_publisher(JointState, "/joint_states", 10)
    odoms: list[Odometry] = []
    ros_node.create_subscription(Odometry, "/diff_drive_base_controller/odom", odoms.append, 10)
    wait_until(lambda: joints.get_subscription_count() and clock.get_subscription_count(), 10, "the controller")
    measured = JointState(name=["left_wheel_joint", "right_wheel_joint"], position=[1.0, 1.0], velocity=[0.0, 0.0])
    measured.header.stamp.sec, measured.header.stamp.nanosec = 9, 500_000_000

    for _ in range(20):  # the wheels are measured before the controller's clock starts
        joints.publish(measured)
        rclpy.spin_once(ros_node, timeout_sec=0.02)

    def tick() -> bool:
        clock.publish(Clock(clock=Time(sec=10)))  # the controller's "now" is half a second later
        joints.publish(measured)
        return bool(odoms)

    wait_until(tick, 10, "odometry", node=ros_node)
    assert (odoms[-1].header.stamp.sec, odoms[-1].header.stamp.nanosec) == (9, 500_000_000)
