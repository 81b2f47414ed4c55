"""The ``amcl`` node over DDS: a map, TF and scans of the synthetic room in; pose, cloud and map → odom out."""
from __future__ import annotations

import math
import os
from typing import Any

import numpy as np
import pytest
from amcl_synthetic import BEAMS, LIDAR, RANGE_MAX, drive, grid, ranges
from geometry_msgs.msg import PoseWithCovarianceStamped, TransformStamped
from nav2_msgs.msg import ParticleCloud
from nav2_msgs.srv import SetInitialPose
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from rclpy.time import Time
from sensor_msgs.msg import LaserScan
from std_srvs.srv import Empty
from tf2_msgs.msg import TFMessage

from pppbot_bringup.run import find_executable
from pppbot_common.maps import OccupancyGrid
from pppbot_common.ros.maps import grid_message
from pppbot_common.ros.planar import transform_message
from pppbot_common.ros.qos import LATCHED, SENSOR
from pppbot_common.ros.wait import wait_until
from pppbot_common.se2 import quaternion_from_yaw, se2_compose, yaw_from_quaternion

pytestmark = pytest.mark.ros


class Robot:
    """The test's side: the map, the lidar mounting, odometry on /tf and scans of the synthetic room."""

    def __init__(self, node: Any) -> None:
        self.node = node
        self.map_pub = node.create_publisher(type(grid_message(grid(), Time().to_msg())), "/map", LATCHED)
        self.static_pub = node.create_publisher(TFMessage, "/tf_static", LATCHED)
        self.tf_pub = node.create_publisher(TFMessage, "/tf", 100)
        self.scan_pub = node.create_publisher(LaserScan, "/scan", SENSOR)
        self.pose_pub = node.create_publisher(PoseWithCovarianceStamped, "/initialpose", 10)
        self.poses: list[PoseWithCovarianceStamped] = []
        self.clouds: list[ParticleCloud] = []
        self.map_to_odom: list[TransformStamped] = []
        node.create_subscription(PoseWithCovarianceStamped, "/amcl_pose", self.poses.append, LATCHED)
        node.create_subscription(ParticleCloud, "/particle_cloud", self.clouds.append, SENSOR)
        node.create_subscription(TFMessage, "/tf", lambda m: self.map_to_odom.extend(
            t for t in m.transforms if t.header.frame_id == "map"), 100)
        self.t_s = 100.0
        self.map_pub.publish(grid_message(grid(), Time(seconds=1).to_msg()))
        self.static_pub.publish(TFMessage(transforms=[transform_message("base_footprint", "lidar_frame",
                                                               Time(seconds=1).to_msg(), np.array(LIDAR))]))

    def step(self, truth: np.ndarray, odom: np.ndarray) -> None:
        """One scan at the truth pose, its odometry on /tf just after it, 0.1 s later than the last."""
        self.t_s += 0.1
        stamp = Time(seconds=self.t_s).to_msg()
        after = Time(seconds=self.t_s + 0.01).to_msg()
        scan = LaserScan()
        scan.header.stamp, scan.header.frame_id = stamp, "lidar_frame"
        scan.angle_min, scan.angle_increment = -math.pi, 2 * math.pi / BEAMS
        scan.angle_max = math.pi - scan.angle_increment
        scan.range_min, scan.range_max = 0.12, RANGE_MAX
        scan.ranges = [float(r) for r in ranges(truth)]
        self.tf_pub.publish(TFMessage(transforms=[transform_message("odom", "base_footprint", stamp, odom)]))
        self.scan_pub.publish(scan)
        self.tf_pub.publish(TFMessage(transforms=[transform_message("odom", "base_footprint", after, odom)]))
        for _ in range(5):
            import rclpy
            rclpy.spin_once(self.node, timeout_sec=0.02)

    def initial_pose(self, pose: tuple[float, float, float], frame: str = "map") -> None:
        msg = PoseWithCovarianceStamped()
        msg.header.frame_id = frame
        msg.pose.pose.position.x, msg.pose.pose.position.y = pose[0], pose[1]
        o = msg.pose.pose.orientation
        o.x, o.y, o.z, o.w = quaternion_from_yaw(pose[2])
        cov = np.zeros((6, 6))
        cov[0, 0] = cov[1, 1] = 0.25
        cov[5, 5] = (math.pi / 12) ** 2
        msg.pose.covariance = cov.ravel().tolist()
        self.pose_pub.publish(msg)


def start_amcl(spawn: Any, *params: str, managed: bool = True) -> Any:
    """AMCL, and a lifecycle manager that brings it up (as lifecycle_manager_localization does)."""
    ros_args = [a for p in ("seed:=3", *params) for a in ("-p", p)]
    amcl = spawn([str(find_executable("pppbot_nav", "amcl")), "--ros-args", *ros_args], name="amcl",
                 env={**os.environ})
    if not managed:
        return amcl
    manager = spawn([str(find_executable("pppbot_nav", "lifecycle_manager")), "--ros-args", "-p", "node_names:=[amcl]",
                     "-p", "autostart:=true"], name="lifecycle_manager", env={**os.environ})
    manager.wait_for_output("Managed nodes are active", 60)  # it uses scans only once active
    return amcl


