"""The slam node over DDS: synthetic scans and odometry in, /map, map → odom and the services out."""
from __future__ import annotations

import math
import re
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import TransformStamped
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import LaserScan
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter
from std_srvs.srv import SetBool, Trigger
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import Marker, MarkerArray

from pppbot_common.maps import OCCUPIED, load_map
from pppbot_common.ros.maps import grid_from_message
from pppbot_common.ros.qos import LATCHED
from pppbot_common.ros.wait import wait_until
from slam_synthetic import ROOM, beam_angles, cast_ranges

pytestmark = pytest.mark.ros


def transform(parent: str, child: str, t: float, x: float, y: float, yaw: float) -> TransformStamped:
    msg = TransformStamped()
    msg.header.frame_id, msg.child_frame_id = parent, child
    msg.header.stamp.sec, msg.header.stamp.nanosec = int(t), int(round((t - int(t)) * 1e9))
    msg.transform.translation.x, msg.transform.translation.y = x, y
    msg.transform.rotation.z, msg.transform.rotation.w = math.sin(yaw / 2), math.cos(yaw / 2)
    return msg


def call(node: Any, service_type: Any, name: str, request: Any) -> Any:
    client = node.create_client(service_type, name)
    wait_until(lambda: client.service_is_ready(), 20, f"service {name}", node=node)
    future = client.call_async(request)
    return wait_until(lambda: future.result(), 20, f"a reply from {name}", node=node)


