"""SLAM speed (issue 9): time per keyframe in the mapper core, and the speed-up the ``slam`` node keeps up with.

Input: the maze dataset of ``benchmarks/slam_dataset.py`` (the coverage route driven in
the simulation core, wheel slip 0.01, seed 0; made on first use, cached in
``benchmarks/.cache/``). Target: p95 ≤ 50 ms per keyframe on 640 beams, and keeping up
at 5× real time in the maze.

**Core** — every scan goes through :class:`pppbot_slam.mapper.Mapper` (settings as the
node builds them: ``SlamParameters().mapper_settings()``) in this process, no ROS, split
as the node splits it between its threads:

* the *keyframe* time is ``process()`` with loop closing deferred: matching against the
  running buffer and adding the keyframe and its edge — what the node's scan thread does
  for each keyframe, and what the p95 target is about (ms: median, p95, max);
* the *loop* time is what the node's loop-closing thread then does for that keyframe
  (``close_loops()``: the search, matching the candidate chains, solving and merging),
  reported for the keyframes that searched and for those that closed a loop.

Each keyframe's loop closing runs right after it, so the graph is the one a synchronous
mapper makes. The offline real-time factor is the dataset's sim duration over the total
processing time of every scan (``ScanRays.from_laser``, ``process`` and loop closing).
At the end the grid rebuild (``mapper.occupancy()``, what the node's map thread does
every ``map_update_interval``) is timed.

**Node** — the real ``slam`` node runs as a child process on ``use_sim_time``, and
this process replays the dataset over DDS at a speed-up ``s`` (sim seconds per wall
second), as the simulator and the controller would publish it: ``/clock`` at 100 Hz,
``/tf`` ``odom → base_footprint`` at 50 Hz (and at each scan's stamp), ``/tf_static``
``base_footprint → lidar_frame`` and ``/scan`` at 10 Hz, all of sim time. Each
keyframe's ``pose`` message is matched to its scan by stamp; its lag is the wall time
from publishing that scan to receiving the pose. The first scan is published (again
and again, same stamp) until keyframe 0 comes back, so the replay starts with DDS
matched both ways; its lag is not counted.

*Keeps up* at ``s`` means both:

1. no scan that mattered was lost: the node produced exactly the keyframes the core
   produces offline from the same scans (same count, same scan stamps; a scan lost
   in a full subscription queue or dropped by the node shifts or removes keyframes), and
2. no backlog builds: the p95 lag is at most the median wall time between keyframes at
   that speed-up (each keyframe is done, as a rule, before the next one arrives).

The highest speed-up of ``--speedups`` sustained with every lower one sustained too is
reported as ``node_sustained_speedup``. The replay's own pacing is reported
(``replay_max_behind_ms``): on this 2-core machine the replaying process takes one
core, as the simulator would.

    ./pppbot env python benchmarks/slam_speed.py [--world maze] [--speedups 1 3 5 8] [--node-sim-seconds 300]
        [--no-node]

The core and every node run use one snapshot of the ``pppbot_slam`` sources, copied
to a temporary directory at start (``slam_source_sha1`` names it), so the figures
belong to one version of the code even if the tree changes during the run.

Prints one JSON object on its last line.
"""
from __future__ import annotations

import argparse
import array
import gc
import hashlib
import json
import math
import os
import re
import shutil
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from slam_dataset import SlamDataset, ensure_dataset, load_dataset  # noqa: E402

from pppbot_common.dds_isolation import isolate_dds  # noqa: E402

TARGET_P95_MS = 50.0
TARGET_SPEEDUP = 5.0
ODOM_TF_RATE_HZ = 50.0
#: Wall seconds without a new pose, after the replay, before the node is taken to be done.
DRAIN_QUIET_S = 10.0
STAMP_TOLERANCE_S = 1e-6


@dataclass
class CoreKeyframe:
    scan: int  # index in the dataset
    stamp_s: float
    process_ms: float  # the scan thread's part
    loop_ms: float  # the loop-closing thread's part (0 when nothing was searched)
    loop_searched: bool
    loop_closed: bool
    pose: np.ndarray  # map pose as the node publishes it right after the keyframe


@dataclass
class CoreResult:
    keyframes: list[CoreKeyframe] = field(default_factory=list)
    total_s: float = 0.0
    scans: int = 0
    stage_s: dict[str, float] = field(default_factory=lambda: {"rays": 0.0, "scan_thread": 0.0, "loop_closing": 0.0})
    map_rebuild_ms: float = 0.0
    loop_closures: int = 0
    ate_rms_m: float = math.nan
    ate_max_m: float = math.nan


