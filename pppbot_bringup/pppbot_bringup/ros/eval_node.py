"""The evaluation's own node: records ground truth, the estimate and collisions, and drives the route
or sends navigation goals.

Route commands go to ``/cmd_vel_teleop`` (twist_mux's teleop input) at :data:`COMMAND_PERIOD_S`
of sim time, computed from ground truth by the route driver. Navigation goals go to the
navigator's ``navigate_to_pose`` action, as RViz's Nav2 panel sends them.
"""
from __future__ import annotations

import time

import rclpy
from geometry_msgs.msg import PointStamped, PoseStamped, PoseWithCovarianceStamped, Twist, Vector3
from nav2_msgs.action import NavigateToPose
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from nav_msgs.msg import Odometry
from pppbot_common.ros.action_client import ActionClient
from rclpy.executors import SingleThreadedExecutor
from rclpy.task import Future
from rclpy.signals import SignalHandlerOptions
from std_srvs.srv import Empty
from tf2_msgs.msg import TFMessage

from pppbot_bringup.eval.driver import RouteDriver
from pppbot_bringup.eval.scenarios import Estimate, Recording
from pppbot_common.ros.maps import grid_from_message
from pppbot_common.ros.planar import planar_transforms, stamp_seconds
from pppbot_common.ros.qos import DEFAULT, LATCHED
from pppbot_common.se2 import quaternion_from_yaw, yaw_from_quaternion

#: The route driver commands at 20 Hz of sim time, a teleop's or a controller's rate
#: (every ground-truth message would be 500 commands a wall second at 10× real time).
COMMAND_PERIOD_S = 0.05
MAX_CALLBACKS_PER_SPIN = 100


