"""The slam node over DDS: synthetic scans and odometry in, /map, map → odom and the services out.

One slam node maps a synthetic room (the module's shared fixture, ``room``); each test then
checks one behaviour of it, in the order the file gives (the later ones change its state:
reset, reload, unknown frames, getting lost)."""
from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
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
from slam_synthetic import ROOM, beam_angles, cast_ranges
from slam_toolbox.srv import DeserializePoseGraph, Pause, Reset, SaveMap, SerializePoseGraph
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import Marker, MarkerArray

from pppbot_common.maps import OCCUPIED, load_map
from pppbot_common.process import ChildProcess
from pppbot_common.ros.maps import grid_from_message
from pppbot_common.ros.qos import LATCHED
from pppbot_common.ros.wait import wait_until
from pppbot_slam.serialization import load_posegraph

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
    wait_until(client.service_is_ready, 20, f"service {name}", node=node)
    future = client.call_async(request)
    return wait_until(future.result, 20, f"a reply from {name}", node=node)


@dataclass
class Room:
    """The slam node after a 2 m drive through the synthetic room, and what it has published."""

    node: Any
    slam: ChildProcess
    map_file: Path
    clock: Any
    tf: Any
    scans: Any
    angles: np.ndarray
    maps: list[OccupancyGridMsg] = field(default_factory=list)
    graphs: list[MarkerArray] = field(default_factory=list)
    health: list[dict[str, str]] = field(default_factory=list)

    def scan(self, t: float, ranges: Any, frame: str = "lidar_frame") -> LaserScan:
        msg = LaserScan(angle_min=float(self.angles[0]), angle_increment=float(self.angles[1] - self.angles[0]),
                        range_min=0.08, range_max=20.0)
        msg.header.frame_id, msg.header.stamp = frame, transform("", "", t, 0, 0, 0).header.stamp
        msg.ranges = [float(r) for r in ranges]
        return msg

    def tick(self, t: float) -> None:
        self.clock.publish(Clock(clock=transform("", "", t, 0, 0, 0).header.stamp))


@pytest.fixture(scope="module")
def room(module_spawn: Callable[..., ChildProcess], tmp_path_factory: pytest.TempPathFactory) -> Iterator[Room]:
    map_file = tmp_path_factory.mktemp("slam_node") / "room_map"
    rclpy.init()
    node = rclpy.create_node("pytest_slam_node")
    try:
        slam = module_spawn([sys.executable, "-m", "pppbot_slam.ros.slam", "--ros-args", "-p", "use_sim_time:=true",
                             "-p", f"map_save_name:={map_file}", "-p", "map_update_interval:=0.5"], name="slam")
        slam.wait_for_output(r"mapping: /scan", 30)
        room = Room(node, slam, map_file, node.create_publisher(Clock, "/clock", 10),
                    node.create_publisher(TFMessage, "/tf", 100), node.create_publisher(LaserScan, "/scan", 10),
                    beam_angles())
        tf_static = node.create_publisher(TFMessage, "/tf_static", LATCHED)
        tf_static.publish(TFMessage(transforms=[transform("base_link", "base_footprint", 0, 0, 0, 0),
                                                transform("base_link", "lidar_frame", 0, 0.05, 0, 0)]))
        node.create_subscription(OccupancyGridMsg, "/map", room.maps.append, LATCHED)
        # Publish only once the node listens: scans are best effort, and discovery takes a moment.
        wait_until(lambda: room.scans.get_subscription_count() and room.tf.get_subscription_count()
                   and room.clock.get_subscription_count(), 20, "the slam node's subscriptions", node=node)
        def on_diagnostics(msg: DiagnosticArray) -> None:
            room.health.extend({"level": s.level, **{v.key: v.value for v in s.values}}
                               for s in msg.status if s.name == "slam_toolbox: mapping")

        node.create_subscription(DiagnosticArray, "/diagnostics", on_diagnostics, 10)
        node.create_subscription(MarkerArray, "/slam_toolbox/graph_visualization", room.graphs.append, 10)
        # The robot drives 2 m along x at 0.4 m/s; odometry is exact; a scan every 0.1 s.
        for k in range(60):
            t = 1.0 + 0.1 * k
            x = min(0.04 * k, 2.0) - 1.0
            room.tick(t)
            room.tf.publish(TFMessage(transforms=[transform("odom", "base_link", t, x, 0.0, 0.0)]))
            room.scans.publish(room.scan(t, cast_ranges(ROOM, np.array([x + 0.05, 0.0, 0.0])).astype(np.float32)))
            rclpy_spin(node, 0.05)
        wait_until(lambda: room.maps, 20, "a /map", node=node)
        yield room
    finally:
        node.destroy_node()
        rclpy.shutdown()


def test_the_map_has_the_room_walls_where_they_are_and_an_open_middle(room: Room):
    grid = grid_from_message(room.maps[-1])
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