def pose_of(msg: PoseWithCovarianceStamped) -> np.ndarray:
    p, o = msg.pose.pose.position, msg.pose.pose.orientation
    return np.array([p.x, p.y, yaw_from_quaternion(o.x, o.y, o.z, o.w)])


def test_localizes_from_an_initial_pose_and_publishes_pose_cloud_and_map_to_odom(ros_node, spawn):
    amcl = start_amcl(spawn)
    robot = Robot(ros_node)
    path = drive()
    _, truth0, odom0 = path[0]
    amcl.wait_for_output(r"map: \d+ × \d+ cells at 0.05 m", 30)
    wait_until(lambda: robot.pose_pub.get_subscription_count() > 0 or None, 20, "amcl on /initialpose",
               node=ros_node)
    # Scans before any initial pose: Nav2's reminder, and no pose.
    deadline_steps = 0
    while "Please set the initial pose" not in amcl.output and deadline_steps < 100:
        robot.step(truth0, odom0)
        deadline_steps += 1
    assert "Please set the initial pose" in amcl.output and not robot.poses

    robot.initial_pose((truth0[0] + 0.3, truth0[1] - 0.2, truth0[2] + 0.2), frame="odom")  # the wrong frame
    amcl.wait_for_output(r"ignoring an initial pose in frame 'odom'", 20)
    robot.initial_pose((truth0[0] + 0.3, truth0[1] - 0.2, truth0[2] + 0.2))
    amcl.wait_for_output(r"initial pose \(0\.800, -1\.200, 0\.200\)", 20)
    for _, truth, odom in path[:60]:  # 2.5 m along the room's first leg
        robot.step(truth, odom)
    wait_until(lambda: len(robot.poses) >= 5 or None, 20, "amcl poses", node=ros_node)
    truth, odom = path[59][1], path[59][2]
    wait_until(lambda: robot.map_to_odom or None, 20, "map → odom", node=ros_node)
    last = robot.map_to_odom[-1]
    tr = last.transform
    map_to_odom = np.array([tr.translation.x, tr.translation.y,
                            yaw_from_quaternion(tr.rotation.x, tr.rotation.y, tr.rotation.z, tr.rotation.w)])
    estimate = se2_compose(map_to_odom, odom)
    assert np.hypot(*(estimate[:2] - truth[:2])) < 0.05
    assert abs(math.remainder(estimate[2] - truth[2], 2 * math.pi)) < math.radians(1.0)
    assert last.child_frame_id == "odom"
    # Stamped with the scan's time plus transform_tolerance (1 s).
    assert Time.from_msg(last.header.stamp).nanoseconds / 1e9 == pytest.approx(robot.t_s + 1.0, abs=0.15)
    assert robot.poses[-1].header.frame_id == "map"
    assert np.hypot(*(pose_of(robot.poses[-1])[:2] - truth[:2])) < 0.3  # at its last filter update
    assert robot.poses[-1].pose.covariance[0] > 0.0 and robot.poses[-1].pose.covariance[35] > 0.0
    wait_until(lambda: robot.clouds or None, 20, "a particle cloud", node=ros_node)
    assert 500 <= len(robot.clouds[-1].particles) <= 2000
    assert sum(p.weight for p in robot.clouds[-1].particles) == pytest.approx(1.0)

    # A new map that does not hold the robot's pose (the room 100 m away): no pose until one is
    # given, and no map → odom meanwhile (Nav2 would start there from the pose it cannot hold).
    room = grid()
    robot.map_pub.publish(grid_message(OccupancyGrid(room.data, room.resolution, (room.origin[0] + 100.0,
                                                                                   room.origin[1], 0.0)),
                                       Time(seconds=2).to_msg()))
    amcl.wait_for_output(r"no pose on this map, set the initial pose: an initial pose at \(\S+, \S+\) lies "
                         r"outside the map \(x 95\.47 to 104\.5\d m", 20)
    for _, truth, odom in path[60:70]:
        robot.step(truth, odom)
    wait_until(lambda: "Please set the initial pose" in amcl.output.partition("no pose on this map")[2] or None,
               20, "AMCL asking for an initial pose again", node=ros_node)
    seen = len(robot.map_to_odom)
    for _, truth, odom in path[70:75]:
        robot.step(truth, odom)
    assert len(robot.map_to_odom) == seen


