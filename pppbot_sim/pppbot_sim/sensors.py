"""Lidar and IMU from the URDF's Gazebo sensor tags, computed on MuJoCo state.

Lidar: one ``mj_multiRay`` per scan from the sensor's site, leaving out the
robot's own geoms; Gaussian range noise from a seeded generator; no return within
``range_max`` is ``+inf`` and a return closer than ``range_min`` is ``-inf``
(REP-117, as Gazebo's gpu_lidar reports). IMU: angular velocity and linear
acceleration (specific force, so +9.81 m/s² up at rest) in the sensor frame, and
orientation in the world frame, with Gaussian noise on the first two.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from pppbot_description.urdf_model import Sensor
from pppbot_sim.errors import SpawnError
from pppbot_sim.mj_build import ROBOT_GROUP


def tag_pose(tag: Sensor) -> tuple[float, float, float, float, float, float]:
    """The sensor's ``<pose>`` in its link's frame: x y z roll pitch yaw (zeros when absent).

    Raises:
        SpawnError: not six numbers.
    """
    text = tag.find_text("pose")
    if not text:
        return (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    try:
        values = [float(v) for v in text.split()]
    except ValueError:
        values = []
    if len(values) != 6 or not all(math.isfinite(v) for v in values):
        raise SpawnError(f"sensor '{tag.name}' on link '{tag.link}': <pose> needs 6 numbers, not '{text}'")
    return (values[0], values[1], values[2], values[3], values[4], values[5])


# Geom groups the lidar sees: everything but the robot's.
LIDAR_GROUPS = np.array([0 if g == ROBOT_GROUP else 1 for g in range(6)], dtype=np.uint8)


@dataclass(frozen=True)
class LidarSpec:
    name: str
    link: str
    frame_id: str
    topic: str
    rate_hz: float
    samples: int
    angle_min: float
    angle_max: float
    range_min: float
    range_max: float
    noise_stddev: float
    pose: tuple[float, float, float, float, float, float] = (0.0,) * 6

    @property
    def angle_increment(self) -> float:
        return 0.0 if self.samples < 2 else (self.angle_max - self.angle_min) / (self.samples - 1)

    def angles(self) -> np.ndarray:
        return self.angle_min + self.angle_increment * np.arange(self.samples)

    @classmethod
    def from_tag(cls, tag: Sensor) -> LidarSpec:
        """Raises SpawnError on values a lidar cannot have."""
        base = "lidar" if tag.element.find("lidar") is not None else "ray"
        f = tag.find_float
        spec = cls(
            name=tag.name, link=tag.link, frame_id=tag.frame_id, topic=tag.topic,
            rate_hz=tag.update_rate_hz or 10.0,
            samples=int(f(f"{base}/scan/horizontal/samples", 640)),
            angle_min=f(f"{base}/scan/horizontal/min_angle", -math.pi),
            angle_max=f(f"{base}/scan/horizontal/max_angle", math.pi),
            range_min=f(f"{base}/range/min", 0.08),
            range_max=f(f"{base}/range/max", 20.0),
            noise_stddev=f(f"{base}/noise/stddev", 0.0),
            pose=tag_pose(tag),
        )
        problems = []
        if spec.samples < 1:
            problems.append(f"samples {spec.samples} < 1")
        if spec.rate_hz <= 0:
            problems.append(f"update_rate {spec.rate_hz} <= 0")
        if not 0 <= spec.range_min < spec.range_max:
            problems.append(f"range {spec.range_min}..{spec.range_max} is empty")
        if spec.angle_max < spec.angle_min:
            problems.append(f"max_angle {spec.angle_max} < min_angle {spec.angle_min}")
        if spec.noise_stddev < 0:
            problems.append(f"noise stddev {spec.noise_stddev} < 0")
        if problems:
            raise SpawnError(f"lidar '{tag.name}' on link '{tag.link}': {'; '.join(problems)}")
        return spec


def finalize_ranges(hit_distance: np.ndarray, spec: LidarSpec, rng: np.random.Generator) -> np.ndarray:
    """Raw ray distances (-1 = no hit) → LaserScan ranges with noise, +inf and -inf."""
    ranges = np.asarray(hit_distance, dtype=np.float64).copy()
    hit = ranges >= 0
    if spec.noise_stddev > 0:
        ranges[hit] += rng.normal(0.0, spec.noise_stddev, int(hit.sum()))
    out = np.full(ranges.shape, math.inf, dtype=np.float32)
    in_range = hit & (ranges <= spec.range_max)
    out[in_range] = ranges[in_range]
    out[in_range & (ranges < spec.range_min)] = -math.inf
    return out


class Lidar:
    """A lidar bound to a compiled model: ``scan(data)`` returns raw hit distances."""

    def __init__(self, spec: LidarSpec, model: mujoco.MjModel, site: str) -> None:
        self.spec = spec
        self.model = model
        self.site_id = model.site(site).id
        angles = spec.angles()
        self._local = np.stack([np.cos(angles), np.sin(angles), np.zeros_like(angles)], axis=1)
        self._geomid = np.zeros(spec.samples, dtype=np.int32)
        self._dist = np.zeros(spec.samples, dtype=np.float64)

    def scan(self, data: mujoco.MjData) -> np.ndarray:
        rotation = data.site_xmat[self.site_id].reshape(3, 3)
        directions = (self._local @ rotation.T).ravel()
        mujoco.mj_multiRay(self.model, data, data.site_xpos[self.site_id].copy(), directions, LIDAR_GROUPS, 1, -1,
                           self._geomid, self._dist, None, self.spec.samples, self.spec.range_max)
        return self._dist.copy()


@dataclass(frozen=True)
class ImuSpec:
    name: str
    link: str
    frame_id: str
    topic: str
    rate_hz: float
    #: per axis x, y, z
    gyro_stddev: tuple[float, float, float]
    accel_stddev: tuple[float, float, float]
    pose: tuple[float, float, float, float, float, float] = (0.0,) * 6

    @classmethod
    def from_tag(cls, tag: Sensor) -> ImuSpec:
        f = tag.find_float
        rate = tag.update_rate_hz or 100.0
        if rate <= 0:
            raise SpawnError(f"imu '{tag.name}' on link '{tag.link}': update_rate {rate} <= 0")

        def axes(kind: str) -> tuple[float, float, float]:
            x, y, z = (f(f"imu/{kind}/{axis}/noise/stddev", 0.0) for axis in "xyz")
            return (x, y, z)

        return cls(tag.name, tag.link, tag.frame_id, tag.topic, rate, axes("angular_velocity"),
                   axes("linear_acceleration"), tag_pose(tag))


@dataclass(frozen=True)
class ImuReading:
    orientation_xyzw: np.ndarray
    angular_velocity: np.ndarray
    linear_acceleration: np.ndarray


class Imu:
    """An IMU on a site: MuJoCo gyro, accelerometer and frame-orientation sensors."""

    def __init__(self, spec: ImuSpec, model: mujoco.MjModel, sensor_prefix: str) -> None:
        self.spec = spec

        def where(suffix: str) -> slice:
            sensor = model.sensor(f"{sensor_prefix}{suffix}")
            return slice(int(sensor.adr[0]), int(sensor.adr[0] + sensor.dim[0]))

        self._gyro, self._accel, self._quat = where("gyro"), where("accel"), where("quat")
        self._gyro_sd = np.asarray(spec.gyro_stddev)
        self._accel_sd = np.asarray(spec.accel_stddev)

    @staticmethod
    def add_to(spec: mujoco.MjSpec, site: str, sensor_prefix: str) -> None:
        for kind, suffix in ((mujoco.mjtSensor.mjSENS_GYRO, "gyro"),
                             (mujoco.mjtSensor.mjSENS_ACCELEROMETER, "accel"),
                             (mujoco.mjtSensor.mjSENS_FRAMEQUAT, "quat")):
            spec.add_sensor(name=f"{sensor_prefix}{suffix}", type=kind, objtype=mujoco.mjtObj.mjOBJ_SITE,
                            objname=site)

    def read(self, data: mujoco.MjData, rng: np.random.Generator) -> ImuReading:
        values = data.sensordata
        noise = rng.normal(0.0, 1.0, 6)
        gyro = values[self._gyro] + self._gyro_sd * noise[:3]
        accel = values[self._accel] + self._accel_sd * noise[3:]
        w, x, y, z = values[self._quat]
        return ImuReading(np.array([x, y, z, w]), gyro, accel)


def sensor_specs(tags: list[Sensor]) -> tuple[list[LidarSpec], list[ImuSpec], list[Sensor]]:
    """Split tags into lidars, IMUs and the rest (cameras and unknown types: not simulated)."""
    lidars = [LidarSpec.from_tag(t) for t in tags if t.type in ("gpu_lidar", "lidar", "gpu_ray", "ray")]
    imus = [ImuSpec.from_tag(t) for t in tags if t.type == "imu"]
    others = [t for t in tags if t.type not in ("gpu_lidar", "lidar", "gpu_ray", "ray", "imu")]
    return lidars, imus, others
