"""What a SLAM node sees on a world's route, with ground truth: generated in the simulation core, no ROS.

The robot drives a route of ``worlds/<world>.routes.yaml`` the way ``./pppbot eval``
drives it, with every piece of the ROS stack's control loop replayed in-process at
the same sim-time rates, so nothing depends on DDS timing:

* the route driver (:class:`pppbot_eval.driver.RouteDriver`, pure pursuit on
  ground truth) is asked for a command on ``/ground_truth/odom`` ticks (50 Hz) once
  :data:`COMMAND_PERIOD_S` has passed, as the eval node does;
* twist_mux passes the teleop input through (one input, never timed out);
* the diff-drive controller at 100 Hz (``config/my_controllers.yaml``): its speed
  limiters (:class:`pppbot_common.limits.SpeedLimiter`), twist → wheel speeds
  (:meth:`DiffDriveGeometry.wheel_speeds`; the simulator clamps to the URDF's
  ±10 rad/s) and wheel odometry (:class:`pppbot_common.kinematics.Odometry`) from
  the wheel positions the simulator reports at 100 Hz, with its wheel slip;
* the lidar (640 beams, 10 Hz) and the IMU are sampled as the simulator node samples
  them, so a seed gives the same noise as ``launch_sim seed:=N``.

Commands act at once (no DDS latency). Per scan the dataset holds its stamp, the
odometry pose ``odom → base_footprint`` at that stamp, the true ``world →
base_footprint`` pose, and the ranges as ``/scan`` carries them (``+inf`` no return,
``-inf`` closer than ``range_min``). It also keeps the odometry after every
controller update (100 Hz; the controller publishes every other one on ``/tf``),
for replaying ``/tf``.

    ./pppbot env python benchmarks/slam_dataset.py --world maze [--route NAME] [--seed 0] [--wheel-slip 0.01]

prints the dataset's path and a JSON summary on its last line. From Python:
``ensure_dataset("maze")`` returns the cached file (``benchmarks/.cache/``, made when
missing) and ``load_dataset(path)`` reads it.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
CACHE = Path(__file__).resolve().parent / ".cache"
#: Bump when what a dataset holds or how it is driven changes: old files are then not reused.
FORMAT_VERSION = 1
#: The eval node's command period (sim s), checked on ground-truth ticks.
COMMAND_PERIOD_S = 0.05
GROUND_TRUTH_RATE_HZ = 50.0
JOINT_STATES_RATE_HZ = 100.0
#: Standing still before the drive and after it (sim s).
SETTLE_S = 1.0
TAIL_S = 1.0
DEFAULT_SPEED_MPS = 0.3


@dataclass(frozen=True)
class SlamDataset:
    """One drive. Poses are (x, y, yaw) in m and rad; stamps in sim seconds."""

    world: str
    route: str
    seed: int
    wheel_slip: float
    stamps: np.ndarray  # (N,) scan stamps
    odom: np.ndarray  # (N, 3) base_footprint in odom at each scan (wheel odometry, with slip)
    truth: np.ndarray  # (N, 3) base_footprint in the world at each scan
    ranges: np.ndarray  # (N, beams) float32, as LaserScan.ranges
    angle_min: float
    angle_increment: float
    range_min: float
    range_max: float
    sensor_offset: np.ndarray  # (3,) the lidar frame in base_footprint
    lidar_frame: str
    odom_stream_stamps: np.ndarray  # (M,) every controller update (100 Hz); the scan stamps are among them
    odom_stream: np.ndarray  # (M, 3) base_footprint in odom after each update
    route_points: np.ndarray  # (K, 2) the route polyline in the world
    speed_mps: float
    collisions: int
    route_completed: bool

    @property
    def duration_s(self) -> float:
        return float(self.stamps[-1] - self.stamps[0]) if len(self.stamps) else 0.0

    @property
    def scan_period_s(self) -> float:
        return float(np.median(np.diff(self.stamps))) if len(self.stamps) > 1 else 0.1

    def scan_rays(self, i: int) -> Any:
        """Scan ``i`` as the slam node hands it to the mapper."""
        from pppbot_slam.occupancy import ScanRays

        return ScanRays.from_laser(self.angle_min, self.angle_increment, self.ranges[i].astype(float),
                                   self.range_min, self.range_max)

    def truth_in_map(self, first: int) -> np.ndarray:
        """The true poses (N, 3) in SLAM's map frame: the odom frame at scan ``first``, SLAM's first keyframe."""
        from pppbot_common.se2 import se2_compose, se2_inverse

        return np.asarray(se2_compose(self.odom[first], se2_compose(se2_inverse(self.truth[first]), self.truth)))


def dataset_path(world: str, route: str, seed: int, wheel_slip: float, speed_mps: float = DEFAULT_SPEED_MPS) -> Path:
    speed = "" if speed_mps == DEFAULT_SPEED_MPS else f"_v{speed_mps:g}"
    return CACHE / f"slam_{world}_{route}_seed{seed}_slip{wheel_slip:g}{speed}_f{FORMAT_VERSION}.npz"


def load_dataset(path: Path | str) -> SlamDataset:
    """Read a dataset written by :func:`generate`.

    Raises:
        ValueError: the file is not a dataset of this format version.
    """
    with np.load(Path(path), allow_pickle=False) as data:
        version = int(data["format_version"]) if "format_version" in data else -1
        if version != FORMAT_VERSION:
            raise ValueError(f"{path}: dataset format {version}, this loader reads {FORMAT_VERSION}")
        return SlamDataset(
            world=str(data["world"]), route=str(data["route"]), seed=int(data["seed"]),
            wheel_slip=float(data["wheel_slip"]), stamps=data["stamps"], odom=data["odom"], truth=data["truth"],
            ranges=data["ranges"], angle_min=float(data["angle_min"]), angle_increment=float(data["angle_increment"]),
            range_min=float(data["range_min"]), range_max=float(data["range_max"]),
            sensor_offset=data["sensor_offset"], lidar_frame=str(data["lidar_frame"]),
            odom_stream_stamps=data["odom_stream_stamps"], odom_stream=data["odom_stream"],
            route_points=data["route_points"], speed_mps=float(data["speed_mps"]),
            collisions=int(data["collisions"]), route_completed=bool(data["route_completed"]))


def ensure_dataset(world: str, route: str | None = None, seed: int = 0, wheel_slip: float = 0.01,
                   speed_mps: float = DEFAULT_SPEED_MPS) -> Path:
    """The cached dataset of (world, route, seed, wheel_slip), generated first when missing."""
    from pppbot_eval.routes import load_routes, routes_file, select_route
    from pppbot_sim.worlds import find_world

    world_file = find_world(world)
    chosen = select_route(load_routes(routes_file(world_file)), route, routes_file(world_file))
    path = dataset_path(world_file.stem, chosen.name, seed, wheel_slip, speed_mps)
    if not path.is_file():
        generate(world, chosen.name, seed, wheel_slip, path, speed_mps)
    return path


def _controller() -> Any:
    """ppp_bot's diff-drive controller parameters (config/my_controllers.yaml), validated by the node's dataclass."""
    import yaml

    from pppbot_common.params import from_values
    from pppbot_control.ros.diff_drive_controller import DiffDriveParameters

    document = yaml.safe_load((ROOT / "config" / "my_controllers.yaml").read_text())
    return from_values(DiffDriveParameters, document["diff_drive_base_controller"]["ros__parameters"])


def _planar(translation: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """(x, y, yaw) of a pose given as a translation and a rotation matrix."""
    return np.array([translation[0], translation[1], np.arctan2(rotation[1, 0], rotation[0, 0])])


def _cross_track_m(points: np.ndarray, route: np.ndarray) -> np.ndarray:
    """Each point's distance (m) to the route polyline."""
    a, b = route[:-1], route[1:]
    ab = b - a
    length2 = np.maximum((ab * ab).sum(axis=1), 1e-12)
    out = np.empty(len(points))
    for i, p in enumerate(points):
        t = np.clip(((p - a) * ab).sum(axis=1) / length2, 0.0, 1.0)
        out[i] = float(np.min(np.linalg.norm(a + t[:, None] * ab - p, axis=1)))
    return out