def _stats(values_ms: list[float]) -> dict[str, float]:
    if not values_ms:
        return {"count": 0, "median_ms": math.nan, "p95_ms": math.nan, "max_ms": math.nan}
    a = np.asarray(values_ms)
    return {"count": len(a), "median_ms": round(float(np.median(a)), 2),
            "p95_ms": round(float(np.percentile(a, 95)), 2), "max_ms": round(float(a.max()), 2)}


def run_core(ds: SlamDataset, sim_seconds: float = math.inf) -> CoreResult:
    """Feed the scans of the first ``sim_seconds`` through the mapper; time each keyframe."""
    from pppbot_slam.mapper import Mapper
    from pppbot_slam.ros.slam import SlamParameters

    mapper = Mapper(SlamParameters().mapper_settings(), defer_loops=True)
    mapper.sensor_offset = np.asarray(ds.sensor_offset, dtype=float).copy()
    result = CoreResult()
    report_at = time.perf_counter() + 10.0
    for i, stamp in enumerate(ds.stamps):
        if stamp > ds.stamps[0] + sim_seconds:
            break
        t0 = time.perf_counter()
        rays = ds.scan_rays(i)
        closures = len(mapper.loop_closures)
        t1 = time.perf_counter()
        keyframe = mapper.process(float(stamp), ds.odom[i], rays)
        t2 = time.perf_counter()
        searched = False
        if keyframe is not None and mapper.settings.do_loop_closing:
            tried = dict(mapper.tried)
            mapper.close_loops(keyframe.index)
            searched = mapper.tried != tried
        t3 = time.perf_counter()
        result.total_s += t3 - t0
        result.scans += 1
        for stage, seconds in (("rays", t1 - t0), ("scan_thread", t2 - t1), ("loop_closing", t3 - t2)):
            result.stage_s[stage] += seconds
        if keyframe is not None:
            result.keyframes.append(CoreKeyframe(i, float(stamp), (t2 - t1) * 1000.0, (t3 - t2) * 1000.0, searched,
                                                 len(mapper.loop_closures) > closures,
                                                 np.asarray(mapper.predict(ds.odom[i]))))
        if t2 > report_at:
            print(f"  core: scan {i + 1}/{len(ds.stamps)}, {len(result.keyframes)} keyframes, "
                  f"{len(mapper.loop_closures)} loop closures", file=sys.stderr)
            report_at = t2 + 10.0
    t0 = time.perf_counter()
    mapper.occupancy()
    result.map_rebuild_ms = (time.perf_counter() - t0) * 1000.0
    result.loop_closures = len(mapper.loop_closures)
    # Final keyframe poses against the truth; the map frame is the odom frame at the first keyframe.
    first = result.keyframes[0].scan
    truth_in_map = ds.truth_in_map(first)
    final = np.array([mapper.map_pose(k) for k in range(len(result.keyframes))])
    errors = np.linalg.norm(final[:, :2] - truth_in_map[[k.scan for k in result.keyframes], :2], axis=1)
    result.ate_rms_m, result.ate_max_m = float(np.sqrt(np.mean(errors ** 2))), float(errors.max())
    return result


