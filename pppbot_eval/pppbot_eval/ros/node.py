"""The evaluation's own node: records ground truth, the estimate and collisions, and acts on its ticks.

What it does is its behaviour's (:mod:`pppbot_eval.ros.behaviors`): drive a route on
ground truth through ``/cmd_vel_teleop`` (twist_mux's teleop input), put AMCL off, send
navigation goals to ``navigate_to_pose`` as RViz's Nav2 panel does. It acts only on its
ticks (every :data:`~pppbot_eval.ros.behaviors.TICK_S` of sim time). In lockstep it
is a participant (``pppbot_eval``): time waits for it, so every tick happens at the same
sim time on every run, and it joins only once the nodes it talks to listen.
"""
from __future__ import annotations

import signal
import time
from collections.abc import Callable
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PointStamped, PoseStamped, PoseWithCovarianceStamped, Twist, Vector3
from nav2_msgs.action import NavigateThroughPoses, NavigateToPose
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from nav_msgs.msg import Odometry
from rclpy.experimental import EventsExecutor
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future
from slam_toolbox.srv import SerializePoseGraph
from std_srvs.srv import Empty
from tf2_msgs.msg import TFMessage

from pppbot_common.ros.maps import grid_from_message
from pppbot_common.ros.planar import planar_transforms, stamp_seconds
from pppbot_common.ros.qos import DEFAULT, LATCHED
from pppbot_common.se2 import quaternion_from_yaw, yaw_from_quaternion
from pppbot_common.upright import UprightWatch
from pppbot_eval.ros.behaviors import TICK_S, Behavior
from pppbot_eval.scenarios import Estimate, Recording
from pppbot_eval.trajectory import PoseRows
from pppbot_lockstep.ros.action_client import ActionClient
from pppbot_lockstep.ros.node import StepExecutor, StepNode
from pppbot_lockstep.ros.participant import Participant
from pppbot_lockstep.ros.port import FREE_RUNNING, StepPort

#: The lockstep participant's name, for the launch's list of whom time waits for.
PARTICIPANT = "pppbot_eval"