def generate(world: str, route_name: str | None, seed: int, wheel_slip: float, out: Path,  # noqa: PLR0915
             speed_mps: float = DEFAULT_SPEED_MPS) -> dict[str, Any]:
    """Drive the route in the simulation core and write the dataset to ``out``; returns a summary.

    Raises:
        RuntimeError: the route was not completed within 2.5 × its time + 60 s (nothing written).
    """
    from pppbot_common.kinematics import Odometry
    from pppbot_common.limits import SpeedLimiter
    from pppbot_common.se2 import se2_compose, se2_inverse, se2_relative, wrap_angles
    from pppbot_description.kinematics import KinematicTree
    from pppbot_description.urdf_model import parse_urdf
    from pppbot_description.xacro_model import process_xacro
    from pppbot_eval.driver import DriverSettings, RouteDriver
    from pppbot_eval.routes import load_routes, routes_file, select_route
    from pppbot_sim.mj_build import SpawnPose
    from pppbot_sim.simulation import Event, EventKind, Simulation, load_world
    from pppbot_sim.wheel_slip import SlipModel
    from pppbot_sim.worlds import find_world, model_paths

    world_file = find_world(world)
    route = select_route(load_routes(routes_file(world_file)), route_name, routes_file(world_file))
    robot = parse_urdf(process_xacro())
    spec, _ = load_world(world_file, model_paths(world_file))
    x0, y0, yaw0 = route.start
    sim = Simulation(spec, robot, SpawnPose(x0, y0, SpawnPose().z, yaw0), seed=seed, slip=SlipModel(wheel_slip))
    if len(sim.lidars) != 1:
        raise RuntimeError(f"the robot has {len(sim.lidars)} lidars; the dataset takes exactly one")
    lidar = sim.lidars[0].spec
    sim.schedule.add(Event(EventKind.JOINT_STATES), JOINT_STATES_RATE_HZ)
    sim.schedule.add(Event(EventKind.GROUND_TRUTH), GROUND_TRUTH_RATE_HZ)

    # Frames as robot_state_publisher gives them: base_footprint and the lidar in the root link.
    links = KinematicTree(robot).link_poses()
    footprint_in_root = _planar(*links["base_footprint"])
    sensor_offset = se2_relative(footprint_in_root, _planar(*links[lidar.frame_id]))

    params = _controller()
    geometry = params.geometry()
    linear, angular = SpeedLimiter(params.limits("linear")), SpeedLimiter(params.limits("angular"))
    odometry = Odometry(geometry)
    left_index = [sim.joint_names.index(n) for n in params.left_wheel_names]
    right_index = [sim.joint_names.index(n) for n in params.right_wheel_names]
    control_dt = 1.0 / params.update_rate

    driver = RouteDriver(route.points, DriverSettings(speed_mps=speed_mps))
    limit_s = SETTLE_S + 2.5 * route.length_m / speed_mps + 60.0
    target = (0.0, 0.0)
    next_command_s = SETTLE_S
    finished_s: float | None = None
    last_control_s: float | None = None
    stamps: list[float] = []
    odom_rows: list[np.ndarray] = []
    truth_rows: list[np.ndarray] = []
    scans: list[np.ndarray] = []
    pending_scan: tuple[float, np.ndarray] | None = None
    stream_stamps: list[float] = []
    stream_rows: list[np.ndarray] = []
    collisions = []
    wall0 = time.perf_counter()
    next_report_s = 100.0
    while True:
        events = sim.advance(1000)
        now = sim.time_s
        collisions += sim.take_collisions()
        wheels = None
        kinds = {event.kind for event in events}
        for event in sorted(events, key=lambda e: (e.kind is EventKind.LIDAR, e.index)):
            # Each sensor has its own noise generator: the same scans as the simulator node's.
            if event.kind is EventKind.LIDAR:
                pending_scan = (now, sim.lidar_scan(event.index).ranges.astype(np.float32))
            elif event.kind is EventKind.IMU:
                sim.imu_sample(event.index)
            elif event.kind is EventKind.JOINT_STATES:
                wheels = sim.wheel_state()
        truth = sim.ground_truth()
        truth_pose = se2_compose(np.array([truth.position[0], truth.position[1], truth.yaw]), footprint_in_root)
        # The eval node: a command on a ground-truth tick once COMMAND_PERIOD_S has passed.
        if (EventKind.GROUND_TRUTH in kinds and now >= SETTLE_S and finished_s is None
                and (now >= next_command_s or driver.finished)):
            next_command_s = now + COMMAND_PERIOD_S
            target = driver.command(truth.position[0], truth.position[1], truth.yaw)
            if driver.finished:
                finished_s, target = now, (0.0, 0.0)
        if wheels is not None:
            # The controller's update (100 Hz, on the same ticks as /joint_states).
            dt = 0.0 if last_control_s is None else now - last_control_s
            last_control_s = now
            v, w = linear.limit(target[0], dt), angular.limit(target[1], dt)
            left, right = geometry.wheel_speeds(v, w)
            sim.set_wheel_velocities({**{n: left for n in params.left_wheel_names},
                                      **{n: right for n in params.right_wheel_names}})
            odometry.update_from_positions(float(np.mean(wheels.positions[left_index])),
                                           float(np.mean(wheels.positions[right_index])), dt)
            odom_pose = se2_compose(np.array([odometry.x, odometry.y, odometry.yaw]), footprint_in_root)
            stream_stamps.append(now)
            stream_rows.append(odom_pose)
            if pending_scan is not None and abs(pending_scan[0] - now) < 0.5 * control_dt:
                stamps.append(pending_scan[0])
                scans.append(pending_scan[1])
                odom_rows.append(odom_pose)
                truth_rows.append(truth_pose)
                pending_scan = None
        if now >= next_report_s:
            print(f"  {world_file.stem}/{route.name}: sim {now:6.0f} s, {driver.travelled_m:6.1f}/"
                  f"{driver.length_m:.1f} m, {now / (time.perf_counter() - wall0):.0f}x", file=sys.stderr)
            next_report_s += 100.0
        if finished_s is not None and now >= finished_s + TAIL_S:
            break
        if now > limit_s:
            raise RuntimeError(f"{world_file.stem}/{route.name}: route not finished within {limit_s:.0f} sim s "
                               f"({driver.travelled_m:.1f} of {driver.length_m:.1f} m)")
    wall_s = time.perf_counter() - wall0

    truth_arr, odom_arr = np.array(truth_rows), np.array(odom_rows)
    # Drift: the truth seen from the start pose (= the odom frame) against odometry.
    truth_in_odom = se2_compose(se2_inverse(truth_arr[0]), truth_arr)
    truth_in_odom = se2_compose(odom_arr[0], truth_in_odom)
    drift = np.linalg.norm(odom_arr[:, :2] - truth_in_odom[:, :2], axis=1)
    yaw_drift = np.abs(wrap_angles(odom_arr[:, 2] - truth_in_odom[:, 2]))
    cross_track = _cross_track_m(truth_arr[:, :2], route.points)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + f".{os.getpid()}.tmp.npz")
    np.savez_compressed(
        tmp, format_version=np.int64(FORMAT_VERSION), world=np.str_(world_file.stem), route=np.str_(route.name),
        seed=np.int64(seed), wheel_slip=np.float64(wheel_slip), stamps=np.array(stamps), odom=odom_arr,
        truth=truth_arr, ranges=np.array(scans, dtype=np.float32), angle_min=np.float64(lidar.angle_min),
        angle_increment=np.float64(lidar.angle_increment), range_min=np.float64(lidar.range_min),
        range_max=np.float64(lidar.range_max), sensor_offset=np.asarray(sensor_offset, dtype=float),
        lidar_frame=np.str_(lidar.frame_id), odom_stream_stamps=np.array(stream_stamps),
        odom_stream=np.array(stream_rows), route_points=route.points, speed_mps=np.float64(speed_mps),
        collisions=np.int64(len(collisions)), route_completed=np.bool_(driver.finished))
    os.replace(tmp, out)
    driven = float(np.linalg.norm(np.diff(truth_arr[:, :2], axis=0), axis=1).sum())
    return {"world": world_file.stem, "route": route.name, "seed": seed, "wheel_slip": wheel_slip,
            "scans": len(stamps), "sim_seconds": round(float(stamps[-1] - stamps[0]), 2),
            "route_length_m": round(route.length_m, 2), "driven_length_m": round(driven, 2),
            "route_completed": driver.finished, "collisions": len(collisions),
            "cross_track_max_m": round(float(cross_track.max()), 3),
            "cross_track_mean_m": round(float(cross_track.mean()), 3),
            "odom_drift_end_m": round(float(drift[-1]), 3), "odom_drift_max_m": round(float(drift.max()), 3),
            "odom_yaw_drift_end_rad": round(float(yaw_drift[-1]), 4),
            "wall_seconds": round(wall_s, 1), "real_time_factor": round(float(stamps[-1]) / wall_s, 1)}