# ------------------------------------------------------------------------ node
@dataclass
class NodeRun:
    speedup: float
    expected: list[CoreKeyframe]
    poses: list[tuple[float, float, np.ndarray]] = field(default_factory=list)  # stamp, wall received, pose
    published_wall: dict[int, float] = field(default_factory=dict)  # scan stamp (ns) → wall time published
    replay_max_behind_s: float = 0.0
    replay_wall_s: float = 0.0
    load_average: float = 0.0  # 1-minute load average at the end of the replay (other work on the machine)
    log: str = ""

    def summary(self, sim_seconds: float) -> dict[str, Any]:
        stamps = [s for s, _, _ in self.poses]
        expected = [k.stamp_s for k in self.expected]
        same = len(stamps) == len(expected) and all(abs(a - b) < STAMP_TOLERANCE_S
                                                    for a, b in zip(stamps, expected, strict=True))
        matched = sum(1 for s in stamps if any(abs(s - e) < STAMP_TOLERANCE_S for e in expected))
        lags = [(wall - self.published_wall[_ns(s)]) * 1000.0 for s, wall, _ in self.poses
                if _ns(s) in self.published_wall]
        lag = _stats(lags)
        interval_ms = float(np.median(np.diff(expected))) / self.speedup * 1000.0 if len(expected) > 1 else math.inf
        by_stamp = {_ns(k.stamp_s): k.pose for k in self.expected}
        differences = [float(np.linalg.norm(p[:2] - by_stamp[_ns(s)][:2])) for s, _, p in self.poses
                       if _ns(s) in by_stamp]
        keeps_up = bool(same and lag["count"] and lag["p95_ms"] <= interval_ms)
        return {"speedup": self.speedup, "sim_seconds": round(sim_seconds, 1),
                "keyframes": len(stamps), "keyframes_expected": len(expected), "keyframes_matching": matched,
                "same_keyframes": same, "lag_median_ms": lag["median_ms"], "lag_p95_ms": lag["p95_ms"],
                "lag_max_ms": lag["max_ms"], "keyframe_interval_wall_ms": round(interval_ms, 1),
                "pose_difference_max_m": round(max(differences), 4) if differences else math.nan,
                "dropped_scan_warnings": len(re.findall(r"dropping", self.log)),
                "loop_closure_lines": len(re.findall(r"loop closure:", self.log)),
                "replay_max_behind_ms": round(self.replay_max_behind_s * 1000.0, 1),
                "replay_wall_s": round(self.replay_wall_s, 1),
                "load_average_1min": round(self.load_average, 2), "keeps_up": keeps_up}


def _ns(stamp_s: float) -> int:
    return int(round(stamp_s * 1e9))


class Replayer:
    """This process's ROS side: publishers of what the simulator and controller publish, and /pose."""

    def __init__(self) -> None:
        import rclpy
        from geometry_msgs.msg import PoseWithCovarianceStamped
        from rclpy.executors import SingleThreadedExecutor
        from rosgraph_msgs.msg import Clock
        from sensor_msgs.msg import LaserScan
        from tf2_msgs.msg import TFMessage

        from pppbot_common.ros.qos import LATCHED

        self.rclpy = rclpy
        self.context = rclpy.Context()
        rclpy.init(args=[], context=self.context)
        self.node = rclpy.create_node("slam_speed_replay", context=self.context, start_parameter_services=False)
        self.clock_pub = self.node.create_publisher(Clock, "/clock", 10)
        self.tf_pub = self.node.create_publisher(TFMessage, "/tf", 100)
        self.static_pub = self.node.create_publisher(TFMessage, "/tf_static", LATCHED)
        self.scan_pub = self.node.create_publisher(LaserScan, "/scan", 10)
        self.run: NodeRun | None = None
        self.pose_sub = self.node.create_subscription(PoseWithCovarianceStamped, "/pose", self._on_pose, 100)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self._spin, name="replay-executor", daemon=True)
        self.thread.start()

    def _spin(self) -> None:
        while self.context.ok():
            try:
                self.executor.spin_once(timeout_sec=0.1)
            except Exception:
                if self.context.ok():
                    raise
                return

    def _on_pose(self, msg: Any) -> None:
        from pppbot_common.se2 import yaw_from_quaternion

        received = time.monotonic()
        if self.run is None:
            return
        stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        self.run.poses.append((stamp, received, np.array([p.x, p.y, yaw_from_quaternion(q.x, q.y, q.z, q.w)])))

    def connected(self) -> bool:
        return (self.scan_pub.get_subscription_count() > 0 and self.tf_pub.get_subscription_count() > 0
                and self.clock_pub.get_subscription_count() > 0 and self.static_pub.get_subscription_count() > 0
                and self.pose_sub.get_publisher_count() > 0)

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        self.rclpy.try_shutdown(context=self.context)
        self.thread.join(timeout=2.0)


def _transform(parent: str, child: str, stamp_ns: int, pose: np.ndarray) -> Any:
    from geometry_msgs.msg import TransformStamped

    t = TransformStamped()
    t.header.frame_id, t.child_frame_id = parent, child
    t.header.stamp.sec, t.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
    t.transform.translation.x, t.transform.translation.y = float(pose[0]), float(pose[1])
    t.transform.rotation.z, t.transform.rotation.w = math.sin(pose[2] / 2.0), math.cos(pose[2] / 2.0)
    return t


