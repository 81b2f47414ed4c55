"""A real robot's CARMEN log as a bag (``pppbot bag from-carmen``), read back by an independent
reader, and the ``slam`` node mapping it from ``pppbot bag play`` as the core maps the same scans."""
from __future__ import annotations

import gzip
import math
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.highlevel import AnyReader

from pppbot_bag.carmen import CarmenLog, read_carmen, synthesize_odometry
from pppbot_common.se2 import se2_compose, se2_relative, yaw_from_quaternion

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "pppbot_slam"))
from slam_synthetic import RING, cast_ranges, ring_path  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
PPPBOT = str(ROOT / "pppbot")
#: A SICK-like front laser: 181 beams from −90° to +90°, as the CARMEN logs' (1°).
ANGLES = np.radians(np.arange(-90, 91))


def pppbot(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([PPPBOT, *args], capture_output=True, text=True, timeout=120)


def synthetic_log(path: Path, scans: int = 120) -> Path:
    """The ring corridor driven once and a bit, a scan every 0.3 m, written as a corrected CARMEN
    log (the true pose in the pose and odometry fields), a scan every 0.5 s."""
    truth = ring_path(step_m=0.3)[:scans]
    lines = ["PARAM robot_frontlaser_offset 0.0 nohost 0"]
    for k, (x, y, yaw) in enumerate(truth):
        ranges = cast_ranges(RING, np.array([x, y, yaw]), noise=0.005, seed=k, angles=ANGLES)
        values = " ".join(f"{(r if math.isfinite(r) else 81.9):.3f}" for r in ranges)
        stamp = 100.0 + 0.5 * k
        lines.append(f"FLASER {len(ranges)} {values} {x:.6f} {y:.6f} {yaw:.6f} {x:.6f} {y:.6f} {yaw:.6f} "
                     f"{stamp:.3f} host {stamp:.3f}")
    with gzip.open(path, "wt") as f:
        f.write("\n".join(lines) + "\n")
    return path


def test_the_bag_holds_the_logs_scans_odometry_and_frames(tmp_path: Path) -> None:
    log_path = synthetic_log(tmp_path / "ring.log.gz", scans=40)
    bag = tmp_path / "ring_bag"
    result = pppbot("bag", "from-carmen", str(log_path), "-o", str(bag), "--seed", "3")
    assert result.returncode == 0, result.stderr
    assert "40 scans of ring over 20 s, 121 messages" in result.stdout
    log = read_carmen(log_path)
    odometry = synthesize_odometry(log.poses, (0.05, 0.05, 0.05, 0.05), np.random.default_rng(3))
    with AnyReader([bag]) as reader:
        messages: list[tuple[str, int, Any]] = [(c.topic, t, reader.deserialize(raw, c.msgtype))
                                                for c, t, raw in reader.messages()]
    scans = [m for topic, _, m in messages if topic == "/scan"]
    odoms = [m for topic, _, m in messages if topic == "/odom"]
    (static,) = [m for topic, _, m in messages if topic == "/tf_static"]
    assert len(scans) == len(odoms) == 40
    first = scans[0]
    assert first.header.frame_id == "laser_frame" and len(first.ranges) == 181
    assert (first.angle_min, first.angle_max) == pytest.approx((-math.pi / 2, math.pi / 2))
    # ranges as the log wrote them (to the millimetre); 81.9 m, the laser's "no return", is inf
    np.testing.assert_allclose(np.where(np.isfinite(log.ranges_m[5]), log.ranges_m[5], -1.0),
                               np.where(np.isfinite(scans[5].ranges), scans[5].ranges, -1.0), atol=1e-3)
    assert scans[5].header.stamp.sec == 102 and scans[5].header.stamp.nanosec == 500_000_000  # the log's clock
    o = odoms[17].pose.pose
    np.testing.assert_allclose([o.position.x, o.position.y, yaw_from_quaternion(o.orientation.x, o.orientation.y,
                                                                                o.orientation.z, o.orientation.w)],
                               odometry[17], atol=1e-9)
    assert (odoms[0].header.frame_id, odoms[0].child_frame_id) == ("odom", "base_footprint")
    assert (static.transforms[0].header.frame_id, static.transforms[0].child_frame_id) == ("base_footprint",
                                                                                          "laser_frame")
    again = pppbot("bag", "from-carmen", str(log_path), "-o", str(bag))
    assert again.returncode == 1 and "exists already" in again.stderr  # never overwritten


def test_bad_logs_and_values_are_refused(tmp_path: Path) -> None:
    bad = tmp_path / "bad.log"
    bad.write_text("FLASER 3 1.0 2.0\n")
    for args, message in ((["from-carmen", str(bad)], "bad.log:1: malformed FLASER record"),
                          (["from-carmen", str(tmp_path / "none.log")], "none.log: no such log"),
                          (["from-carmen", str(bad), "--alphas", "0", "0", "-1", "0"], "--alphas must be four")):
        result = pppbot("bag", *args)
        assert result.returncode == 1 and message in result.stderr, result.stderr


@pytest.mark.ros
def test_the_slam_node_maps_the_bag_as_the_core_maps_the_log(ros_node, spawn, tmp_path: Path,
                                                              load_benchmark) -> None:
    """slam_toolbox users map a bag: ``bag play --clock`` into the node. Its pose graph at the end
    (serialize_map) must be the core's for the same scans and odometry, keyframe for keyframe (the
    scans it got: on a loaded machine one can miss a best-effort subscription, the last one must not)."""
    from slam_toolbox.srv import SerializePoseGraph

    from pppbot_common.ros.wait import wait_until
    from pppbot_slam.serialization import load_posegraph

    carmen = load_benchmark("carmen_slam")
    params_file = ROOT / "benchmarks" / "carmen_slam_params.yaml"
    log_path = synthetic_log(tmp_path / "ring.log.gz", scans=106)
    bag = tmp_path / "ring_bag"
    assert pppbot("bag", "from-carmen", str(log_path), "-o", str(bag)).returncode == 0
    graph = tmp_path / "node_map"
    slam = spawn([PPPBOT, "run", "pppbot_slam", "slam", "--ros-args", "--params-file", str(params_file),
                  "-p", "use_sim_time:=true", "-p", f"map_save_name:={graph}"], name="slam")
    slam.wait_for_output(r"mapping: /scan", 30)
    # --delay: the node's subscriptions meet the player's publishers before the first scan goes out;
    # the log's own pace: its sensor-data subscription (best effort, depth 5, as slam_toolbox's)
    # dropped scans at 3x on a busy machine (102 keyframes of 106)
    play = spawn([PPPBOT, "bag", "play", str(bag), "--clock", "--rate", "1", "--delay", "3",
                  "--disable-keyboard-controls"], name="bag play")
    assert play.wait(timeout_s=120) == 0, play.output
    log = read_carmen(log_path)
    odometry = synthesize_odometry(log.poses, (0.05, 0.05, 0.05, 0.05), np.random.default_rng(0))
    parameters = carmen.slam_parameters(params_file)
    cores: dict[tuple[int, ...], Any] = {}

    def core_of(kept: tuple[int, ...]) -> Any:
        """The core's graph of the scans the node kept: on a loaded machine a scan can miss the
        node (its sensor-data subscription is best effort, as slam_toolbox's); the rest must map
        the same, keyframe for keyframe."""
        if kept not in cores:
            rows = list(kept)
            part = CarmenLog(log.name, log.stamps_s[rows], log.ranges_m[rows], log.poses[rows],
                             log.angle_min_rad, log.angle_increment_rad)
            cores[kept] = carmen.run_slam(part, odometry[rows], parameters)[1]
        return cores[kept]

    client = ros_node.create_client(SerializePoseGraph, "/slam_toolbox/serialize_map")
    assert client.wait_for_service(timeout_sec=10)
    asked = [-math.inf]

    def serialized() -> tuple[Any, tuple[int, ...]] | None:
        if time.monotonic() - asked[0] < 0.5:  # not faster than twice a second: each call writes the graph
            return None
        asked[0] = time.monotonic()
        future = client.call_async(SerializePoseGraph.Request(filename=str(graph)))
        done = wait_until(lambda: future.result() if future.done() else None, 10, "serialize_map", node=ros_node)
        node_map = load_posegraph(graph) if done.result == done.RESULT_SUCCESS else None
        if node_map is None or not node_map.keyframes:
            return None
        stamps = np.array([k.stamp_s for k in node_map.keyframes])
        rows = np.searchsorted(log.stamps_s, stamps - 1e-3)
        assert np.allclose(log.stamps_s[np.minimum(rows, len(log.stamps_s) - 1)], stamps, atol=1e-3), stamps
        kept = tuple(int(r) for r in rows)
        # the node maps in threads: once the last scan is a keyframe and the loops are in, it is done
        if kept[-1] != len(log.stamps_s) - 1 or len(kept) < len(log.stamps_s) - 2:
            return None
        core = core_of(kept)
        done_mapping = len(node_map.keyframes) == len(core.keyframes)
        return (node_map, kept) if done_mapping and len(node_map.loop_closures) == len(core.loop_closures) else None

    node_map, kept = wait_until(serialized, 180, "the node's pose graph with the last scan and the core's loops",
                                node=ros_node)
    core = core_of(kept)
    assert len(core.loop_closures) > 0  # the ring's second lap closed the loop
    core_poses = np.array([core.map_pose(i) for i in range(len(core.keyframes))])
    node_poses = np.array([node_map.map_pose(i) for i in range(len(node_map.keyframes))])
    # the true path seen from the first kept scan (the map's origin is where that scan was taken)
    truth = ring_path(step_m=0.3)[list(kept)]
    truth = se2_compose(core_poses[0], se2_relative(truth[0], truth))
    # The node closes loops in a thread of its own, on the graph as it is a few keyframes on: the
    # same closures, solved at slightly different moments (measured: within 6 cm and 0.024 rad
    # of the core's), and as close to the ring's true path as the core's (measured: within 5 cm
    # after the lap and a bit, 32 m, on 5 % odometry noise).
    np.testing.assert_allclose(node_poses[:, :2], core_poses[:, :2], atol=0.1)
    assert np.abs(np.angle(np.exp(1j * (node_poses[:, 2] - core_poses[:, 2])))).max() < 0.04
    for poses in (core_poses, node_poses):
        assert np.hypot(*(poses[:, :2] - truth[:, :2]).T).max() < 0.1