def test_maps_a_room_from_scans_and_odometry_and_saves_it(ros_node, spawn, tmp_path: Path):
    node = ros_node
    map_file = tmp_path / "room_map"
    slam = spawn([sys.executable, "-m", "pppbot_slam.ros.slam", "--ros-args", "-p", "use_sim_time:=true",
                  "-p", f"map_save_name:={map_file}", "-p", "map_update_interval:=0.5"], name="slam")
    slam.wait_for_output(r"mapping: /scan", 30)
    clock = node.create_publisher(Clock, "/clock", 10)
    tf = node.create_publisher(TFMessage, "/tf", 100)
    tf_static = node.create_publisher(TFMessage, "/tf_static", LATCHED)
    scans = node.create_publisher(LaserScan, "/scan", 10)
    tf_static.publish(TFMessage(transforms=[transform("base_link", "base_footprint", 0, 0, 0, 0),
                                            transform("base_link", "lidar_frame", 0, 0.05, 0, 0)]))
    angles = beam_angles()
    maps: list[OccupancyGridMsg] = []
    node.create_subscription(OccupancyGridMsg, "/map", maps.append, LATCHED)
    # Publish only once the node listens: scans are best effort, and discovery takes a moment.
    wait_until(lambda: scans.get_subscription_count() and tf.get_subscription_count()
               and clock.get_subscription_count(), 20, "the slam node's subscriptions", node=node)
    graphs: list[MarkerArray] = []
    health: list[dict[str, str]] = []
    node.create_subscription(DiagnosticArray, "/diagnostics", lambda m: health.extend(
        {"level": s.level,
         **{v.key: v.value for v in s.values}} for s in m.status if s.name == "slam_toolbox: mapping"), 10)
    node.create_subscription(MarkerArray, "/slam_toolbox/graph_visualization", graphs.append, 10)
    # The robot drives 2 m along x at 0.4 m/s; odometry is exact; a scan every 0.1 s.
    for k in range(60):
        t = 1.0 + 0.1 * k
        x = min(0.04 * k, 2.0) - 1.0
        clock.publish(Clock(clock=transform("", "", t, 0, 0, 0).header.stamp))
        tf.publish(TFMessage(transforms=[transform("odom", "base_link", t, x, 0.0, 0.0)]))
        scan = LaserScan(angle_min=float(angles[0]), angle_increment=float(angles[1] - angles[0]),
                         range_min=0.08, range_max=20.0)
        scan.header.frame_id = "lidar_frame"
        scan.header.stamp = transform("", "", t, 0, 0, 0).header.stamp
        scan.ranges = cast_ranges(ROOM, np.array([x + 0.05, 0.0, 0.0])).astype(np.float32).tolist()
        scans.publish(scan)
        rclpy_spin(node, 0.05)
    wait_until(lambda: maps, 20, "a /map", node=node)
    grid = grid_from_message(maps[-1])
    assert grid.frame_id == "map" and grid.resolution == pytest.approx(0.05)
    # The room's walls are in the map where they are (map frame = where mapping started: odom's origin).
    for x, y, along_x in [(3.0, 0.0, True), (-3.0, 0.3, True), (0.0, 2.0, False), (0.5, -2.0, False)]:
        offsets = np.linspace(-0.075, 0.075, 7)
        xs, ys = (x + offsets, np.full(7, y)) if along_x else (np.full(7, x), y + offsets)
        rows, cols = grid.cell_of(xs, ys)
        assert (grid.data[rows, cols] == OCCUPIED).any(), (x, y)
    # and nothing in the open middle of the room
    rows, cols = grid.cell_of(np.linspace(-0.5, 0.5, 21), np.full(21, -0.5))
    assert not (grid.data[rows, cols] == OCCUPIED).any()
    seen: list[TFMessage] = []
    node.create_subscription(TFMessage, "/tf", lambda m: seen.extend(
        [m] if any(t.header.frame_id == "map" and t.child_frame_id == "odom" for t in m.transforms) else []), 100)
    t = 7.0
    while not seen and t < 30.0:  # the transform timer runs on sim time: keep the clock going
        t += 0.05
        clock.publish(Clock(clock=transform("", "", t, 0, 0, 0).header.stamp))
        rclpy_spin(node, 0.02)
    assert seen, "no map → odom transform"
    offset = seen[-1].transforms[0].transform.translation
    assert abs(offset.x) < 0.03 and abs(offset.y) < 0.03  # exact odometry: nothing to correct
    # The pose graph as markers: a sphere per keyframe (at least 0.5 m apart over 2 m), a
    # line per edge.
    serialized = call(node, Trigger, "/slam_toolbox/serialize_map", Trigger.Request())
    assert serialized.success, serialized.message
    count = re.search(r"\((\d+) keyframes\)", serialized.message)
    assert count, serialized.message
    keyframes = int(count.group(1))
    wait_until(lambda: graphs and len(graphs[-1].markers[0].points) == keyframes, 20, "graph markers", node=node)
    spheres, links, loops = graphs[-1].markers
    assert spheres.type == Marker.SPHERE_LIST and spheres.header.frame_id == "map"
    xs = np.array([p.x for p in spheres.points])
    assert 3 <= keyframes <= 5 and xs[0] < -0.85 and np.all(np.diff(xs) > 0.49)
    assert len(links.points) == 2 * (keyframes - 1) and loops.points == []
    reply = call(node, Trigger, "/slam_toolbox/save_map", Trigger.Request())
    assert reply.success, reply.message
    saved, _ = load_map(map_file.with_suffix(".yaml"))
    assert (saved.data == OCCUPIED).sum() > 100
    assert call(node, SetBool, "/slam_toolbox/pause_new_measurements", SetBool.Request(data=True)).success
    assert call(node, Trigger, "/slam_toolbox/reset", Trigger.Request()).success
    empty = call(node, Trigger, "/slam_toolbox/save_map", Trigger.Request())
    assert not empty.success and "no map yet" in empty.message
    # Load the serialized graph back (the file name is a parameter, set at run time).
    unset = call(node, Trigger, "/slam_toolbox/deserialize_map", Trigger.Request())
    assert not unset.success and "map_file_name" in unset.message
    set_reply = call(node, SetParameters, "/slam_toolbox/set_parameters", SetParameters.Request(
        parameters=[Parameter("map_file_name", value=str(map_file)).to_parameter_msg()]))
    assert set_reply.results[0].successful
    loaded = call(node, Trigger, "/slam_toolbox/deserialize_map", Trigger.Request())
    assert loaded.success, loaded.message
    again = call(node, Trigger, "/slam_toolbox/save_map", Trigger.Request())
    assert again.success, again.message
    reloaded, _ = load_map(map_file.with_suffix(".yaml"))
    np.testing.assert_array_equal(reloaded.data, saved.data)
    # A scan from a frame TF does not know is dropped with a warning naming the frames.
    assert call(node, SetBool, "/slam_toolbox/pause_new_measurements", SetBool.Request(data=False)).success
    t = 40.0
    tf.publish(TFMessage(transforms=[transform("odom", "base_link", t + 0.1, 1.0, 0.0, 0.0)]))
    stray = LaserScan(angle_min=float(angles[0]), angle_increment=float(angles[1] - angles[0]), range_min=0.08,
                      range_max=20.0, ranges=[1.0] * len(angles))
    stray.header.frame_id, stray.header.stamp = "nowhere", transform("", "", t, 0, 0, 0).header.stamp
    rclpy_spin(node, 0.2)
    scans.publish(stray)
    slam.wait_for_output(r"dropping a scan: no transform odom → base_footprint → nowhere", 20)
    wait_until(lambda: health and health[-1]["lost"] == "false", 20, "a healthy /diagnostics", node=node)
    assert health[-1]["level"] == DiagnosticStatus.OK and int(health[-1]["keyframes"]) >= 3
    # Scans that fit nothing (clutter half a metre around the lidar) while odometry goes on:
    # after LOST_KEYFRAMES keyframes the node says it is lost, and leaves them out of the map.
    clutter = np.random.default_rng(0)
    for k in range(8):
        t = 41.0 + 0.5 * k
        # turning on the spot in the room's open middle, 0.6 rad a scan: a keyframe each
        tf.publish(TFMessage(transforms=[transform("odom", "base_link", t - 0.1, 0.0, -0.3, 0.6 * k),
                                         transform("odom", "base_link", t + 0.1, 0.0, -0.3, 0.6 * (k + 1))]))
        clock.publish(Clock(clock=transform("", "", t, 0, 0, 0).header.stamp))
        scan = LaserScan(angle_min=float(angles[0]), angle_increment=float(angles[1] - angles[0]), range_min=0.08,
                         range_max=20.0, ranges=clutter.uniform(0.3, 0.5, len(angles)).astype(np.float32).tolist())
        scan.header.frame_id, scan.header.stamp = "lidar_frame", transform("", "", t, 0, 0, 0).header.stamp
        scans.publish(scan)
        rclpy_spin(node, 0.1)
    slam.wait_for_output(r"lost at keyframe \d+ .*left out of the map", 20)
    wait_until(lambda: health and health[-1]["lost"] == "true", 20, "/diagnostics saying lost", node=node)
    assert health[-1]["level"] == DiagnosticStatus.WARN and int(health[-1]["keyframes_left_out"]) >= 1


def rclpy_spin(node: Any, seconds: float) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.01)
