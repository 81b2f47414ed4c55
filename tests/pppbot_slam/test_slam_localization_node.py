"""The slam node in ``mode: localization`` over DDS: a saved pose graph, synthetic scans and odometry in,
``/map``, ``/pose``, ``map → odom`` and slam_toolbox's localization services out.

The box room is mapped in-process and serialized (the module's ``graph``); one node localizes in it
(``robot``), started at a ``map_start_pose`` a few cm off the truth. The odometry frame sits at
:data:`MAP_TO_ODOM` in the map until the robot is carried elsewhere; the tests run in the file's
order (the later ones carry the robot)."""
from __future__ import annotations

import math
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import rclpy
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseWithCovarianceStamped, TransformStamped
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import LaserScan
from slam_synthetic import ROOM, beam_angles, cast_ranges, scan_rays
from slam_toolbox.srv import DeserializePoseGraph, SerializePoseGraph
from std_srvs.srv import Empty
from tf2_msgs.msg import TFMessage

from pppbot_common.maps import OCCUPIED
from pppbot_common.process import ChildProcess
from pppbot_common.ros.maps import grid_from_message
from pppbot_common.ros.qos import LATCHED
from pppbot_common.ros.wait import wait_until
from pppbot_common.se2 import quaternion_from_yaw, se2_compose, se2_inverse, wrap_angles, yaw_from_quaternion
from pppbot_slam.mapper import Mapper
from pppbot_slam.serialization import save_posegraph

pytestmark = pytest.mark.ros

#: Where the odometry frame is in the map (the truth the node must find), and the lidar on the base.
MAP_TO_ODOM = np.array([0.3, -0.2, 0.1])
LIDAR = np.array([0.05, 0.0, 0.0])
#: Within this of the truth (m, rad).
POSITION_TOLERANCE_M = 0.03
YAW_TOLERANCE_RAD = math.radians(1.0)


def stamp(t: float) -> Time:
    return Time(sec=int(t), nanosec=int(round((t - int(t)) * 1e9)))


def transform(parent: str, child: str, t: float, pose: np.ndarray) -> TransformStamped:
    msg = TransformStamped()
    msg.header.frame_id, msg.child_frame_id, msg.header.stamp = parent, child, stamp(t)
    msg.transform.translation.x, msg.transform.translation.y = float(pose[0]), float(pose[1])
    o = msg.transform.rotation
    o.x, o.y, o.z, o.w = quaternion_from_yaw(float(pose[2]))
    return msg


def call(node: Any, service_type: Any, name: str, request: Any) -> Any:
    client = node.create_client(service_type, name)
    wait_until(client.service_is_ready, 20, f"service {name}", node=node)
    future = client.call_async(request)
    return wait_until(future.result, 20, f"a reply from {name}", node=node)


def pose_of(msg: PoseWithCovarianceStamped) -> np.ndarray:
    p, o = msg.pose.pose.position, msg.pose.pose.orientation
    return np.array([p.x, p.y, yaw_from_quaternion(o.x, o.y, o.z, o.w)])


def assert_near(pose: np.ndarray, truth: np.ndarray) -> None:
    assert float(np.hypot(*(pose[:2] - truth[:2]))) < POSITION_TOLERANCE_M, (pose, truth)
    assert abs(float(wrap_angles(pose[2] - truth[2]))) < YAW_TOLERANCE_RAD, (pose, truth)


@dataclass
class Robot:
    """The localizing node and the test's side: the simulated robot and what the node published."""

    node: Any
    slam: ChildProcess
    graph: Path
    clock: Any
    tf: Any
    scans: Any
    initial_pose: Any
    map_to_odom: np.ndarray = field(default_factory=MAP_TO_ODOM.copy)  # the truth
    odom: np.ndarray = field(default_factory=lambda: np.zeros(3))
    t: float = 1.0
    maps: list[OccupancyGridMsg] = field(default_factory=list)
    poses: list[PoseWithCovarianceStamped] = field(default_factory=list)
    transforms: list[TransformStamped] = field(default_factory=list)

    def truth(self) -> np.ndarray:
        return np.asarray(se2_compose(self.map_to_odom, self.odom))

    def tick(self, dt: float = 0.05) -> None:
        self.t += dt
        self.clock.publish(Clock(clock=stamp(self.t)))

    def scan_at(self, odom: np.ndarray) -> PoseWithCovarianceStamped:
        """Move to ``odom`` (odometry is exact), scan, and wait for the pose the node localized."""
        self.odom = np.asarray(odom, dtype=float)
        self.tick(0.25)
        t = self.t
        angles = beam_angles()
        msg = LaserScan(angle_min=float(angles[0]), angle_increment=float(angles[1] - angles[0]),
                        range_min=0.08, range_max=20.0)
        msg.header.frame_id, msg.header.stamp = "lidar_frame", stamp(t)
        msg.ranges = [float(r) for r in cast_ranges(ROOM, se2_compose(self.truth(), LIDAR)).astype(np.float32)]
        self.scans.publish(msg)

        tries = 0

        def localized() -> PoseWithCovarianceStamped | None:
            # The node holds the scan until odometry reaches its stamp, checking on each /tf: odometry
            # is sent again while waiting (the static transforms may reach the node after the first).
            # The scan is sent again every 20 tries unanswered: scans are best effort, and the node's
            # reader may not know this writer yet when the first one goes out (on a loaded machine).
            nonlocal tries
            tries += 1
            if tries % 20 == 0:
                self.scans.publish(msg)
            self.tf.publish(odom)
            return next((p for p in self.poses if p.header.stamp == stamp(t)), None)

        odom = TFMessage(transforms=[transform("odom", "base_link", t, self.odom)])
        return wait_until(localized, 20, f"the pose of the scan at t = {t:.2f} s", node=self.node)

    def carry(self, to_map_pose: np.ndarray) -> None:
        """Carry the robot to ``to_map_pose`` without odometry noticing (kidnapping)."""
        self.map_to_odom = np.asarray(se2_compose(to_map_pose, se2_inverse(self.odom)))