def replay(replayer: Replayer, ds: SlamDataset, run: NodeRun, sim_seconds: float) -> None:
    """Publish the dataset's first ``sim_seconds`` at ``run.speedup``, paced on the wall clock."""
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import LaserScan
    from tf2_msgs.msg import TFMessage

    t_first = float(ds.stamps[0])
    end_s = t_first + sim_seconds
    scan_index = {_ns(s): i for i, s in enumerate(ds.stamps)}
    scan = LaserScan(angle_min=ds.angle_min, angle_max=ds.angle_min + ds.angle_increment * (ds.ranges.shape[1] - 1),
                     angle_increment=ds.angle_increment, time_increment=0.0, scan_time=ds.scan_period_s,
                     range_min=ds.range_min, range_max=ds.range_max)
    scan.header.frame_id = ds.lidar_frame
    clock = Clock()
    first_ns = _ns(t_first)
    # The first scan, until its keyframe comes back: DDS discovery is done both ways and the
    # node has the static transform (a best-effort scan published too early is lost unseen).
    deadline = time.monotonic() + 30.0
    while not run.poses:
        if time.monotonic() > deadline:
            raise RuntimeError("the slam node did not answer the first scan within 30 s")
        replayer.static_pub.publish(TFMessage(transforms=[_transform("base_footprint", ds.lidar_frame, 0,
                                                                     ds.sensor_offset)]))
        clock.clock.sec, clock.clock.nanosec = divmod(first_ns, 1_000_000_000)
        replayer.clock_pub.publish(clock)
        scan.header.stamp.sec, scan.header.stamp.nanosec = divmod(first_ns, 1_000_000_000)
        scan.ranges = array.array("f", ds.ranges[0].tobytes())
        replayer.scan_pub.publish(scan)
        replayer.tf_pub.publish(TFMessage(transforms=[_transform("odom", "base_footprint", first_ns, ds.odom[0])]))
        wait_until = time.monotonic() + 0.5
        while not run.poses and time.monotonic() < wait_until:
            time.sleep(0.01)
    tf_period = 1.0 / ODOM_TF_RATE_HZ
    next_tf = t_first + tf_period
    wall0 = time.monotonic()
    for stamp, odom in zip(ds.odom_stream_stamps, ds.odom_stream, strict=True):
        t = float(stamp)
        if t <= t_first + STAMP_TOLERANCE_S:
            continue
        if t > end_s:
            break
        ns = _ns(t)
        i = scan_index.get(ns)
        due = wall0 + (t - t_first) / run.speedup
        ahead = due - time.monotonic()
        if ahead > 0:
            time.sleep(ahead)
        else:
            run.replay_max_behind_s = max(run.replay_max_behind_s, -ahead)
        # The simulator's /clock (the stream is every 100 Hz controller tick, the clock's rate too).
        clock.clock.sec, clock.clock.nanosec = divmod(ns, 1_000_000_000)
        replayer.clock_pub.publish(clock)
        if i is not None:  # the simulator's /scan, before the controller's odometry of the same tick
            scan.header.stamp.sec, scan.header.stamp.nanosec = divmod(ns, 1_000_000_000)
            scan.ranges = array.array("f", ds.ranges[i].tobytes())
            run.published_wall[ns] = time.monotonic()
            replayer.scan_pub.publish(scan)
        if i is not None or t >= next_tf - 1e-9:  # the controller's odom → base frame
            replayer.tf_pub.publish(TFMessage(transforms=[_transform("odom", "base_footprint", ns, odom)]))
            if t >= next_tf - 1e-9:
                next_tf += tf_period * max(1, math.floor((t - next_tf) / tf_period) + 1)
    run.replay_wall_s = time.monotonic() - wall0
    run.load_average = os.getloadavg()[0]


def run_node(replayer: Replayer, ds: SlamDataset, expected: list[CoreKeyframe], speedup: float,
             sim_seconds: float) -> NodeRun:
    from pppbot_common.process import ChildProcess

    run = NodeRun(speedup, expected)
    cmd = [sys.executable, "-m", "pppbot_slam.ros.slam", "--ros-args", "-p", "use_sim_time:=true"]
    with ChildProcess(cmd, name="slam") as slam:
        slam.wait_for_output(r"mapping: ", 60.0)
        deadline = time.monotonic() + 30.0
        while not replayer.connected():
            if time.monotonic() > deadline:
                raise RuntimeError("the slam node's subscriptions and /pose did not match within 30 s")
            time.sleep(0.05)
        replayer.run = run
        print(f"  node at {speedup:g}x: replaying {sim_seconds:.0f} sim s (slam pid {slam.pid})", file=sys.stderr)
        replay(replayer, ds, run, sim_seconds)
        # Let the node finish what it has queued: until every expected pose came, or it went quiet.
        last_count, quiet_since = -1, time.monotonic()
        while len(run.poses) < len(expected) and time.monotonic() - quiet_since < DRAIN_QUIET_S:
            if len(run.poses) != last_count:
                last_count, quiet_since = len(run.poses), time.monotonic()
            time.sleep(0.05)
        replayer.run = None
        slam.stop()
        run.log = slam.output
    return run