class EvalNode:
    """Records ground truth, the estimate and collisions; drives the route on ground truth (with a
    ``driver``), or leaves driving to the navigator (without one, ``navigates``)."""

    def __init__(self, estimate: Estimate, driver: RouteDriver | None, recording: Recording, wants_map: bool = False,
                 localizes: bool = False, navigates: bool = False) -> None:
        self.context = rclpy.Context()
        rclpy.init(args=[], context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node("pppbot_eval", context=self.context, start_parameter_services=False)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.estimate = estimate
        self.driver = driver
        self.recording = recording
        self.wanted_edges = set(estimate.edges())
        self.driving = False
        self._next_command_s = 0.0
        self.last_truth_wall_s = time.monotonic()
        self.sim_now_s: float | None = None
        self.truth_pose: tuple[float, float, float] | None = None
        self.cmd_pub = self.node.create_publisher(Twist, "/cmd_vel_teleop", DEFAULT)
        self.node.create_subscription(Odometry, "/ground_truth/odom", self._on_truth, 100)
        if estimate.topic is not None:
            self.node.create_subscription(Odometry, estimate.topic, self._on_estimate, 100)
        else:
            self.node.create_subscription(TFMessage, "/tf", self._on_tf, 200)
            self.node.create_subscription(TFMessage, "/tf_static", self._keep_edges, LATCHED)
        self.node.create_subscription(PointStamped, "/ground_truth/collisions", self._on_collision, 100)
        if wants_map:
            self.node.create_subscription(OccupancyGridMsg, "/map", self._on_map, LATCHED)
        self.amcl_poses = 0
        if localizes:
            self.initial_pose_pub = self.node.create_publisher(PoseWithCovarianceStamped, "/initialpose", DEFAULT)
            self.node.create_subscription(PoseWithCovarianceStamped, "/amcl_pose", self._on_amcl_pose, LATCHED)
            self.global_client = self.node.create_client(Empty, "/reinitialize_global_localization")
        self.recoveries = 0  # of the current navigation goal, from its feedback
        if navigates:
            self.navigator = ActionClient(self.node, NavigateToPose, "navigate_to_pose")

    def send_goal(self, x: float, y: float, yaw: float) -> Future:
        """A NavigateToPose goal at (x, y, yaw) in ``map``; the future's result is its goal handle."""
        goal = NavigateToPose.Goal()
        goal.pose = PoseStamped()
        goal.pose.header.frame_id = "map"
        goal.pose.header.stamp = self.node.get_clock().now().to_msg()
        goal.pose.pose.position.x, goal.pose.pose.position.y = float(x), float(y)
        o = goal.pose.pose.orientation
        o.x, o.y, o.z, o.w = quaternion_from_yaw(yaw)
        self.recoveries = 0
        return self.navigator.send_goal_async(goal, feedback_callback=self._on_feedback)

    def _on_feedback(self, msg: NavigateToPose.Impl.FeedbackMessage) -> None:
        self.recoveries = int(msg.feedback.number_of_recoveries)

    def _on_amcl_pose(self, msg: PoseWithCovarianceStamped) -> None:
        self.amcl_poses += 1

    def amcl_listens(self) -> bool:
        return self.initial_pose_pub.get_subscription_count() > 0

    def send_initial_pose(self, x: float, y: float, yaw: float, covariance: list[float]) -> None:
        """What RViz's 2D Pose Estimate sends: a pose in ``map`` with its covariance."""
        msg = PoseWithCovarianceStamped()
        msg.header.frame_id = "map"
        msg.header.stamp = self.node.get_clock().now().to_msg()
        msg.pose.pose.position.x, msg.pose.pose.position.y = float(x), float(y)
        o = msg.pose.pose.orientation
        o.x, o.y, o.z, o.w = quaternion_from_yaw(yaw)
        msg.pose.covariance = [float(v) for v in covariance]
        self.initial_pose_pub.publish(msg)

    def start_global_localization(self) -> bool:
        """Ask AMCL to spread its particles over the map; False when the service did not answer."""
        if not self.global_client.wait_for_service(timeout_sec=10.0):
            return False
        future = self.global_client.call_async(Empty.Request())
        self.executor.spin_until_future_complete(future, timeout_sec=10.0)
        return future.done()

    def _on_truth(self, msg: Odometry) -> None:
        t = stamp_seconds(msg.header.stamp)
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        yaw = yaw_from_quaternion(q.x, q.y, q.z, q.w)
        self.sim_now_s = t
        self.truth_pose = (p.x, p.y, yaw)
        self.last_truth_wall_s = time.monotonic()
        if not self.driving:
            return
        self.recording.truth_rows.append((t, p.x, p.y, yaw))
        if self.driver is None:
            return
        if t < self._next_command_s and not self.driver.finished:
            return
        self._next_command_s = t + COMMAND_PERIOD_S
        v, w = self.driver.command(p.x, p.y, yaw)
        self.cmd_pub.publish(Twist(linear=_vector(v), angular=_vector(0.0, 0.0, w)))
        self.recording.route_progress = self.driver.progress
        self.recording.route_finished = self.driver.finished

    def _on_estimate(self, msg: Odometry) -> None:
        if self.driving:
            q = msg.pose.pose.orientation
            p = msg.pose.pose.position
            self.recording.estimate_rows.append((stamp_seconds(msg.header.stamp), p.x, p.y,
                                                 yaw_from_quaternion(q.x, q.y, q.z, q.w)))

    def _on_tf(self, msg: TFMessage) -> None:
        if self.driving:
            self._keep_edges(msg)

    def _keep_edges(self, msg: TFMessage) -> None:
        """Keep the estimate chain's edges; they are composed after the run (no extrapolation)."""
        for t in planar_transforms(msg):
            if (t.parent, t.child) in self.wanted_edges:
                self.recording.edge_rows.setdefault((t.parent, t.child), []).append((t.stamp_s, t.x, t.y, t.yaw))

    def _on_collision(self, msg: PointStamped) -> None:
        t = stamp_seconds(msg.header.stamp)
        self.recording.collisions.append((t, msg.point.x, msg.point.y))

    def _on_map(self, msg: OccupancyGridMsg) -> None:
        try:
            self.recording.final_map = grid_from_message(msg)
        except ValueError:
            return  # a malformed map is nobody's result; the next one replaces it
        self.recording.final_map_stamp_s = stamp_seconds(msg.header.stamp)

    def stop_robot(self) -> None:
        self.driving = False
        if self.driver is None:
            return  # the navigator drives: its goals are canceled or over
        for _ in range(3):
            self.cmd_pub.publish(Twist())

    def spin_once(self, timeout_s: float) -> None:
        self.executor.spin_once(timeout_sec=timeout_s)

    def spin_pending(self, timeout_s: float, limit: int = MAX_CALLBACKS_PER_SPIN) -> None:
        """Wait up to ``timeout_s`` for work, then run what is ready (one callback per spin_once)."""
        self.executor.spin_once(timeout_sec=timeout_s)
        for _ in range(limit):
            before = self.sim_now_s, len(self.recording.estimate_rows), len(self.recording.collisions)
            self.executor.spin_once(timeout_sec=0.0)
            if (self.sim_now_s, len(self.recording.estimate_rows), len(self.recording.collisions)) == before:
                break

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def _vector(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> Vector3:
    return Vector3(x=float(x), y=float(y), z=float(z))

