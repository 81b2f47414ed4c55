"""``simulator``: the MuJoCo world as ROS 2 sees Gazebo plus its bridge.

Publishes ``/clock``, ``/scan``, ``/imu``, ``/joint_states``, ``/ground_truth/odom`` and
``/ground_truth/collisions`` (a PointStamped in ``world`` where each contact episode
between the robot and anything but the ground began);
takes wheel velocity commands on ``/joint_commands`` (JointState, by name);
services ``pause_physics``, ``unpause_physics``, ``reset_world`` (std_srvs/Empty)
and ``step_physics`` (std_srvs/Trigger, ``step_count`` steps while paused).
The node is the clock: it never uses sim time itself, it makes it.
"""
from __future__ import annotations

import array
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import rclpy
from builtin_interfaces.msg import Time as TimeMsg
from geometry_msgs.msg import PointStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState, LaserScan
from std_srvs.srv import Empty, Trigger

from pppbot_common.params import ParameterError, check_finite_range, param
from pppbot_common.ros.node_main import Warnings, guarded, run_node
from pppbot_common.ros.params import declare_parameters, on_valid_update
from pppbot_description.errors import DescriptionError
from pppbot_description.urdf_model import parse_urdf
from pppbot_description.xacro_model import read_robot_description
from pppbot_sim.errors import SpawnError, WorldError
from pppbot_sim.mj_build import SpawnPose
from pppbot_sim.sdf_world import World
from pppbot_sim.runner import PhysicsRunner, Reading
from pppbot_sim.simulation import (
    Collision,
    GroundTruth,
    ImuSample,
    LidarScan,
    Simulation,
    WheelState,
    load_world,
    unsimulated_summary,
)
from pppbot_sim.wheel_slip import MAX_SLIP_STDDEV, SlipModel
from pppbot_sim.worlds import find_world, model_paths

WARN_PERIOD_S = 5.0
#: How often (wall time) the loop serves ROS callbacks when running flat out.
SERVICE_PERIOD_S = 0.005
RTF_LOG_PERIOD_S = 10.0
VIEWER_PERIOD_S = 1.0 / 30.0


@dataclass(frozen=True)
class SimulatorParameters:
    world: str = param("empty", "world name (worlds/<name>.sdf) or path to an SDF or MJCF file")
    robot_description: str = param("", "URDF XML, or a .urdf/.xacro path; empty = ppp_bot's robot.urdf.xacro")
    robot_name: str = param("ppp_bot", "name of the spawned robot")
    x: float = param(0.0, "spawn x (m)")
    y: float = param(0.0, "spawn y (m)")
    z: float = param(0.05, "spawn z of the robot's root link (m); ppp_bot rests at 0.05")
    yaw: float = param(0.0, "spawn yaw (rad)")
    real_time_factor: float = param(1.0, "simulated seconds per wall second; 0 = as fast as possible")
    seed: int = param(0, "seed of the sensor-noise and wheel-slip generators")
    wheel_slip: float = param(0.0, "standard deviation of each wheel's slip fraction as its encoder reports it "
                                   "(0.02 = 2 %); makes odometry drift; 0 = exact encoders")
    wheel_slip_correlation: float = param(2.0, "how long a wheel's slip persists (sim s)")
    command_timeout: float = param(0.5, "wheels stop when no command came for this long (sim s); 0 = never")
    joint_states_rate: float = param(100.0, "/joint_states rate (Hz, sim time)")
    ground_truth_rate: float = param(50.0, "/ground_truth/odom rate (Hz, sim time)")
    clock_rate: float = param(100.0, "/clock rate (Hz, sim time)")
    step_count: int = param(1, "physics steps per step_physics call")
    paused: bool = param(False, "start paused")
    viewer: bool = param(False, "open MuJoCo's viewer window (needs a display)")

    def validate(self) -> None:
        for name in ("x", "y", "z", "yaw"):
            check_finite_range(name, getattr(self, name))
        check_finite_range("real_time_factor", self.real_time_factor, 0.0, 1000.0)
        check_finite_range("command_timeout", self.command_timeout, 0.0, 3600.0)
        check_finite_range("wheel_slip", self.wheel_slip, 0.0, MAX_SLIP_STDDEV)
        check_finite_range("wheel_slip_correlation", self.wheel_slip_correlation, 0.0, 3600.0, low_open=True)
        for name in ("joint_states_rate", "ground_truth_rate", "clock_rate"):
            check_finite_range(name, getattr(self, name), 0.0, 10000.0, low_open=True)
        if not 1 <= self.step_count <= 1_000_000:
            raise ParameterError("step_count", self.step_count, "must be in [1, 1000000]")
        if not self.robot_name or "/" in self.robot_name:
            raise ParameterError("robot_name", self.robot_name, "must be a non-empty name without '/'")


