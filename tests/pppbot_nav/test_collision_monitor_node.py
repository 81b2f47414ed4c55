"""The collision monitor node over DDS: quiet until active; a scan inside the stop polygon turns a
command into a stop (and says so on the state topic), a clear scan lets it through; bad
parameters are refused at configure by name."""
from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import pytest
import rclpy
from geometry_msgs.msg import PolygonStamped, Twist
from nav2_msgs.msg import CollisionMonitorState
from rclpy.lifecycle import TransitionCallbackReturn
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import LaserScan

from pppbot_common.ros.qos import LATCHED, SENSOR
from pppbot_common.ros.wait import wait_until
from pppbot_nav.ros.collision_monitor import CollisionMonitor

pytestmark = pytest.mark.ros

STOP_BOX = "[[0.4, 0.3], [0.4, -0.3], [0.0, -0.3], [0.0, 0.3]]"
PARAMETERS = {"polygons": ["PolygonStop"], "PolygonStop.type": "polygon", "PolygonStop.points": STOP_BOX,
              "PolygonStop.action_type": "stop", "PolygonStop.min_points": 4, "PolygonStop.visualize": True,
              "PolygonStop.polygon_pub_topic": "polygon_stop", "observation_sources": ["scan"],
              "scan.type": "scan", "scan.topic": "scan", "source_timeout": 60.0}


def monitor(**changes: Any) -> CollisionMonitor:
    """A collision monitor with one stop box ahead and a lidar 0.1 m ahead of base_link."""
    values = {**PARAMETERS, **changes}
    node = CollisionMonitor(parameter_overrides=[Parameter(k, value=v) for k, v in values.items()])
    node.tf.set_transform("odom", "base_link", 0.0, (0.0, 0.0, 0.0), static=True)
    node.tf.set_transform("base_link", "lidar", 0.0, (0.1, 0.0, 0.0), static=True)
    return node


def scan(node: Node, obstacle_m: float | None) -> LaserScan:
    """A scan of 37 beams over ±90° with a return at ``obstacle_m`` for the beams within ±10° (none elsewhere)."""
    msg = LaserScan()
    msg.header.frame_id = "lidar"
    msg.header.stamp = node.get_clock().now().to_msg()
    msg.angle_min, msg.angle_increment = -math.pi / 2, math.pi / 36
    msg.range_min, msg.range_max = 0.05, 10.0
    angles = [msg.angle_min + i * msg.angle_increment for i in range(37)]
    msg.ranges = [obstacle_m if obstacle_m is not None and abs(a) <= math.radians(10.5) else math.inf
                  for a in angles]
    return msg


def forward(x: float) -> Twist:
    msg = Twist()
    msg.linear.x = x
    return msg


@pytest.fixture
def spin(spin_in_background: Callable[..., Any]) -> Callable[[Node], None]:
    """``spin(node)``: spin ``node`` in an executor thread until the test ends (then destroy it)."""
    return spin_in_background


class Rig:
    """The test node's side: scans and commands in, outputs, states and polygons as received."""

    def __init__(self, ros_node: Node, cm: CollisionMonitor) -> None:
        self.node, self.cm = ros_node, cm
        self.outputs: list[Twist] = []
        self.states: list[CollisionMonitorState] = []
        self.polygons: list[PolygonStamped] = []
        ros_node.create_subscription(Twist, "cmd_vel", self.outputs.append, 100)
        ros_node.create_subscription(CollisionMonitorState, "collision_monitor_state", self.states.append, 100)
        ros_node.create_subscription(PolygonStamped, "polygon_stop", self.polygons.append, LATCHED)
        self.scans = ros_node.create_publisher(LaserScan, "scan", SENSOR)
        self.commands = ros_node.create_publisher(Twist, "cmd_vel_smoothed", 10)
        wait_until(lambda: self.scans.get_subscription_count() and self.commands.get_subscription_count()
                   and cm.output.get_subscription_count() and cm.state_pub.get_subscription_count(),
                   10, "the collision monitor's topics matched", node=ros_node)

    def see(self, obstacle_m: float | None) -> None:
        """Publish scans (best effort: again until one arrives) until the node holds one."""
        msg = scan(self.node, obstacle_m)

        def arrived() -> bool:
            held = self.cm.latest.get("scan")
            if held is None or held.header.stamp != msg.header.stamp:
                self.scans.publish(msg)
                return False
            return True
        wait_until(arrived, 10, "the scan reaching the collision monitor", node=self.node)

    def command(self, x: float) -> Twist:
        """Send a command; the checked command that comes out."""
        count = len(self.outputs)
        self.commands.publish(forward(x))
        wait_until(lambda: len(self.outputs) > count, 10, "the checked command", node=self.node)
        return self.outputs[count]