def snapshot_slam_sources(directory: Path) -> str:
    """Copy the ``pppbot_slam`` package into ``directory`` and put it first on the import path,
    for this process and its children; returns a SHA-1 of the copied sources.

    Must run before anything imports ``pppbot_slam``.
    """
    import importlib.util

    if "pppbot_slam" in sys.modules:
        raise RuntimeError("pppbot_slam was imported before its snapshot")
    spec = importlib.util.find_spec("pppbot_slam")
    if spec is None or not spec.submodule_search_locations:
        raise RuntimeError("pppbot_slam is not importable (run with ./pppbot env)")
    source = Path(next(iter(spec.submodule_search_locations))).resolve()
    shutil.copytree(source, directory / "pppbot_slam", ignore=shutil.ignore_patterns("__pycache__"))
    digest = hashlib.sha1()
    for path in sorted((directory / "pppbot_slam").rglob("*.py")):
        digest.update(path.relative_to(directory).as_posix().encode())
        digest.update(path.read_bytes())
    sys.path.insert(0, str(directory))
    os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [str(directory), os.environ.get("PYTHONPATH", "")]))
    import subprocess

    child = subprocess.run([sys.executable, "-c", "import pppbot_slam; print(pppbot_slam.__file__)"],
                           capture_output=True, text=True, check=True).stdout.strip()
    if not child.startswith(str(directory)):
        raise RuntimeError(f"a child process imports pppbot_slam from {child}, not from the snapshot in {directory}")
    return digest.hexdigest()