def summary(dataset: SlamDataset) -> dict[str, Any]:
    """Figures of a loaded dataset (what the CLI prints for a cached file)."""
    from pppbot_common.se2 import se2_compose, se2_inverse, wrap_angles

    truth_in_odom = se2_compose(dataset.odom[0], se2_compose(se2_inverse(dataset.truth[0]), dataset.truth))
    drift = np.linalg.norm(dataset.odom[:, :2] - truth_in_odom[:, :2], axis=1)
    cross_track = _cross_track_m(dataset.truth[:, :2], dataset.route_points)
    route_length = float(np.linalg.norm(np.diff(dataset.route_points, axis=0), axis=1).sum())
    driven = float(np.linalg.norm(np.diff(dataset.truth[:, :2], axis=0), axis=1).sum())
    return {"world": dataset.world, "route": dataset.route, "seed": dataset.seed, "wheel_slip": dataset.wheel_slip,
            "scans": len(dataset.stamps), "beams": int(dataset.ranges.shape[1]),
            "sim_seconds": round(dataset.duration_s, 2), "route_length_m": round(route_length, 2),
            "driven_length_m": round(driven, 2), "route_completed": dataset.route_completed,
            "collisions": dataset.collisions, "cross_track_max_m": round(float(cross_track.max()), 3),
            "cross_track_mean_m": round(float(cross_track.mean()), 3),
            "odom_drift_end_m": round(float(drift[-1]), 3), "odom_drift_max_m": round(float(drift.max()), 3),
            "odom_yaw_drift_end_rad": round(float(abs(wrap_angles(dataset.odom[-1, 2] - truth_in_odom[-1, 2]))), 4)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--world", default="maze")
    parser.add_argument("--route", default=None, help="a route of <world>.routes.yaml (default: the first)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--wheel-slip", type=float, default=0.01)
    parser.add_argument("--speed", type=float, default=DEFAULT_SPEED_MPS, help="route speed (m/s)")
    parser.add_argument("--force", action="store_true", help="generate again even when cached")
    args = parser.parse_args()
    if args.force:
        from pppbot_eval.routes import load_routes, routes_file, select_route
        from pppbot_sim.worlds import find_world

        world_file = find_world(args.world)
        route = select_route(load_routes(routes_file(world_file)), args.route, routes_file(world_file))
        path = dataset_path(world_file.stem, route.name, args.seed, args.wheel_slip, args.speed)
        generate(args.world, route.name, args.seed, args.wheel_slip, path, args.speed)
    else:
        path = ensure_dataset(args.world, args.route, args.seed, args.wheel_slip, args.speed)
    print(path)
    print(json.dumps({"benchmark": "slam_dataset", "path": str(path), **summary(load_dataset(path))}))


if __name__ == "__main__":
    main()