def test_map_to_odom_is_published_and_corrects_nothing_with_exact_odometry(room: Room):
    seen: list[TFMessage] = []
    room.node.create_subscription(TFMessage, "/tf", lambda m: seen.extend(
        [m] if any(t.header.frame_id == "map" and t.child_frame_id == "odom" for t in m.transforms) else []), 100)
    t = 7.0
    while not seen and t < 30.0:  # the transform timer runs on sim time: keep the clock going
        t += 0.05
        room.tick(t)
        rclpy_spin(room.node, 0.02)
    assert seen, "no map → odom transform"
    offset = seen[-1].transforms[0].transform.translation
    assert abs(offset.x) < 0.03 and abs(offset.y) < 0.03  # exact odometry: nothing to correct


def test_the_pose_graph_is_shown_as_a_sphere_per_keyframe_and_a_line_per_edge(room: Room):
    serialized = call(room.node, SerializePoseGraph, "/slam_toolbox/serialize_map",
                      SerializePoseGraph.Request(filename=str(room.map_file)))
    assert serialized.result == SerializePoseGraph.Response.RESULT_SUCCESS
    keyframes = len(load_posegraph(room.map_file).keyframes)
    wait_until(lambda: room.graphs and len(room.graphs[-1].markers[0].points) == keyframes, 20, "graph markers",
               node=room.node)
    spheres, links, loops = room.graphs[-1].markers
    assert spheres.type == Marker.SPHERE_LIST and spheres.header.frame_id == "map"
    xs = np.array([p.x for p in spheres.points])
    # keyframes at least 0.5 m apart over the 2 m drive (from -1 m; on a busy machine the first
    # scans can come before the node has the static transforms, and are dropped)
    assert 3 <= keyframes <= 5 and xs[0] < -0.5 and np.all(np.diff(xs) > 0.49)
    assert len(links.points) == 2 * (keyframes - 1) and loops.points == []


def save_map(room: Room, name: Path) -> int:
    reply = call(room.node, SaveMap, "/slam_toolbox/save_map", SaveMap.Request(name=String(data=str(name))))
    return int(reply.result)


def keyframe_count(room: Room, name: Path) -> int:
    reply = call(room.node, SerializePoseGraph, "/slam_toolbox/serialize_map",
                 SerializePoseGraph.Request(filename=str(name)))
    assert reply.result == SerializePoseGraph.Response.RESULT_SUCCESS
    return len(load_posegraph(name).keyframes)


def deserialize(room: Room, name: Path, match_type: int, x: float = 0.0, y: float = 0.0, theta: float = 0.0) -> None:
    request = DeserializePoseGraph.Request(filename=str(name), match_type=match_type)
    request.initial_pose.x, request.initial_pose.y, request.initial_pose.theta = x, y, theta
    call(room.node, DeserializePoseGraph, "/slam_toolbox/deserialize_map", request)  # Jazzy's reply is empty


def test_save_map_writes_the_yaml_and_pgm_the_request_names(room: Room, tmp_path: Path):
    assert save_map(room, tmp_path / "named") == SaveMap.Response.RESULT_SUCCESS
    saved, _ = load_map(tmp_path / "named.yaml")
    assert (tmp_path / "named.pgm").is_file() and (saved.data == OCCUPIED).sum() > 100


def test_save_reset_and_reload_the_serialized_graph_give_the_same_map(room: Room, tmp_path: Path):
    graph = tmp_path / "graph"
    keyframes = keyframe_count(room, graph)
    assert (tmp_path / "graph.posegraph").is_file() and keyframes >= 3
    assert save_map(room, tmp_path / "before") == SaveMap.Response.RESULT_SUCCESS
    saved, _ = load_map(tmp_path / "before.yaml")
    reset = call(room.node, Reset, "/slam_toolbox/reset", Reset.Request(pause_new_measurements=True))
    assert reset.result == Reset.Response.RESULT_SUCCESS
    assert save_map(room, tmp_path / "empty") == SaveMap.Response.RESULT_NO_MAP_RECEIEVD
    # UNSET is refused (the log says so) and the node keeps what it had: nothing
    deserialize(room, graph, DeserializePoseGraph.Request.UNSET)
    room.slam.wait_for_output(r"deserialize_map: not loaded.*UNSET", 20)
    assert save_map(room, tmp_path / "still_empty") == SaveMap.Response.RESULT_NO_MAP_RECEIEVD
    deserialize(room, graph, DeserializePoseGraph.Request.START_AT_FIRST_NODE)
    room.slam.wait_for_output(r"mapping on from .*graph.posegraph: \d+ keyframes, starting at \(", 20)
    assert save_map(room, tmp_path / "after") == SaveMap.Response.RESULT_SUCCESS
    reloaded, _ = load_map(tmp_path / "after.yaml")
    np.testing.assert_array_equal(reloaded.data, saved.data)
    # Paused by the reset: scans that would make keyframes are ignored ...
    drive(room, 20.0, [0.0, 0.5, 1.0])
    assert keyframe_count(room, tmp_path / "paused") == keyframes
    # ... and Pause toggles it back: the map goes on from the loaded graph.
    assert call(room.node, Pause, "/slam_toolbox/pause_new_measurements", Pause.Request()).status
    room.slam.wait_for_output(r"pause_new_measurements: taking new scans", 20)
    drive(room, 25.0, [1.0, 1.0, 1.0, 1.0])
    wait_until(lambda: keyframe_count(room, tmp_path / "continued") > keyframes, 20, "a keyframe after the load",
               node=room.node)