# ------------------------------------------------------------------------ main
def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--world", default="maze")
    parser.add_argument("--route", default=None)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--wheel-slip", type=float, default=0.01)
    parser.add_argument("--speedups", type=float, nargs="+", default=[1.0, 3.0, 5.0, 8.0])
    parser.add_argument("--node-sim-seconds", type=float, default=300.0,
                        help="sim seconds of the dataset replayed to the node per speed-up (0 = all)")
    parser.add_argument("--no-node", action="store_true", help="only the core")
    parser.add_argument("--sim-seconds", type=float, default=0.0,
                        help="use only the dataset's first sim seconds for everything (0 = all; for quick checks)")
    args = parser.parse_args()
    isolate_dds()
    snapshot = tempfile.TemporaryDirectory(prefix="slam_speed_")
    source_sha1 = snapshot_slam_sources(Path(snapshot.name))
    path = ensure_dataset(args.world, args.route, args.seed, args.wheel_slip)
    ds = load_dataset(path)
    results: dict[str, Any] = {"benchmark": "slam_speed", "world": ds.world, "route": ds.route, "seed": ds.seed,
                               "wheel_slip": ds.wheel_slip, "dataset_scans": len(ds.stamps),
                               "lidar_beams": int(ds.ranges.shape[1]), "dataset_sim_seconds": round(ds.duration_s, 1),
                               "cpu_count": os.cpu_count(), "target_p95_ms": TARGET_P95_MS,
                               "target_speedup": TARGET_SPEEDUP, "slam_source_sha1": source_sha1,
                               "load_average_1min_at_start": round(os.getloadavg()[0], 2)}
    print(f"dataset {path}: {len(ds.stamps)} scans, {ds.duration_s:.0f} sim s", file=sys.stderr)

    gc.collect()
    limit_s = args.sim_seconds or math.inf
    core = run_core(ds, limit_s)
    duration_s = min(ds.duration_s, limit_s)
    all_kf = _stats([k.process_ms for k in core.keyframes])
    searches = _stats([k.loop_ms for k in core.keyframes if k.loop_searched])
    closing = _stats([k.loop_ms for k in core.keyframes if k.loop_closed])
    core_rtf = duration_s / core.total_s
    if not str(sys.modules["pppbot_slam"].__file__).startswith(snapshot.name):
        raise RuntimeError("the core did not run the snapshot of pppbot_slam")
    results.update({
        "keyframes": all_kf["count"], "loop_closures": core.loop_closures,
        "keyframe_median_ms": all_kf["median_ms"], "keyframe_p95_ms": all_kf["p95_ms"],
        "keyframe_max_ms": all_kf["max_ms"],
        "loop_searches": searches["count"], "loop_search_median_ms": searches["median_ms"],
        "loop_search_p95_ms": searches["p95_ms"], "loop_search_max_ms": searches["max_ms"],
        "loop_closing_keyframes": closing["count"], "loop_closing_median_ms": closing["median_ms"],
        "loop_closing_p95_ms": closing["p95_ms"], "loop_closing_max_ms": closing["max_ms"],
        "core_sim_seconds": round(duration_s, 1), "core_processing_s": round(core.total_s, 2),
        "core_real_time_factor": round(core_rtf, 1),
        "core_scans_per_s": round(core.scans / core.total_s, 1),
        **{f"core_{stage}_ms_per_scan": round(1000.0 * seconds / max(core.scans, 1), 2)
           for stage, seconds in core.stage_s.items()},
        "map_rebuild_ms": round(core.map_rebuild_ms, 1),
        "keyframe_ate_rms_m": round(core.ate_rms_m, 3), "keyframe_ate_max_m": round(core.ate_max_m, 3),
        "meets_p95_target": bool(all_kf["p95_ms"] <= TARGET_P95_MS),
        "real_time_factor": round(core_rtf, 1)})
    print(f"core: {all_kf['count']} keyframes of {len(ds.stamps)} scans, {core.loop_closures} loop closures; "
          f"per keyframe (scan thread) median {all_kf['median_ms']} ms, p95 {all_kf['p95_ms']} ms, "
          f"max {all_kf['max_ms']} ms; loop closing (its own thread): {searches['count']} searches, median "
          f"{searches['median_ms']}, p95 {searches['p95_ms']}, max {searches['max_ms']} ms, of which "
          f"{closing['count']} closed loops (median {closing['median_ms']}, p95 {closing['p95_ms']} ms); "
          f"offline {core_rtf:.1f}x real time, {core.scans / core.total_s:.0f} scans/s (per scan: "
          + ", ".join(f"{stage} {1000.0 * t / max(core.scans, 1):.2f} ms" for stage, t in core.stage_s.items())
          + "); "
          f"map rebuild {core.map_rebuild_ms:.0f} ms; keyframe ATE RMS {core.ate_rms_m:.3f} m",
          file=sys.stderr)

    if not args.no_node:
        sim_seconds = min(args.node_sim_seconds or math.inf, limit_s, ds.duration_s + 1.0)
        t_end = float(ds.stamps[0]) + sim_seconds
        expected = [k for k in core.keyframes if k.stamp_s <= t_end]
        replayer = Replayer()
        sustained = 0.0
        try:
            for speedup in sorted(args.speedups):
                run = run_node(replayer, ds, expected, speedup, sim_seconds)
                figures = run.summary(min(sim_seconds, ds.duration_s))
                key = f"node_{speedup:g}x"
                results.update({f"{key}_{name}": value for name, value in figures.items() if name != "speedup"})
                print(f"node at {speedup:g}x: {figures['keyframes']}/{figures['keyframes_expected']} keyframes "
                      f"({'the same' if figures['same_keyframes'] else 'NOT the same'} as offline), lag median "
                      f"{figures['lag_median_ms']} ms, p95 {figures['lag_p95_ms']} ms, max {figures['lag_max_ms']} ms "
                      f"(keyframe interval {figures['keyframe_interval_wall_ms']} ms wall); "
                      f"{'keeps up' if figures['keeps_up'] else 'does NOT keep up'}; replay behind by at most "
                      f"{figures['replay_max_behind_ms']} ms; load average {figures['load_average_1min']}",
                      file=sys.stderr)
                if figures["keeps_up"] and sustained == max([0.0, *[s for s in args.speedups if s < speedup]]):
                    sustained = speedup
        finally:
            replayer.close()
        results["node_sim_seconds"] = round(min(sim_seconds, ds.duration_s), 1)
        results["node_sustained_speedup"] = sustained
        results["meets_speedup_target"] = bool(sustained >= TARGET_SPEEDUP)
    snapshot.cleanup()
    print(json.dumps({k: None if isinstance(v, float) and not math.isfinite(v) else v for k, v in results.items()}))


if __name__ == "__main__":
    main()