def set_stamp(target: TimeMsg, seconds: float) -> None:
    """Write ``seconds`` into a builtin_interfaces/Time in place (messages are reused)."""
    nanoseconds = int(round(seconds * 1e9))
    target.sec, target.nanosec = divmod(nanoseconds, 1_000_000_000)


class Simulator(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__("simulator", **kwargs)
        self.params = declare_parameters(self, SimulatorParameters)
        p = self.params
        world_file = find_world(p.world)
        spec, world = load_world(world_file, model_paths(world_file))
        urdf, urdf_source = read_robot_description(p.robot_description)
        robot = parse_urdf(urdf, urdf_source)
        self.sim = Simulation(spec, robot, SpawnPose(p.x, p.y, p.z, p.yaw), p.robot_name, p.seed,
                              slip=SlipModel(p.wheel_slip, p.wheel_slip_correlation))
        self.root_frame = robot.root
        self._report_world(world_file, world)

        self.clock_pub = self.create_publisher(Clock, "/clock", 10)
        self.joint_pub = self.create_publisher(JointState, "joint_states", 10)
        self.truth_pub = self.create_publisher(Odometry, "ground_truth/odom", 10)
        self.collision_pub = self.create_publisher(PointStamped, "ground_truth/collisions", 100)
        self.scan_pubs = [self.create_publisher(LaserScan, lidar.spec.topic, 10) for lidar in self.sim.lidars]
        self.imu_pubs = [self.create_publisher(Imu, imu.spec.topic, 10) for imu in self.sim.imus]
        self.create_subscription(JointState, "joint_commands", guarded(self, self.on_joint_commands, "JointState"), 10)
        self.create_service(Empty, "pause_physics", self._pause)
        self.create_service(Empty, "unpause_physics", self._unpause)
        self.create_service(Empty, "reset_world", self._reset)
        self.create_service(Trigger, "step_physics", self._step)
        schedule = self.sim.schedule
        schedule.add("clock", p.clock_rate)
        schedule.add("joint_states", p.joint_states_rate)
        schedule.add("ground_truth", p.ground_truth_rate)
        self._init_messages()
        self.viewer = self._open_viewer() if p.viewer else None
        self._viewer_synced = 0.0
        self.published_s = 0.0
        self._warn = Warnings(self, WARN_PERIOD_S)
        self.runner = PhysicsRunner(self.sim, p.real_time_factor, p.command_timeout, p.paused,
                                    log=lambda text: self.get_logger().error(text))
        on_valid_update(self, lambda: self.params, self._apply)

    def _apply(self, params: SimulatorParameters) -> None:
        """Runtime updates: real_time_factor, command_timeout, step_count take effect now."""
        fixed = ("world", "robot_description", "robot_name", "x", "y", "z", "yaw", "seed",
                 "wheel_slip", "wheel_slip_correlation",
                 "joint_states_rate", "ground_truth_rate", "clock_rate")
        changed = [n for n in fixed if getattr(params, n) != getattr(self.params, n)]
        if changed:
            self.get_logger().warning(f"{', '.join(changed)} apply at the next start of the simulator")
        self.params = params
        self.runner.real_time_factor = params.real_time_factor
        self.runner.command_timeout_s = params.command_timeout

    def _open_viewer(self) -> Any:
        try:
            import mujoco.viewer
            return mujoco.viewer.launch_passive(self.sim.model, self.sim.data)
        except Exception as exc:  # no display, no OpenGL: many exception types
            raise ParameterError("viewer", True, f"cannot open MuJoCo's viewer ({exc}); run headless") from exc

    def _sync_viewer(self) -> None:
        now = time.monotonic()
        if self.viewer is not None and now - self._viewer_synced >= VIEWER_PERIOD_S:
            if self.viewer.is_running():
                self.viewer.sync()
            self._viewer_synced = now

    def _init_messages(self) -> None:
        """One message object per topic, filled in place: publishing serializes at once."""
        self._clock_msg = Clock()
        self._joint_msg = JointState(name=list(self.sim.joint_names))
        self._truth_msg = Odometry()
        self._truth_msg.header.frame_id = "world"
        self._truth_msg.child_frame_id = self.root_frame
        self._scan_msgs = []
        for lidar in self.sim.lidars:
            s = lidar.spec
            msg = LaserScan(angle_min=s.angle_min, angle_max=s.angle_max, angle_increment=s.angle_increment,
                            time_increment=0.0, scan_time=1.0 / s.rate_hz, range_min=s.range_min,
                            range_max=s.range_max)
            msg.header.frame_id = s.frame_id
            self._scan_msgs.append(msg)
        self._imu_msgs = []
        for imu in self.sim.imus:
            msg = Imu()
            msg.header.frame_id = imu.spec.frame_id
            msg.angular_velocity_covariance[0::4] = [s * s for s in imu.spec.gyro_stddev]
            msg.linear_acceleration_covariance[0::4] = [s * s for s in imu.spec.accel_stddev]
            msg.orientation_covariance[0::4] = [1e-6] * 3
            self._imu_msgs.append(msg)

    def _report_world(self, world_file: Path, world: World | None) -> None:
        log = self.get_logger()
        if world is not None:
            summary = world.skipped_summary()
            log.info(f"world '{world.name}' from {world_file}: {len(world.static_shapes)} static shapes, "
                     f"{len(world.bodies)} free bodies, step {world.step_size_s * 1000:g} ms"
                     + (f"; {summary}" if summary else ""))
            for warning in world.warnings:
                log.warning(warning)
        else:
            log.info(f"MJCF world from {world_file}, step {self.sim.step_s * 1000:g} ms")
        p = self.params
        log.info(f"robot '{p.robot_name}' spawned at x={p.x} y={p.y} z={p.z} yaw={p.yaw}; driven joints: "
                 f"{', '.join(self.sim.handles.wheel_joints) or 'none'}")
        for lidar in self.sim.lidars:
            s = lidar.spec
            log.info(f"lidar '{s.name}': {s.samples} beams, {s.rate_hz:g} Hz, {s.range_min}-{s.range_max} m "
                     f"on /{s.topic.lstrip('/')} (frame {s.frame_id})")
        for imu in self.sim.imus:
            log.info(f"imu '{imu.spec.name}': {imu.spec.rate_hz:g} Hz on /{imu.spec.topic.lstrip('/')}")
        if self.sim.unsimulated_sensors:
            log.info(f"accepted but not rendered yet: {unsimulated_summary(self.sim.unsimulated_sensors)}")

    # -------------------------------------------------------------- commands
    def on_joint_commands(self, msg: JointState) -> None:
        if len(msg.velocity) != len(msg.name):
            self._warn("lengths", f"rejecting a joint command with {len(msg.name)} names and "
                                  f"{len(msg.velocity)} velocities")
            return
        try:
            self.runner.command(dict(zip(msg.name, msg.velocity)))
        except (KeyError, ValueError) as exc:
            reason = exc.args[0] if exc.args else str(exc)
            self._warn(type(exc).__name__, f"rejecting a joint command: {reason}")


    # -------------------------------------------------------------- services
    def _pause(self, request: Empty.Request, response: Empty.Response) -> Empty.Response:
        self.runner.pause()
        return response

    def _unpause(self, request: Empty.Request, response: Empty.Response) -> Empty.Response:
        self.runner.unpause()
        return response

    def _reset(self, request: Empty.Request, response: Empty.Response) -> Empty.Response:
        at = self.runner.reset_robot()
        self.get_logger().info(f"robot reset to its spawn pose at t = {at:.3f} s")
        return response

    def _step(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        if not self.runner.paused:
            response.success, response.message = False, "pause the simulation first (pause_physics)"
            return response
        self._publish_batch(self.runner.step(self.params.step_count))
        response.success = True
        response.message = f"stepped {self.params.step_count} step(s) to t = {self.sim.time_s:.6f} s"
        return response

    # ------------------------------------------------------------ publishing
    def _publish_batch(self, readings: list[Reading]) -> None:
        for r in readings:
            if r.kind == "clock":
                set_stamp(self._clock_msg.clock, r.stamp_s)
                self.clock_pub.publish(self._clock_msg)
            elif r.kind == "joint_states":
                self._publish_joints(r.stamp_s, r.value)
            elif r.kind == "ground_truth":
                self._publish_truth(r.stamp_s, r.value)
            elif r.kind == "lidar":
                self._publish_scan(r.index, r.value)
            elif r.kind == "imu":
                self._publish_imu(r.index, r.value)
            elif r.kind == "collision":
                self._publish_collision(r.value)
            self.published_s = r.stamp_s

    def _publish_joints(self, now_s: float, state: WheelState) -> None:
        msg = self._joint_msg
        set_stamp(msg.header.stamp, now_s)
        msg.position = array.array("d", state.positions.tobytes())
        msg.velocity = array.array("d", state.velocities.tobytes())
        msg.effort = array.array("d", state.efforts.tobytes())
        self.joint_pub.publish(msg)

    def _publish_truth(self, now_s: float, truth: GroundTruth) -> None:
        msg = self._truth_msg
        set_stamp(msg.header.stamp, now_s)
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        p.x, p.y, p.z = truth.position.tolist()
        q.x, q.y, q.z, q.w = truth.orientation_xyzw.tolist()
        lin, ang = msg.twist.twist.linear, msg.twist.twist.angular
        lin.x, lin.y, lin.z = truth.linear_velocity.tolist()
        ang.x, ang.y, ang.z = truth.angular_velocity.tolist()
        self.truth_pub.publish(msg)

    def _publish_scan(self, index: int, scan: LidarScan) -> None:
        msg = self._scan_msgs[index]
        set_stamp(msg.header.stamp, scan.stamp_s)
        msg.ranges = array.array("f", scan.ranges.tobytes())
        self.scan_pubs[index].publish(msg)

    def _publish_collision(self, collision: Collision) -> None:
        msg = PointStamped()
        msg.header.frame_id = "world"
        set_stamp(msg.header.stamp, collision.stamp_s)
        msg.point.x, msg.point.y, msg.point.z = collision.position.tolist()
        self.collision_pub.publish(msg)
        self._warn("collision", f"collision at t = {collision.stamp_s:.2f} s: {collision.robot_part} touched "
                                f"{collision.obstacle} at ({collision.position[0]:.2f}, {collision.position[1]:.2f})")

    def _publish_imu(self, index: int, sample: ImuSample) -> None:
        r, msg = sample.reading, self._imu_msgs[index]
        set_stamp(msg.header.stamp, sample.stamp_s)
        o, w, a = msg.orientation, msg.angular_velocity, msg.linear_acceleration
        o.x, o.y, o.z, o.w = r.orientation_xyzw.tolist()
        w.x, w.y, w.z = r.angular_velocity.tolist()
        a.x, a.y, a.z = r.linear_acceleration.tolist()
        self.imu_pubs[index].publish(msg)

    # ------------------------------------------------------------------ loop
    def run(self, until_s: float = math.inf) -> None:
        """Step, publish and serve callbacks at ``real_time_factor`` until shutdown
        (or until published time reaches ``until_s``)."""
        log_wall, log_sim = time.monotonic(), self.published_s

        def idle(timeout_s: float) -> None:
            nonlocal log_wall, log_sim
            rclpy.spin_once(self, timeout_sec=timeout_s)
            self._sync_viewer()
            now = time.monotonic()
            if now - log_wall >= RTF_LOG_PERIOD_S:
                rtf = self.params.real_time_factor
                target = "as fast as possible" if rtf == 0 else f"target {rtf:g}x"
                if not self.runner.paused:
                    achieved = (self.published_s - log_sim) / (now - log_wall)
                    self.get_logger().info(f"real-time factor {achieved:.1f}x ({target}), "
                                           f"t = {self.published_s:.1f} s")
                log_wall, log_sim = now, self.published_s

        self.runner.run_until(lambda: not rclpy.ok() or self.published_s >= until_s,
                              self._publish_batch, idle, SERVICE_PERIOD_S)


def main(args: list[str] | None = None) -> int:
    return run_node(Simulator, "simulator", args, spin=lambda node: node.run(), fatal=(ParameterError, DescriptionError, WorldError, SpawnError))


if __name__ == "__main__":
    sys.exit(main())