@pytest.fixture(scope="module")
def graph(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The box room mapped along its middle (x from −1 to 1 m), serialized."""
    mapper = Mapper(sensor_offset=LIDAR.copy())
    for k, x in enumerate(np.linspace(-1.0, 1.0, 41)):
        base = np.array([x, 0.0, 0.0])
        mapper.process(0.1 * k, base, scan_rays(ROOM, np.asarray(se2_compose(base, LIDAR)), seed=k))
    return save_posegraph(mapper, tmp_path_factory.mktemp("localization_node") / "room")


@pytest.fixture(scope="module")
def robot(module_spawn: Callable[..., ChildProcess], graph: Path) -> Iterator[Robot]:
    rclpy.init()
    node = rclpy.create_node("pytest_slam_localization")
    try:
        start = MAP_TO_ODOM + [0.04, -0.03, 0.02]  # the robot starts at odom's origin; the pose given is off
        slam = module_spawn([sys.executable, "-m", "pppbot_slam.ros.slam", "--ros-args", "-p", "use_sim_time:=true",
                             "-p", "mode:=localization", "-p", f"map_file_name:={graph.with_suffix('')}",
                             "-p", f"map_start_pose:=[{start[0]}, {start[1]}, {start[2]}]",
                             "-p", "minimum_travel_distance:=0.2", "-p", "map_update_interval:=0.5"],
                            name="slam")
        slam.wait_for_output(r"localization: /scan", 30)
        robot = Robot(node, slam, graph, node.create_publisher(Clock, "/clock", 10),
                      node.create_publisher(TFMessage, "/tf", 100), node.create_publisher(LaserScan, "/scan", 10),
                      node.create_publisher(PoseWithCovarianceStamped, "/initialpose", 10))
        node.create_publisher(TFMessage, "/tf_static", LATCHED).publish(TFMessage(transforms=[
            transform("base_link", "base_footprint", 0, np.zeros(3)), transform("base_link", "lidar_frame", 0, LIDAR)]))
        node.create_subscription(OccupancyGridMsg, "/map", robot.maps.append, LATCHED)
        node.create_subscription(PoseWithCovarianceStamped, "/pose", robot.poses.append, 10)
        # Publish only once the node listens: scans are best effort, and discovery takes a moment.
        wait_until(lambda: robot.scans.get_subscription_count() and robot.tf.get_subscription_count()
                   and robot.clock.get_subscription_count() and robot.initial_pose.get_subscription_count(), 20,
                   "the slam node's subscriptions", node=node)
        # (after the wait: the count of /tf's subscribers must be the node's)
        def on_tf(msg: TFMessage) -> None:
            robot.transforms.extend(t for t in msg.transforms
                                    if (t.header.frame_id, t.child_frame_id) == ("map", "odom"))

        node.create_subscription(TFMessage, "/tf", on_tf, 100)
        yield robot
    finally:
        node.destroy_node()
        rclpy.shutdown()


def test_the_loaded_graph_is_published_as_the_map(robot: Robot):
    wait_until(lambda: robot.maps, 20, "a /map", node=robot.node)
    grid = grid_from_message(robot.maps[-1])
    assert grid.frame_id == "map" and grid.resolution == pytest.approx(0.05)
    offsets = np.linspace(-0.075, 0.075, 7)
    for x, y, along_x in [(3.0, 0.0, True), (-3.0, 0.3, True), (0.0, 2.0, False), (0.5, -2.0, False)]:  # walls
        xs, ys = (x + offsets, np.full(7, y)) if along_x else (np.full(7, x), y + offsets)
        rows, cols = grid.cell_of(xs, ys)
        assert (grid.data[rows, cols] == OCCUPIED).any(), (x, y)


def test_each_scan_is_localized_on_pose_with_the_matchs_covariance(robot: Robot):
    for x in np.arange(0.0, 1.01, 0.25):
        msg = robot.scan_at(np.array([x, 0.05 * x, 0.1 * x]))
        assert msg.header.frame_id == "map"
        assert_near(pose_of(msg), robot.truth())
        covariance = np.asarray(msg.pose.covariance).reshape(6, 6)
        assert covariance[0, 0] > 0 and covariance[1, 1] > 0 and covariance[5, 5] > 0
        assert covariance[2, 2] == covariance[3, 3] == covariance[4, 4] == 0.0


def test_map_to_odom_is_where_the_odometry_frame_is_in_the_map(robot: Robot):
    after = robot.poses[-1].header.stamp

    def newest() -> TransformStamped | None:
        robot.tick()  # the transform timer runs on sim time: keep the clock going
        fresh = [t for t in robot.transforms if (t.header.stamp.sec, t.header.stamp.nanosec) > (after.sec,
                                                                                                  after.nanosec)]
        return fresh[-1] if fresh else None

    msg = wait_until(newest, 20, "a map → odom transform after the last scan", node=robot.node)
    q = msg.transform.rotation
    found = np.array([msg.transform.translation.x, msg.transform.translation.y,
                      yaw_from_quaternion(q.x, q.y, q.z, q.w)])
    assert_near(found, robot.map_to_odom)


def test_deserialize_map_localizes_at_the_given_pose_only(robot: Robot):
    request = DeserializePoseGraph.Request(filename=str(robot.graph.with_suffix("")),
                                           match_type=DeserializePoseGraph.Request.START_AT_FIRST_NODE)
    call(robot.node, DeserializePoseGraph, "/slam_toolbox/deserialize_map", request)  # Jazzy's reply is empty
    robot.slam.wait_for_output(r"deserialize_map: not loaded.*START_AT_FIRST_NODE.*takes LOCALIZE_AT_POSE", 20)
    robot.carry(np.array([-0.8, 0.3, -0.4]))
    request.match_type = DeserializePoseGraph.Request.LOCALIZE_AT_POSE
    request.initial_pose.x, request.initial_pose.y, request.initial_pose.theta = -0.75, 0.25, -0.35
    call(robot.node, DeserializePoseGraph, "/slam_toolbox/deserialize_map", request)
    robot.slam.wait_for_output(r"localizing in .*room\.posegraph: \d+ keyframes, starting at "
                               r"\(-0\.75, 0\.25, -0\.350\)", 20)
    assert_near(pose_of(robot.scan_at(robot.odom)), robot.truth())  # the first scan: taken where it stands
    assert_near(pose_of(robot.scan_at(robot.odom + [0.25, 0.0, 0.0])), robot.truth())


def test_initialpose_relocalizes_where_rviz_says(robot: Robot):
    robot.carry(np.array([1.2, -0.6, 0.5]))
    given = PoseWithCovarianceStamped()
    given.header.frame_id = "map"
    given.pose.pose.position.x, given.pose.pose.position.y = 1.15, -0.55
    o = given.pose.pose.orientation
    o.x, o.y, o.z, o.w = quaternion_from_yaw(0.45)
    robot.initial_pose.publish(given)
    robot.slam.wait_for_output(r"initialpose: localizing at \(1\.15, -0\.55, 0\.450\)", 20)
    assert_near(pose_of(robot.scan_at(robot.odom)), robot.truth())


def test_serialize_is_refused_save_map_is_not_served_and_the_buffer_can_be_cleared(robot: Robot):
    reply = call(robot.node, SerializePoseGraph, "/slam_toolbox/serialize_map",
                 SerializePoseGraph.Request(filename=str(robot.graph.parent / "never")))
    assert reply.result == SerializePoseGraph.Response.RESULT_FAILED_TO_WRITE_FILE
    assert not (robot.graph.parent / "never.posegraph").exists()
    call(robot.node, Empty, "/slam_toolbox/clear_localization_buffer", Empty.Request())
    robot.slam.wait_for_output(r"clear_localization_buffer: the rolling buffer is cleared", 20)
    services = dict(robot.node.get_service_names_and_types())
    assert services["/slam_toolbox/deserialize_map"] == ["slam_toolbox/srv/DeserializePoseGraph"]
    assert "/slam_toolbox/save_map" not in services  # slam_toolbox's localization node has no map saver


def test_the_mode_cannot_change_while_the_node_runs(robot: Robot):
    value = ParameterValue(type=ParameterType.PARAMETER_STRING, string_value="mapping")
    reply = call(robot.node, SetParameters, "/slam_toolbox/set_parameters",
                 SetParameters.Request(parameters=[Parameter(name="mode", value=value)]))
    assert not reply.results[0].successful and "'mode' cannot change" in reply.results[0].reason


def test_a_mode_other_than_mapping_or_localization_stops_the_node_naming_it(spawn: Callable[..., ChildProcess]):
    slam = spawn([sys.executable, "-m", "pppbot_slam.ros.slam", "--ros-args", "-p", "mode:=lifelong"], name="slam")
    assert slam.wait(30) == 1
    slam.wait_for_output(r"parameter 'mode' = 'lifelong': must be 'mapping' or 'localization'", 5)