class EvalNode:
    """Records ground truth, the estimate and collisions; runs ``behavior`` on its ticks once
    :meth:`start` is called."""

    def __init__(self, estimate: Estimate, recording: Recording, wants_map: bool = False,
                 localizes: bool = False, navigates: bool = False, lockstep: bool = False,
                 goal_frame: str = "map", through_poses: bool = False) -> None:
        self.context = rclpy.Context()
        rclpy.init(args=[], context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.participant = Participant(PARTICIPANT, rclpy.create_node(
            f"_lockstep_{PARTICIPANT}", context=self.context, start_parameter_services=False,
            enable_rosout=False)) if lockstep else None
        port = self.participant if self.participant is not None else FREE_RUNNING
        self.node = StepNode("pppbot_eval", port=port, context=self.context, start_parameter_services=False,
                             parameter_overrides=[Parameter("use_sim_time", value=True)])
        handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
        self.executor = StepExecutor(self.participant, context=self.context) if self.participant is not None \
            else EventsExecutor(context=self.context)
        for sig, handler in handlers.items():  # the executor installs its own: the run's own handlers win
            if callable(handler):
                signal.signal(sig, handler)
        self.executor.add_node(self.node)
        if self.participant is not None:
            self.executor.add_node(self.participant.node)
            self.participant.start(self.executor, [self.node])
        self.estimate = estimate
        self.recording = recording
        self.wanted_edges = set(estimate.edges())
        self.behavior: Behavior | None = None
        self.started = False
        self._driving = False
        #: Wall time (monotonic) when the behaviour began driving: the run's speed is measured from it.
        self.driving_since_wall: float | None = None
        self.finished_wall: float | None = None
        self.last_truth_wall_s = time.monotonic()
        self.sim_now_s: float | None = None
        self.truth_pose: tuple[float, float, float] | None = None
        self.upright = UprightWatch()
        node = self.node
        self.cmd_pub = node.create_publisher(Twist, "/cmd_vel_teleop", DEFAULT)
        # What it hears it records (its timer acts on it): quiet subscriptions, no round of their own.
        if not navigates:
            port.require_match(node, self.cmd_pub)  # the route driver's commands
        node.create_subscription(Odometry, "/ground_truth/odom", self._on_truth, 100, data_path=True, quiet=True)
        if estimate.topic is not None:
            node.create_subscription(Odometry, estimate.topic, self._on_estimate, 100, data_path=True, quiet=True)
        else:
            node.create_subscription(TFMessage, "/tf", self._on_tf, 200, data_path=True, quiet=True)
            node.create_subscription(TFMessage, "/tf_static", self._keep_edges, LATCHED)
        node.create_subscription(PointStamped, "/ground_truth/collisions", self._on_collision, 100, data_path=True,
                                 quiet=True)
        if wants_map:
            node.create_subscription(OccupancyGridMsg, "/map", self._on_map, LATCHED)
            node.create_subscription(DiagnosticArray, "/diagnostics", self._on_diagnostics, 10)
        self.amcl_poses = 0
        self.localizes = localizes
        self.goal_frame = goal_frame
        if localizes:
            self.initial_pose_pub = node.create_publisher(PoseWithCovarianceStamped, "/initialpose", DEFAULT)
            port.require_match(node, self.initial_pose_pub)
            node.create_subscription(PoseWithCovarianceStamped, "/amcl_pose", self._on_amcl_pose, LATCHED,
                                     data_path=True, quiet=True)
            self.global_client = node.create_client(Empty, "/reinitialize_global_localization")
        self._recoveries = 0  # of the current navigation goal, from its feedback
        #: Servers the run needs before it starts, by name (a request sent before its server is
        #: discovered is lost). In lockstep the node joins only once they are there.
        self.servers: dict[str, Callable[[], bool]] = {}
        if localizes:
            self.servers["the reinitialize_global_localization service"] = self.global_client.service_is_ready
        #: Goals go to navigate_through_poses as one-pose goals (the through-poses tree), not navigate_to_pose.
        self.through_poses = through_poses
        if navigates:
            self._navigation_client(node)
        if wants_map:
            self.serialize_client = node.create_client(SerializePoseGraph, "/slam_toolbox/serialize_map")
            self.servers["the serialize_map service"] = self.serialize_client.service_is_ready
        for what, ready in self.servers.items():
            port.require_when(what, ready)
        node.step_timer(TICK_S, self._tick)

    def _navigation_client(self, node: Any) -> None:
        action, name = ((NavigateThroughPoses, "navigate_through_poses") if self.through_poses
                        else (NavigateToPose, "navigate_to_pose"))
        self.navigator = ActionClient(node, action, name)
        self.servers[f"the {name} server"] = self.navigator.server_is_ready

    @property
    def port(self) -> StepPort:
        return self.node.port

    @property
    def driving(self) -> bool:
        """Whether the run is under way (recording ground truth and the estimate)."""
        return self._driving

    @driving.setter
    def driving(self, value: bool) -> None:
        if value and self.driving_since_wall is None:
            self.driving_since_wall = time.monotonic()
        self._driving = value

    def start(self) -> None:
        """From the next tick on, the behaviour acts."""
        self.started = True

    def _tick(self) -> None:
        if self.started and self.behavior is not None and self.behavior.outcome is None:
            self.behavior.tick(self)
            if self.behavior.outcome is not None:
                self.finished_wall = time.monotonic()
                # The record ends with the behaviour, at this sim time on every run: the steps this
                # process still answers until it stops its stack (their number depends on the
                # machine) are not part of it.
                self.driving = False

    def drive_wall_seconds(self) -> float:
        """Wall seconds from the start of driving to the behaviour's end (or to now)."""
        if self.driving_since_wall is None:
            return 0.0
        return (self.finished_wall or time.monotonic()) - self.driving_since_wall

    # ----------------------------------------------------------------- actions
    def command(self, linear_mps: float, angular_radps: float) -> None:
        self.cmd_pub.publish(Twist(linear=_vector(linear_mps), angular=_vector(0.0, 0.0, angular_radps)))

    def send_goal(self, x: float, y: float, yaw: float) -> Future:
        """A NavigateToPose goal at (x, y, yaw) in ``goal_frame`` (a one-pose NavigateThroughPoses goal with
        ``through_poses``); the future's result is its goal handle."""
        pose = PoseStamped()
        pose.header.frame_id = self.goal_frame
        pose.header.stamp = self.node.get_clock().now().to_msg()
        pose.pose.position.x, pose.pose.position.y = float(x), float(y)
        o = pose.pose.orientation
        o.x, o.y, o.z, o.w = quaternion_from_yaw(yaw)
        goal: Any = (NavigateThroughPoses.Goal(poses=[pose]) if self.through_poses
                     else NavigateToPose.Goal(pose=pose))
        self._recoveries = 0
        return self.navigator.send_goal_async(goal, feedback_callback=self._on_feedback)

    def recoveries(self) -> int:
        return self._recoveries

    def _on_feedback(self, msg: Any) -> None:
        self._recoveries = int(msg.feedback.number_of_recoveries)

    def _on_amcl_pose(self, msg: PoseWithCovarianceStamped) -> None:
        self.amcl_poses += 1

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

    def request_global_localization(self) -> Future:
        """Ask AMCL to spread its particles over the map."""
        return self.global_client.call_async(Empty.Request())

    def serialize(self, filename: str) -> Future:
        """Ask the slam node to write its pose graph to ``filename`` + ``.posegraph``
        (``/slam_toolbox/serialize_map``, slam_toolbox/srv/SerializePoseGraph)."""
        return self.serialize_client.call_async(SerializePoseGraph.Request(filename=filename))

    # --------------------------------------------------------------- records
    def _on_truth(self, msg: Odometry) -> None:
        t = stamp_seconds(msg.header.stamp)
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        yaw = yaw_from_quaternion(q.x, q.y, q.z, q.w)
        self.sim_now_s = t
        self.truth_pose = (p.x, p.y, yaw)
        changed = self.upright.update(t, p.z, (q.x, q.y, q.z, q.w))
        if changed is not None and not changed.upright and self.recording.not_upright is None:
            self.recording.not_upright = f"the robot is not upright: {changed.describe()}"
        self.last_truth_wall_s = time.monotonic()
        if self.driving:
            self.recording.truth_rows.append((t, p.x, p.y, yaw))

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
            edge = (t.parent, t.child)
            if edge in self.wanted_edges:
                self.recording.edge_rows.setdefault(edge, PoseRows()).append((t.stamp_s, t.x, t.y, t.yaw))

    def _on_collision(self, msg: PointStamped) -> None:
        if self.finished_wall is not None:  # after the behaviour: the robot stands, and it is not the run
            return
        t = stamp_seconds(msg.header.stamp)
        self.recording.collisions.append((t, msg.point.x, msg.point.y))

    @property
    def _final(self) -> bool:
        """The behaviour has ended and the first map after its end is kept: the record is complete (what
        comes later depends on how long this process takes to stop, which depends on the machine)."""
        rec = self.recording
        return self.finished_wall is not None and rec.final_map is not None and rec.final_map_stamp_s > rec.end_sim_s

    def _on_map(self, msg: OccupancyGridMsg) -> None:
        if self._final:
            return
        try:
            self.recording.final_map = grid_from_message(msg)
        except ValueError:
            return  # a malformed map is nobody's result; the next one replaces it
        self.recording.final_map_stamp_s = stamp_seconds(msg.header.stamp)

    def _on_diagnostics(self, msg: DiagnosticArray) -> None:
        if self._final:
            return
        for status in msg.status:
            if status.name.endswith(": mapping"):  # the slam node's health (its node name first)
                self.recording.slam_health = {v.key: v.value for v in status.values}

    # ------------------------------------------------------------------ loop
    def stop_robot(self) -> None:
        self.driving = False
        for _ in range(3):
            self.cmd_pub.publish(Twist())

    def spin_pending(self, timeout_s: float) -> None:
        """Run what is ready, waiting up to ``timeout_s`` for it (and join lockstep once ready)."""
        self.executor.spin_once(timeout_sec=timeout_s)
        if self.participant is not None:
            self.participant.maintain()

    def close(self) -> None:
        if self.participant is not None and self.context.ok():
            self.participant.leave()
        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        if self.participant is not None:
            self.participant.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def _vector(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> Vector3:
    return Vector3(x=float(x), y=float(y), z=float(z))