def test_deserialize_at_a_given_pose_starts_the_new_session_there(room: Room, tmp_path: Path):
    graph = tmp_path / "graph"
    keyframe_count(room, graph)
    deserialize(room, graph, DeserializePoseGraph.Request.START_AT_GIVEN_POSE, 0.5, -0.25, 0.1)
    room.slam.wait_for_output(r"mapping on from .*graph.posegraph: \d+ keyframes, starting at \(0\.50, -0\.25, "
                              r"0\.100\)", 20)
    deserialize(room, graph, DeserializePoseGraph.Request.LOCALIZE_AT_POSE)
    room.slam.wait_for_output(r"deserialize_map: not loaded.*LOCALIZE_AT_POSE", 20)


def test_the_interactive_mode_services_answer_and_say_there_is_none(room: Room):
    from slam_toolbox.srv import Clear, LoopClosure, ToggleInteractive

    for srv_type, name in ((Clear, "clear_changes"), (LoopClosure, "manual_loop_closure"),
                           (ToggleInteractive, "toggle_interactive_mode")):
        assert call(room.node, srv_type, f"/slam_toolbox/{name}", srv_type.Request()) is not None
    room.slam.wait_for_output(r"interactive mode is not implemented", 20)


def drive(room: Room, t0: float, xs: list[float]) -> None:
    """Scans of the room from x (m, odometry), one every 0.2 s of sim time from ``t0``."""
    for k, x in enumerate(xs):
        t = t0 + 0.2 * k
        room.tick(t)
        room.tf.publish(TFMessage(transforms=[transform("odom", "base_link", t, x, 0.0, 0.0)]))
        room.scans.publish(room.scan(t, cast_ranges(ROOM, np.array([x + 0.05, 0.0, 0.0])).astype(np.float32)))
        rclpy_spin(room.node, 0.1)


def test_a_scan_from_an_unknown_frame_is_dropped_with_a_warning_and_health_stays_ok(room: Room):
    t = 40.0
    room.tf.publish(TFMessage(transforms=[transform("odom", "base_link", t + 0.1, 1.0, 0.0, 0.0)]))
    rclpy_spin(room.node, 0.2)
    room.scans.publish(room.scan(t, [1.0] * len(room.angles), frame="nowhere"))
    room.slam.wait_for_output(r"dropping a scan: no transform odom → base_footprint → nowhere", 20)
    health = room.health
    wait_until(lambda: health and health[-1]["lost"] == "false", 20, "a healthy /diagnostics", node=room.node)
    assert health[-1]["level"] == DiagnosticStatus.OK and int(health[-1]["keyframes"]) >= 3
    assert int(health[-1]["map_rebuilds"]) >= 1 and health[-1]["map_stale_keyframes"] == "0"


def test_scans_that_fit_nothing_make_it_say_lost_and_leave_them_out_of_the_map(room: Room):
    # Clutter half a metre around the lidar while odometry goes on: after LOST_KEYFRAMES
    # keyframes the node says it is lost, and leaves them out of the map.
    clutter = np.random.default_rng(0)
    for k in range(8):
        t = 41.0 + 0.5 * k
        # turning on the spot in the room's open middle, 0.6 rad a scan: a keyframe each
        room.tf.publish(TFMessage(transforms=[transform("odom", "base_link", t - 0.1, 0.0, -0.3, 0.6 * k),
                                              transform("odom", "base_link", t + 0.1, 0.0, -0.3, 0.6 * (k + 1))]))
        room.tick(t)
        room.scans.publish(room.scan(t, clutter.uniform(0.3, 0.5, len(room.angles)).astype(np.float32)))
        rclpy_spin(room.node, 0.1)
    room.slam.wait_for_output(r"lost at keyframe \d+ .*left out of the map", 20)
    health = room.health
    wait_until(lambda: health and health[-1]["lost"] == "true", 20, "/diagnostics saying lost", node=room.node)
    assert health[-1]["level"] == DiagnosticStatus.WARN and int(health[-1]["keyframes_left_out"]) >= 1


def rclpy_spin(node: Any, seconds: float) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.01)
