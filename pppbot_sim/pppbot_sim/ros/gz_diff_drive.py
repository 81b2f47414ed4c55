"""Gazebo's DiffDrive plugins on the simulator node, as ROS sees them through ros_gz_bridge.

Each plugin of the robot or of a world model (:mod:`pppbot_sim.gz_plugins`) takes
``geometry_msgs/Twist`` on its topic, sets its wheels' velocities every update, and publishes
``nav_msgs/Odometry`` on its odometry topic and the same pose as a ``tf2_msgs/TFMessage`` on its
TF topic (Gazebo's Pose_V, bridged), at its odometry rate, stamped with sim time. The robot's
plugin can listen on another topic than its own (``cmd_vel_topic``, what a bridge remapping does):
the bringup uses that to put twist_mux in front of it.
"""
from __future__ import annotations

import math
from collections.abc import Callable

from geometry_msgs.msg import TransformStamped, Twist
from nav_msgs.msg import Odometry
from rclpy.node import Node
from tf2_msgs.msg import TFMessage

from pppbot_common.ros.wire import MessageTemplate, stamp_fields, stamp_values
from pppbot_lockstep.ros.node import subscribe
from pppbot_lockstep.ros.runner import Warnings, guarded
from pppbot_sim.gz_plugins import DiffDriveSpec, DiffDriveSystem, Flavor, Pose2D
from pppbot_sim.simulation import Simulation

_POSE_FIELDS = ("pose.pose.position.x", "pose.pose.position.y", "pose.pose.orientation.z", "pose.pose.orientation.w",
                "twist.twist.linear.x", "twist.twist.angular.z")
_TF_FIELDS = ("transforms.0.transform.translation.x", "transforms.0.transform.translation.y",
              "transforms.0.transform.rotation.z", "transforms.0.transform.rotation.w")


class HostedDiffDrive:
    """One plugin: its subscription, publishers, state and the times of its next odometry."""

    def __init__(self, node: Node, sim: Simulation, spec: DiffDriveSpec, topic: str,
                 command: Callable[[dict[str, float]], None]) -> None:
        self.sim = sim
        self.spec = spec
        self.system = DiffDriveSystem(spec)
        self.command = command
        self.topic = topic
        self._warn = Warnings(node, 5.0)
        # In lockstep a step waits for the commands sent before it.
        self.subscription = subscribe(node, Twist, topic, guarded(node, self._on_twist, "Twist"), 10, data_path=True,
                                      needs_publisher=False)
        self.odom_pub = node.create_publisher(Odometry, spec.odom_topic, 10) if spec.publish_odom else None
        self.tf_pub = node.create_publisher(TFMessage, spec.tf_topic, 100) if spec.tf_topic else None
        odom = Odometry()
        odom.header.frame_id = spec.frame_id
        odom.child_frame_id = spec.child_frame_id
        if spec.flavor is Flavor.CLASSIC:  # the covariances libgazebo_ros_diff_drive publishes
            odom.pose.covariance[0] = odom.pose.covariance[7] = 1e-5
            odom.pose.covariance[14] = odom.pose.covariance[21] = odom.pose.covariance[28] = 1e12
            odom.pose.covariance[35] = 1e-3
        self._odom_wire = MessageTemplate(odom, [*stamp_fields(), *_POSE_FIELDS])
        transform = TransformStamped()
        transform.header.frame_id = spec.frame_id
        transform.child_frame_id = spec.child_frame_id
        self._tf_wire = MessageTemplate(TFMessage(transforms=[transform]),
                                        [*stamp_fields("transforms.0.header.stamp"), *_TF_FIELDS])
        self._last_s: float | None = None
        self._next_odom_s = 0.0

    def _on_twist(self, msg: Twist) -> None:
        try:
            self.system.command(msg.linear.x, msg.angular.z)
        except ValueError as exc:
            self._warn("nonfinite", f"{self.topic}: dropping a command: {exc}")

    def update(self, now_s: float, now_ns: int) -> None:
        """One update: wheel speeds from the last command, then odometry when it is due."""
        dt = 0.0 if self._last_s is None or now_s < self._last_s else now_s - self._last_s
        if self._last_s is not None and now_s < self._last_s:  # time went back (a reset)
            self.system.reset()
            self._next_odom_s = 0.0
        self._last_s = now_s
        self.command(self.system.wheel_speeds(dt))
        spec = self.spec
        if spec.odometry_from_world:
            pose = Pose2D(*self.sim.planar_state(spec.body))
        else:
            left, right = self.sim.joint_positions((spec.left_joints[0], spec.right_joints[0]))
            pose = self.system.integrate(left, right, dt)
        if now_s + 1e-9 < self._next_odom_s:
            return
        self._next_odom_s = (math.floor(now_s * spec.odom_rate_hz + 1e-6) + 1) / spec.odom_rate_hz
        qz, qw = math.sin(pose.yaw / 2.0), math.cos(pose.yaw / 2.0)
        stamp = stamp_values(now_ns)
        if self.odom_pub is not None:
            self.odom_pub.publish(self._odom_wire.serialize({
                **stamp, "pose.pose.position.x": pose.x, "pose.pose.position.y": pose.y,
                "pose.pose.orientation.z": qz, "pose.pose.orientation.w": qw,
                "twist.twist.linear.x": pose.v, "twist.twist.angular.z": pose.w}))
        if self.tf_pub is not None:
            self.tf_pub.publish(self._tf_wire.serialize({
                **stamp_values(now_ns, "transforms.0.header.stamp"),
                "transforms.0.transform.translation.x": pose.x, "transforms.0.transform.translation.y": pose.y,
                "transforms.0.transform.rotation.z": qz, "transforms.0.transform.rotation.w": qw}))

    def reset(self) -> None:
        """The robot or world was reset: odometry starts over, as Gazebo's plugins do."""
        self.system.reset()
        self._last_s = None
        self._next_odom_s = 0.0


def host_diff_drives(node: Node, sim: Simulation, cmd_vel_topic: str,
                     command: Callable[[dict[str, float]], None]) -> list[HostedDiffDrive]:
    """Every DiffDrive plugin of ``sim`` on ``node``; the robot's listens on ``cmd_vel_topic`` when
    that is not empty."""
    hosted = []
    for spec in sim.diff_drives:
        topic = cmd_vel_topic if cmd_vel_topic and not spec.body else spec.topic
        hosted.append(HostedDiffDrive(node, sim, spec, topic, command))
    return hosted