def test_services_and_bad_input_keep_the_node_running(ros_node, spawn):
    amcl = start_amcl(spawn, "set_initial_pose:=true", "initial_pose.x:=0.5", "initial_pose.y:=-1.0")
    robot = Robot(ros_node)
    amcl.wait_for_output(r"initial pose \(0\.500, -1\.000, 0\.000\)", 30)
    client = ros_node.create_client(Empty, "/reinitialize_global_localization")
    wait_until(lambda: client.service_is_ready() or None, 20, "the service", node=ros_node)
    future = client.call_async(Empty.Request())
    wait_until(lambda: future.done() or None, 20, "a reply", node=ros_node)
    amcl.wait_for_output(r"global localization: 2000 particles over the free space", 10)
    # Nav2's set_initial_pose service does what /initialpose does.
    setter = ros_node.create_client(SetInitialPose, "/set_initial_pose")
    wait_until(lambda: setter.service_is_ready() or None, 20, "set_initial_pose", node=ros_node)
    request = SetInitialPose.Request()
    request.pose.header.frame_id = "map"
    request.pose.pose.pose.position.x, request.pose.pose.pose.position.y = 0.25, -0.75
    request.pose.pose.pose.orientation.w = 1.0
    request.pose.pose.covariance[0] = request.pose.pose.covariance[7] = 0.25
    request.pose.pose.covariance[35] = 0.07
    future = setter.call_async(request)
    wait_until(lambda: future.done() or None, 20, "a reply", node=ros_node)
    amcl.wait_for_output(r"initial pose \(0\.250, -0\.750, 0\.000\)", 10)
    wait_until(lambda: robot.pose_pub.get_subscription_count() > 0 or None, 20, "amcl on /initialpose",
               node=ros_node)
    robot.initial_pose((math.nan, 0.0, 0.0))
    amcl.wait_for_output(r"ignoring an initial pose: an initial pose must be finite", 20)
    robot.initial_pose((50.0, 0.0, 0.0))  # off the map: named apart from the bad one before it, not taken
    amcl.wait_for_output(r"ignoring an initial pose: an initial pose at \(50, 0\) lies outside the map", 20)
    assert "initial pose (50.000" not in amcl.output
    _, truth, odom = drive()[0]

    def send_an_empty_scan() -> bool | None:
        robot.step(truth, odom)  # odometry at t, then a scan stamped t with no ranges at all
        bad = LaserScan()
        bad.header.frame_id = "lidar_frame"
        bad.header.stamp = Time(seconds=robot.t_s).to_msg()
        bad.range_min, bad.range_max = 0.1, 10.0
        robot.scan_pub.publish(bad)
        return "dropping a scan: a scan with no ranges" in amcl.output or None

    # Scans are best effort, and the first ones may go before amcl's subscriptions have matched the
    # test's publishers: sent until one is answered, as a sensor would go on sending.
    wait_until(send_an_empty_scan, 20, "amcl dropping a scan with no ranges", node=ros_node)
    # Runtime parameter changes are validated like start-up ones.
    setter = ros_node.create_client(SetParameters, "/amcl/set_parameters")
    wait_until(lambda: setter.service_is_ready() or None, 20, "amcl's parameter service", node=ros_node)
    for value, ok in ((ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=1), False),
                      (ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=30), True)):
        future = setter.call_async(SetParameters.Request(parameters=[Parameter(name="max_beams", value=value)]))
        result = wait_until(future.result, 20, "a reply", node=ros_node).results[0]
        assert result.successful is ok
        if not ok:
            assert "max_beams" in result.reason and "at least 2" in result.reason
    assert amcl.running()


def test_request_nomotion_update_updates_on_the_next_scan_without_motion(ros_node, spawn):
    amcl = start_amcl(spawn, "set_initial_pose:=true", "initial_pose.x:=0.5", "initial_pose.y:=-1.0")
    robot = Robot(ros_node)
    amcl.wait_for_output(r"initial pose \(0\.500, -1\.000, 0\.000\)", 30)
    _, truth, odom = drive()[0]
    # The first scan after an initial pose is always used; later ones, standing still, are not.
    def step_and_count() -> int:
        robot.step(truth, odom)
        return len(robot.poses)

    wait_until(lambda: step_and_count() or None, 20, "the first pose", node=ros_node)
    for _ in range(10):
        robot.step(truth, odom)
    before = len(robot.poses)
    assert before >= 1
    client = ros_node.create_client(Empty, "/request_nomotion_update")
    wait_until(lambda: client.service_is_ready() or None, 20, "the service", node=ros_node)
    future = client.call_async(Empty.Request())
    wait_until(lambda: future.done() or None, 20, "a reply", node=ros_node)
    wait_until(lambda: step_and_count() > before or None, 20, "a pose after the no-motion update", node=ros_node)
    for _ in range(10):
        robot.step(truth, odom)
    assert len(robot.poses) == before + 1  # one update per request


@pytest.mark.parametrize("param, message", [
    ("laser_model_type:=sonar", "parameter 'laser_model_type' = 'sonar': must be one of likelihood_field, beam"),
    ("min_particles:=3000", "parameter 'min_particles' = 3000: min_particles (3000) and max_particles (2000)"),
    ("sigma_hit:=0.0", "parameter 'sigma_hit' = 0.0"),
])
def test_a_bad_parameter_stops_the_node_naming_it(spawn, param, message):
    amcl = start_amcl(spawn, param, managed=False)  # a bad parameter stops it before anything is managed
    assert amcl.wait(30) == 1
    assert message in amcl.output