def test_a_scan_in_the_stop_polygon_stops_the_robot_and_a_clear_one_lets_it_go(ros_node, spin):
    cm = monitor()
    assert cm.trigger_configure() == TransitionCallbackReturn.SUCCESS
    assert cm.trigger_activate() == TransitionCallbackReturn.SUCCESS
    spin(cm)
    rig = Rig(ros_node, cm)
    rig.see(0.2)  # returns 0.3 m ahead of base_link: inside the 0.4 m box
    assert rig.command(0.3).linear.x == 0.0
    wait_until(lambda: rig.states and rig.polygons, 10, "the state and the polygon", node=ros_node)
    assert (rig.states[0].action_type, rig.states[0].polygon_name) == (CollisionMonitorState.STOP, "PolygonStop")
    polygon = rig.polygons[0]
    assert polygon.header.frame_id == "base_link"
    corners = [c for p in polygon.polygon.points for c in (p.x, p.y)]
    assert corners == pytest.approx([0.4, 0.3, 0.4, -0.3, 0.0, -0.3, 0.0, 0.3])
    rig.see(1.0)  # 1.1 m ahead: clear
    passed = rig.command(0.3)
    assert passed.linear.x == pytest.approx(0.3) and passed.angular.z == 0.0
    wait_until(lambda: len(rig.states) >= 2, 10, "the state changing back", node=ros_node)
    assert (rig.states[1].action_type, rig.states[1].polygon_name) == (CollisionMonitorState.DO_NOTHING, "")


def test_without_a_scan_the_robot_is_stopped_for_an_invalid_source(ros_node, spin):
    cm = monitor()
    assert cm.trigger_configure() == TransitionCallbackReturn.SUCCESS
    assert cm.trigger_activate() == TransitionCallbackReturn.SUCCESS
    spin(cm)
    rig = Rig(ros_node, cm)
    assert rig.command(0.3).linear.x == 0.0
    wait_until(lambda: rig.states, 10, "the state", node=ros_node)
    assert rig.states[0].polygon_name == "invalid source"


def test_nothing_is_published_while_inactive(ros_node, spin):
    cm = monitor()
    assert cm.trigger_configure() == TransitionCallbackReturn.SUCCESS
    spin(cm)
    rig = Rig(ros_node, cm)
    rig.see(1.0)
    rig.commands.publish(forward(0.11))
    wait_until(lambda: cm.ignored_inactive == 1, 10, "the command reaching the inactive node", node=ros_node)
    cm.trigger_activate()
    # The first output is the command sent once active: nothing came out before (one writer's order).
    assert rig.command(0.22).linear.x == pytest.approx(0.22)
    assert [m.linear.x for m in rig.outputs] == pytest.approx([0.22])


@pytest.mark.parametrize("name, value", [
    ("PolygonStop.action_type", "halt"), ("PolygonStop.points", "[[0.0, 0.0], [1.0, 0.0]]"),
    ("PolygonStop.type", "velocity_polygon"), ("PolygonStop.polygon_sub_topic", "polygon"),
    ("PolygonStop.max_points", 3), ("PolygonStop.slowdown_ratio", 2.0), ("scan.type", "pointcloud"),
    ("source_timeout", -1.0), ("PolygonStop.sources_names", ["lidar"]),
])
def test_bad_parameters_fail_configure_naming_them(name: str, value: Any):
    rclpy.init()
    try:
        cm = monitor(**{name: value})
        assert cm.trigger_configure() == TransitionCallbackReturn.FAILURE
        assert f"'{name}'" in cm.configure_failure and cm.state == "unconfigured"
        cm.destroy_node()
    finally:
        rclpy.shutdown()
