"""``amcl``: Adaptive Monte Carlo Localization on a known map, in Nav2's ``amcl`` place (``localization:=true``).

Subscribes the map (``map_topic``, transient local), scans (``scan_topic``), TF
(``odom_frame_id → base_frame_id`` at each scan's stamp, and the lidar's mounting) and
``initialpose`` (PoseWithCovarianceStamped in ``global_frame_id``, what RViz's "2D Pose
Estimate" sends). Publishes ``amcl_pose`` (transient local, on each filter update),
``particle_cloud`` (nav2_msgs/ParticleCloud, best effort) and the TF
``global_frame_id → odom_frame_id`` at every scan, stamped with the scan's time plus
``transform_tolerance``. Services: ``set_initial_pose`` (nav2_msgs/SetInitialPose, as a
message on ``initialpose``), and (std_srvs/Empty) ``reinitialize_global_localization``
(particles spread over the map's free space) and ``request_nomotion_update`` (update on
the next scan without motion). Until it has an initial pose (``set_initial_pose`` with
``initial_pose.*``, ``/initialpose`` or global localization) it says so every 2 s, as
Nav2 does.

Parameters carry Nav2's names and meanings; four are pppbot's own: ``refine_estimate``
(polish each estimate by fitting the whole scan to the map, :mod:`pppbot_nav.amcl.refine`,
and between filter updates refit map → odom at every scan, so odometry's drift does not
wait for ``update_min_d``), ``beams_with_returns`` (the likelihood field's ``max_beams``
picked among the beams that returned),
``refined_particle_fraction`` (the share of particles redrawn around each refined estimate)
and ``seed`` (the random generator's seed; −1 draws one). The algorithm is
:mod:`pppbot_nav.amcl.localizer`.
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from typing import Any

import numpy as np
from geometry_msgs.msg import PoseWithCovarianceStamped
from nav2_msgs.msg import Particle, ParticleCloud
from nav2_msgs.srv import SetInitialPose
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from rclpy.duration import Duration
from rclpy.time import Time
from sensor_msgs.msg import LaserScan
from std_srvs.srv import Empty
from tf2_msgs.msg import TFMessage

from pppbot_common.params import ParameterError, check_finite_range, param, parameter_fields, ros_name
from pppbot_common.ros.maps import grid_from_message
from pppbot_common.ros.params import declare_parameters, fixed_parameters
from pppbot_common.ros.planar import transform_message
from pppbot_common.ros.qos import LATCHED, SENSOR
from pppbot_common.se2 import quaternion_from_yaw, yaw_from_quaternion
from pppbot_lockstep.ros.lifecycle import ManagedNode
from pppbot_lockstep.ros.runner import Warnings, guarded, run_node
from pppbot_lockstep.ros.scan_odometry import ScanOdometry
from pppbot_nav.amcl.filter import FilterSettings
from pppbot_nav.amcl.laser import LaserModelType, LaserSettings, laser_scans
from pppbot_nav.amcl.localizer import (
    Localizer,
    LocalizerSettings,
    Update,
    covariance_from_message,
    covariance_to_message,
)
from pppbot_nav.amcl.motion import MotionNoise, RobotModel
from pppbot_nav.errors import AmclError, OffTheMap

#: Seconds between "set the initial pose" reminders (Nav2's).
NO_POSE_WARN_PERIOD_S = 2.0
#: The covariance of an initial pose from parameters (Nav2's: 0.5 m, 0.5 m, π/12 rad standard deviations).
INITIAL_COVARIANCE = np.diag([0.5 ** 2, 0.5 ** 2, (math.pi / 12) ** 2])


@dataclass(frozen=True)
class AmclParameters:
    alpha1: float = param(0.2, "rotation noise from rotation")
    alpha2: float = param(0.2, "rotation noise from translation")
    alpha3: float = param(0.2, "translation noise from translation")
    alpha4: float = param(0.2, "translation noise from rotation")
    alpha5: float = param(0.2, "strafe noise from translation (omni model)")
    base_frame_id: str = param("base_footprint", "robot base frame")
    global_frame_id: str = param("map", "map frame")
    odom_frame_id: str = param("odom", "odometry frame")
    scan_topic: str = param("scan", "laser scan topic")
    map_topic: str = param("map", "map topic (transient local)")
    laser_model_type: str = param("likelihood_field", "likelihood_field or beam")
    laser_likelihood_max_dist: float = param(2.0, "likelihood field: distance cap to obstacles (m)")
    laser_max_range: float = param(100.0, "beams beyond this are no return (m); ≤ 0: the scan's range_max")
    laser_min_range: float = param(-1.0, "beams under this are no return (m); ≤ 0: the scan's range_min")
    max_beams: int = param(60, "beams used per scan")
    z_hit: float = param(0.5, "weight of the hit component")
    z_short: float = param(0.05, "beam model: weight of the short-reading component")
    z_max: float = param(0.05, "beam model: weight of the max-range component")
    z_rand: float = param(0.5, "weight of the random component")
    sigma_hit: float = param(0.2, "standard deviation of the hit component (m)")
    lambda_short: float = param(0.1, "beam model: decay of short readings (1/m)")
    min_particles: int = param(500, "fewest particles")
    max_particles: int = param(2000, "most particles")
    pf_err: float = param(0.05, "KLD bound: largest error between true and estimated distribution")
    pf_z: float = param(0.99, "KLD bound: upper standard normal quantile")
    recovery_alpha_slow: float = param(0.0, "slow average weight rate (0: no random particles)")
    recovery_alpha_fast: float = param(0.0, "fast average weight rate (0: no random particles)")
    resample_interval: int = param(1, "filter updates between resamplings")
    robot_model_type: str = param("nav2_amcl::DifferentialMotionModel",
                                  "nav2_amcl::DifferentialMotionModel or nav2_amcl::OmniMotionModel")
    update_min_d: float = param(0.25, "translation before a filter update (m)")
    update_min_a: float = param(0.2, "rotation before a filter update (rad)")
    transform_tolerance: float = param(1.0, "map → odom is stamped this far ahead of the scan (s)")
    tf_broadcast: bool = param(True, "publish map → odom")
    set_initial_pose: bool = param(False, "start from initial_pose.* instead of waiting for /initialpose")
    always_reset_initial_pose: bool = param(False, "on each new map, restart from initial_pose.* or /initialpose")
    first_map_only: bool = param(False, "ignore maps after the first")
    initial_pose_x: float = param(0.0, "initial x (m)", ros_name="initial_pose.x")
    initial_pose_y: float = param(0.0, "initial y (m)", ros_name="initial_pose.y")
    initial_pose_z: float = param(0.0, "initial z (m, unused)", ros_name="initial_pose.z")
    initial_pose_yaw: float = param(0.0, "initial yaw (rad)", ros_name="initial_pose.yaw")
    tf_buffer_duration: float = param(10.0, "seconds of TF history kept")
    refine_estimate: bool = param(True, "pppbot: polish each estimate by fitting the whole scan to the map, and "
                                        "refit map → odom at every scan between filter updates")
    beams_with_returns: bool = param(True, "pppbot: with likelihood_field, pick the max_beams among the beams that "
                                           "returned (Nav2 picks among all and skips those without a return)")
    refined_particle_fraction: float = param(0.1, "pppbot: share of particles redrawn around each refined "
                                                  "estimate (0: refinement only changes the output)")
    seed: int = param(-1, "pppbot: random seed (-1: a fresh one)")

    def validate(self) -> None:
        for name in ("alpha1", "alpha2", "alpha3", "alpha4", "alpha5", "z_hit", "z_short", "z_max", "z_rand",
                     "lambda_short"):
            check_finite_range(name, getattr(self, name), 0.0, 1e6)
        for name in ("sigma_hit", "laser_likelihood_max_dist"):
            check_finite_range(name, getattr(self, name), 0.0, 1e3, low_open=True)
        for name in ("update_min_d", "update_min_a", "transform_tolerance"):
            check_finite_range(name, getattr(self, name), 0.0, 1e3)
        check_finite_range("tf_buffer_duration", self.tf_buffer_duration, 0.0, 3600.0, low_open=True)
        check_finite_range("refined_particle_fraction", self.refined_particle_fraction, 0.0, 1.0)
        for name in ("initial_pose_x", "initial_pose_y", "initial_pose_z", "initial_pose_yaw"):
            check_finite_range(name.replace("initial_pose_", "initial_pose."), getattr(self, name))
        if self.max_beams < 2:
            raise ParameterError("max_beams", self.max_beams, "must be at least 2")
        if self.resample_interval < 1:
            raise ParameterError("resample_interval", self.resample_interval, "must be at least 1")
        for name, enum in (("laser_model_type", LaserModelType), ("robot_model_type", RobotModel)):
            allowed = [m.value for m in enum]
            if getattr(self, name) not in allowed:
                raise ParameterError(name, getattr(self, name), f"must be one of {', '.join(allowed)}")
        for name in ("base_frame_id", "global_frame_id", "odom_frame_id", "scan_topic", "map_topic"):
            if not getattr(self, name):
                raise ParameterError(name, getattr(self, name), "must not be empty")
        try:
            self.settings().filter.validate()
        except AmclError as exc:
            name = exc.parameter or "min_particles"
            raise ParameterError(name, getattr(self, name), str(exc)) from exc

    def settings(self) -> LocalizerSettings:
        return LocalizerSettings(
            filter=FilterSettings(self.min_particles, self.max_particles, self.pf_err, self.pf_z,
                                  self.recovery_alpha_slow, self.recovery_alpha_fast),
            laser=LaserSettings(self.z_hit, self.z_short, self.z_max, self.z_rand, self.sigma_hit,
                                self.lambda_short, self.laser_likelihood_max_dist, self.max_beams,
                                self.laser_min_range, self.laser_max_range,
                                self.beams_with_returns
                                and self.laser_model_type == LaserModelType.LIKELIHOOD_FIELD.value),
            laser_model_type=LaserModelType(self.laser_model_type),
            robot_model_type=RobotModel(self.robot_model_type),
            motion_noise=MotionNoise(self.alpha1, self.alpha2, self.alpha3, self.alpha4, self.alpha5),
            update_min_d=self.update_min_d, update_min_a=self.update_min_a,
            resample_interval=self.resample_interval, refine_estimate=self.refine_estimate,
            refined_particle_fraction=self.refined_particle_fraction)

    def initial_pose(self) -> np.ndarray:
        return np.array([self.initial_pose_x, self.initial_pose_y, self.initial_pose_yaw])


#: Everything but the topics may change while AMCL runs.
LIVE = frozenset(ros_name(f) for f in parameter_fields(AmclParameters)) - {"scan_topic", "map_topic"}


class Amcl(ManagedNode):
    """A lifecycle node, as Nav2's: it takes the map and initial poses at any time, and uses scans
    (and publishes) only while active."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("amcl", **kwargs)
        self.params = p = declare_parameters(self, AmclParameters)
        self.parameter_notes = {
            "*beam_skip*": "beam skipping is not implemented (Nav2's default, do_beamskip false)",
            "do_beamskip": "beam skipping is not implemented (Nav2's default, do_beamskip false)",
            "save_pose_rate": "the pose is not saved to parameters: the launch gives the initial pose",
            "use_sim_time": ""}
        # Topics are subscribed once (as Nav2's AMCL, whose dynamic parameters leave them out).
        fixed_parameters(self, lambda: self.params, LIVE, self._set_params)
        self.rng = np.random.default_rng(None if p.seed < 0 else p.seed)
        self.localizer: Localizer | None = None
        self._pose: tuple[np.ndarray, np.ndarray] | None = None  # the last initial pose asked for (mean, cov)
        self._map_to_odom: np.ndarray | None = None
        self._warn = Warnings(self, settling=("no map", "transform"))
        self._no_pose = Warnings(self, NO_POSE_WARN_PERIOD_S)
        self.scans = ScanOdometry(self, p.odom_frame_id, p.base_frame_id, self._on_scan_with_odometry, self._warn,
                                  p.tf_buffer_duration)
        self._map_arrived = self.port.require(f"a map on '{p.map_topic}'")
        self.pose_pub = self.create_publisher(PoseWithCovarianceStamped, "amcl_pose", LATCHED)
        self.cloud_pub = self.create_publisher(ParticleCloud, "particle_cloud", SENSOR)
        self.tf_pub = self.create_publisher(TFMessage, "/tf", 100)
        self.create_subscription(OccupancyGridMsg, p.map_topic, guarded(self, self._on_map, "OccupancyGrid"), LATCHED)
        self.create_subscription(LaserScan, p.scan_topic, guarded(self, self.scans.add, "LaserScan"), SENSOR,
                                 data_path=True, at_step=True)
        self.create_subscription(PoseWithCovarianceStamped, "initialpose",
                                 guarded(self, self._on_initial_pose, "PoseWithCovarianceStamped"), 10)
        self.create_service(SetInitialPose, "set_initial_pose", self._set_initial_pose)
        self.create_service(Empty, "reinitialize_global_localization", self._global_localization)
        self.create_service(Empty, "request_nomotion_update", self._nomotion_update)
        if p.set_initial_pose:
            self._pose = (p.initial_pose(), INITIAL_COVARIANCE)
        self.get_logger().info(f"localizing: {p.scan_topic} with {p.odom_frame_id} → {p.base_frame_id} on "
                               f"{p.map_topic}; {p.min_particles}–{p.max_particles} particles, {p.laser_model_type}")

    def _set_params(self, params: AmclParameters) -> None:
        old = self.params
        self.params = params
        self.scans.odom_frame, self.scans.base_frame = params.odom_frame_id, params.base_frame_id
        if self.localizer is not None and params.settings() != old.settings():
            self.localizer.reconfigure(params.settings())

    # ------------------------------------------------------------------- map
    def _on_map(self, msg: OccupancyGridMsg) -> None:
        p = self.params
        if self.localizer is not None and p.first_map_only:
            return
        if msg.header.frame_id.lstrip("/") != p.global_frame_id:
            self._warn("map frame", f"the map is in frame '{msg.header.frame_id}', not global_frame_id "
                                    f"'{p.global_frame_id}': localizing in it anyway")
        try:
            grid = grid_from_message(msg)
            if self.localizer is None:
                self.localizer = Localizer(p.settings(), grid, self.rng)
            else:
                last = self.localizer.last
                self.localizer.set_map(grid)
                if last is not None and not p.always_reset_initial_pose:
                    self._pose = (last.estimate.mean, last.estimate.covariance)
        except (AmclError, ValueError) as exc:
            self._warn("map", f"ignoring a map: {exc}")
            return
        self.get_logger().info(f"map: {grid.width} × {grid.height} cells at {grid.resolution} m, "
                               f"{int(self.localizer.field.free.sum())} free")
        self._map_arrived()
        if self._pose is not None:
            try:
                self._start_at(*self._pose)
            except AmclError as exc:  # a map that does not hold the last pose: localized nowhere, Nav2 goes on
                self._pose, self._map_to_odom = None, None
                self.localizer.forget_pose()
                # Not throttled with refused poses: said once, as the pose is gone until one is given.
                self.get_logger().warning(f"no pose on this map, set the initial pose: {exc}")

    def _start_at(self, mean: np.ndarray, covariance: np.ndarray) -> None:
        """Raises AmclError: a pose the localizer refuses (off the map, spread wider than it)."""
        assert self.localizer is not None
        self.localizer.set_initial_pose(mean, covariance)
        self.get_logger().info(f"initial pose ({mean[0]:.3f}, {mean[1]:.3f}, {mean[2]:.3f}); "
                               f"{len(self.localizer.filter)} particles")

    # --------------------------------------------------------- initial poses
    def _on_initial_pose(self, msg: PoseWithCovarianceStamped) -> None:
        p = self.params
        frame = msg.header.frame_id.lstrip("/")
        if frame != p.global_frame_id:
            self._warn("initial pose", f"ignoring an initial pose in frame '{msg.header.frame_id}': initial poses "
                                       f"must be in global_frame_id '{p.global_frame_id}'")
            return
        pose = msg.pose.pose
        o = pose.orientation
        mean = np.array([pose.position.x, pose.position.y, yaw_from_quaternion(o.x, o.y, o.z, o.w)])
        try:
            covariance = covariance_from_message(list(msg.pose.covariance))
            if not np.isfinite(mean).all():
                raise AmclError(f"an initial pose must be finite, not {mean.tolist()}")
            if self.localizer is None:
                self._pose = (mean, covariance)
                self.get_logger().info("initial pose received; waiting for a map")
                return
            self._start_at(mean, covariance)
            self._pose = (mean, covariance)
        except AmclError as exc:  # each kind named apart: a pose off the map must not hide a bad one's reason
            self._warn("initial pose off the map" if isinstance(exc, OffTheMap) else "initial pose",
                       f"ignoring an initial pose: {exc}")

    def _set_initial_pose(self, request: SetInitialPose.Request,
                          response: SetInitialPose.Response) -> SetInitialPose.Response:
        """Nav2's ``set_initial_pose`` service: as a message on ``initialpose``."""
        self._on_initial_pose(request.pose)
        return response

    def _global_localization(self, request: Empty.Request, response: Empty.Response) -> Empty.Response:
        if self.localizer is None:
            self.get_logger().warning("reinitialize_global_localization: no map yet")
            return response
        self.localizer.global_localization()
        self._pose = None  # a map that comes later restarts from the search's estimate, not an older pose
        self.get_logger().info(f"global localization: {len(self.localizer.filter)} particles over the free space")
        return response

    def _nomotion_update(self, request: Empty.Request, response: Empty.Response) -> Empty.Response:
        if self.localizer is not None:
            self.localizer.request_nomotion_update()
        return response

    # ------------------------------------------------------------------ scans
    def _on_scan_with_odometry(self, msg: LaserScan, stamp: float, frame: str, odom_pose: np.ndarray,
                               sensor: np.ndarray) -> None:
        if not self.active:
            return
        loc = self.localizer
        if loc is None:
            self._warn("no map", f"no map on '{self.params.map_topic}' yet: scans are not used")
            return
        if not loc.initialized:
            self._no_pose("no pose", "AMCL cannot publish a pose or update the transform. Please set the initial "
                                     "pose (/initialpose, RViz's 2D Pose Estimate, or set_initial_pose).")
            return
        laser = loc.settings.laser
        ranges = np.asarray(msg.ranges, dtype=float)
        mount = (float(sensor[0]), float(sensor[1]), float(sensor[2]))
        try:
            scan, full = laser_scans(ranges, msg.angle_min, msg.angle_increment, msg.range_min, msg.range_max,
                                     mount, laser, full=loc.settings.refine_estimate)
            update = loc.update(odom_pose, scan, full)
            tracked = loc.track(odom_pose, full) if update is None and full is not None else None
        except AmclError as exc:
            self._warn("scan", f"dropping a scan: {exc}")
            return
        if update is not None:
            if update.alias is not None:
                (x, y, yaw), fit = update.alias
                self.get_logger().info(f"global localization: ({x:.2f}, {y:.2f}, {yaw:.2f}) holds the weight but only "
                                       f"{100 * fit:.0f} % of the scan fits the map there: searching again")
            self._map_to_odom = update.map_to_odom
            self._publish_pose(msg.header.stamp, update)
            self._publish_cloud(msg.header.stamp)
        elif tracked is not None:
            self._map_to_odom = tracked
        if self._map_to_odom is not None and self.params.tf_broadcast:
            self._publish_transform(Time.from_msg(msg.header.stamp), self._map_to_odom)

    def _publish_pose(self, stamp: Any, update: Update) -> None:
        msg = PoseWithCovarianceStamped()
        msg.header.stamp = stamp
        msg.header.frame_id = self.params.global_frame_id
        mean = update.estimate.mean
        msg.pose.pose.position.x, msg.pose.pose.position.y = float(mean[0]), float(mean[1])
        o = msg.pose.pose.orientation
        o.x, o.y, o.z, o.w = quaternion_from_yaw(float(mean[2]))
        msg.pose.covariance = covariance_to_message(update.estimate.covariance)
        self.pose_pub.publish(msg)

    def _publish_cloud(self, stamp: Any) -> None:
        if self.cloud_pub.get_subscription_count() == 0 or self.localizer is None:
            return
        f = self.localizer.filter
        half = f.particles[:, 2] / 2.0
        msg = ParticleCloud()
        msg.header.stamp = stamp
        msg.header.frame_id = self.params.global_frame_id
        particles = []
        for (x, y, _), s, c, w in zip(f.particles.tolist(), np.sin(half).tolist(), np.cos(half).tolist(),
                                      f.weights.tolist(), strict=True):
            particle = Particle(weight=w)
            particle.pose.position.x, particle.pose.position.y = x, y
            particle.pose.orientation.z, particle.pose.orientation.w = s, c
            particles.append(particle)
        msg.particles = particles
        self.cloud_pub.publish(msg)

    def _publish_transform(self, scan_time: Time, map_to_odom: np.ndarray) -> None:
        p = self.params
        stamp = (scan_time + Duration(seconds=p.transform_tolerance)).to_msg()
        self.tf_pub.publish(TFMessage(transforms=[transform_message(p.global_frame_id, p.odom_frame_id, stamp,
                                                                    map_to_odom)]))


def main(args: list[str] | None = None) -> int:
    return run_node(Amcl, "amcl", args)


if __name__ == "__main__":
    sys.exit(main())
