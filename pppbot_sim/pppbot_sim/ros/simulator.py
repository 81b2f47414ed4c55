"""``simulator``: the MuJoCo world as ROS 2 sees Gazebo plus its bridge.

Publishes ``/clock``, ``/scan``, ``/imu``, ``/joint_states``, ``/ground_truth/odom`` and
``/ground_truth/collisions`` (a PointStamped in ``world`` where each contact episode
between the robot and anything but the ground began), ``/diagnostics`` (whether the robot is
upright: :mod:`pppbot_common.upright`); takes wheel velocity commands on
``/joint_commands`` (JointState, by name) from a controller outside; services
``pause_physics``, ``unpause_physics``, ``reset_world`` (std_srvs/Empty) and
``step_physics`` (std_srvs/Trigger, ``step_count`` steps while paused). The node is the
clock: it never uses sim time itself, it makes it.

Controllers named by the robot's gz_ros2_control plugin run in this process, ticked by
the physics loop, with a ``controller_manager`` node that lists and switches them
(:mod:`pppbot_sim.ros.hosted`). ``controller_remappings`` are applied to those nodes, as
gz_ros2_control applies its plugin's ``<ros><remapping>``: by default
``/diff_drive_base_controller/odom:=/odom``, where ppp_bot's odometry is read. With ``lockstep:=true`` time advances
only when the lockstep participants have done their work (:mod:`pppbot_lockstep.ros.coordinator`);
``real_time_factor`` then caps the speed (0: as fast as they allow). Without lockstep it
runs against the wall clock at ``real_time_factor``.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from builtin_interfaces.msg import Time as TimeMsg
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PointStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.utilities import remove_ros_args
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState, LaserScan
from std_srvs.srv import Empty, Trigger

from pppbot_common.params import ParameterError
from pppbot_common.ros.driven_clock import DrivenClock
from pppbot_common.ros.params import declare_parameters, on_valid_update
from pppbot_common.ros.wire import MessageTemplate, stamp_fields, stamp_values, vector
from pppbot_common.upright import UPRIGHT_STATUS, UprightWatch
from pppbot_description.errors import DescriptionError
from pppbot_description.urdf_model import RobotModel, parse_urdf
from pppbot_description.xacro_model import read_robot_description
from pppbot_lockstep.protocol import LockstepError
from pppbot_lockstep.ros.coordinator import Coordinator, CoordinatorPort
from pppbot_lockstep.ros.node import StepNode
from pppbot_lockstep.ros.port import StepPort
from pppbot_lockstep.ros.runner import Process, Warnings, guarded, run_nodes
from pppbot_sim.controllers import controllers_file, read_plan
from pppbot_sim.errors import SpawnError, WorldError
from pppbot_sim.hosting import node_factories
from pppbot_sim.mj_build import SpawnPose
from pppbot_sim.ros.camera_publisher import CameraPublisher
from pppbot_sim.ros.gz_diff_drive import host_diff_drives
from pppbot_sim.ros.hosted import Hosted, SimWheels, controller_arguments, host
from pppbot_sim.ros.simulator_params import SimulatorParameters
from pppbot_sim.runner import (
    CameraReading,
    ClockTick,
    CollisionReading,
    ControlTick,
    GroundTruthReading,
    ImuReadingAt,
    JointStatesReading,
    LidarReading,
    Pacer,
    PhysicsRunner,
    PluginTick,
    Reading,
)
from pppbot_sim.sdf_model import World
from pppbot_sim.simulation import Collision, Event, EventKind, Simulation, load_world, unsimulated_summary
from pppbot_sim.wheel_slip import SlipModel
from pppbot_sim.worlds import find_world, model_paths

WARN_PERIOD_S = 5.0
#: How often (wall time) the loop serves ROS callbacks when running flat out.
SERVICE_PERIOD_S = 0.005
RTF_LOG_PERIOD_S = 10.0
#: /diagnostics every this many sim seconds (diagnostic_updater's 1 Hz), and at once on a change
DIAGNOSTICS_PERIOD_S = 1.0
VIEWER_PERIOD_S = 1.0 / 30.0


def _ns(seconds: float) -> int:
    return int(round(seconds * 1e9))


def set_stamp(target: TimeMsg, seconds: float) -> None:
    """Write ``seconds`` into a builtin_interfaces/Time in place (messages are reused)."""
    nanoseconds = int(round(seconds * 1e9))
    target.sec, target.nanosec = divmod(nanoseconds, 1_000_000_000)


class Simulator(StepNode):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__("simulator", **kwargs)
        self.params = declare_parameters(self, SimulatorParameters)
        p = self.params
        # In lockstep what this process publishes is counted (steps carry it, participants wait for
        # it) and what its nodes receive on the data path too (time moves on once they have it).
        self.lockstep_port = CoordinatorPort() if p.lockstep else None
        if self.lockstep_port is not None:
            self.port = self.lockstep_port
        world_file = find_world(p.world)
        spec, world = load_world(world_file, model_paths(world_file))
        urdf, urdf_source = read_robot_description(p.robot_description)
        robot = parse_urdf(urdf, urdf_source)
        self.sim = Simulation(spec, robot, SpawnPose(p.x, p.y, p.z, p.yaw), p.robot_name, p.seed,
                              slip=SlipModel(p.wheel_slip, p.wheel_slip_correlation), world=world)
        self.root_frame = robot.root
        self._report_world(world_file, world)

        self.clock_pub = self.create_publisher(Clock, "/clock", 10)
        self.joint_pub = self.create_publisher(JointState, "joint_states", 10)
        self.truth_pub = self.create_publisher(Odometry, "ground_truth/odom", 10)
        self.collision_pub = self.create_publisher(PointStamped, "ground_truth/collisions", 100)
        self.scan_pubs = [self.create_publisher(LaserScan, lidar.spec.topic, 10) for lidar in self.sim.lidars]
        self.imu_pubs = [self.create_publisher(Imu, imu.spec.topic, 10) for imu in self.sim.imus]
        # An external controller's wheel commands: in lockstep a step waits for those sent before it.
        self._commands_sub = self.create_subscription(JointState, "joint_commands",
                                                      guarded(self, self.on_joint_commands, "JointState"), 10,
                                                      data_path=True, needs_publisher=False)
        self.create_service(Empty, "pause_physics", self._pause)
        self.create_service(Empty, "unpause_physics", self._unpause)
        self.create_service(Empty, "reset_world", self._reset)
        self.create_service(Trigger, "step_physics", self._step)
        schedule = self.sim.schedule
        if not p.lockstep:
            schedule.add(Event(EventKind.CLOCK), p.clock_rate)
        schedule.add(Event(EventKind.JOINT_STATES), p.joint_states_rate)
        schedule.add(Event(EventKind.GROUND_TRUTH), p.ground_truth_rate)
        self._init_messages()
        self.viewer = self._open_viewer() if p.viewer else None
        self._viewer_synced = 0.0
        self.published_s = 0.0
        self._clock_ns = -1  # the time of the last /clock
        self._driven: list[DrivenClock] = []  # the clocks of the nodes run beside it
        self._published_since_sync = False  # a reading or a controller's odometry, since the last sync
        self._warn = Warnings(self, WARN_PERIOD_S)
        self.cameras = CameraPublisher(self, self.sim, p.seed, p.cameras, self._warn, self.get_logger().error,
                                       every_frame=p.lockstep)
        for line in self.cameras.describe():
            if line.startswith("cameras off:"):  # one call site per severity (rclpy's rule)
                self.get_logger().error(line)
            else:
                self.get_logger().info(line)
        self.runner = PhysicsRunner(self.sim, p.command_timeout, p.paused,
                                    log=lambda text: self.get_logger().error(text))
        self.pacer = Pacer(p.real_time_factor)
        # Readings nobody listens to are not even computed (each sensor has its own noise
        # generator, so skipping one never changes another's readings).
        self._listeners: dict[EventKind, list[Any]] = {
            EventKind.JOINT_STATES: [self.joint_pub], EventKind.LIDAR: self.scan_pubs, EventKind.IMU: self.imu_pubs}
        # Ground truth is always read: the upright watch needs it, whoever listens.
        self.upright = UprightWatch(p.upright_max_tilt, p.upright_min_height)
        self.diagnostics_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self._next_diagnostics_s = 0.0
        self.coordinator = (Coordinator(self, p.expected_participants(), p.lockstep_timeout,
                                        lambda text: self.get_logger().info(text), self.lockstep_port)
                            if self.lockstep_port is not None else None)
        self.hosted = self._host_controllers(robot)
        self.controllers, self.broadcasters = self.hosted.controllers, self.hosted.broadcasters
        self.composed_nodes: list[Node] = self.hosted.nodes
        self.diff_drives = host_diff_drives(self, self.sim, p.cmd_vel_topic, self.runner.command)
        for hosted in self.diff_drives:
            d = hosted.spec
            self.get_logger().info(
                f"DiffDrive plugin of '{d.model}' ({d.where}): {hosted.topic} → wheels "
                f"{', '.join(d.joints)}; odometry {d.frame_id} → {d.child_frame_id} "
                + ", ".join(f"on {t}" for t in (d.odom_topic if d.publish_odom else None, d.tf_topic) if t)
                + f" at {d.odom_rate_hz:g} Hz")
        on_valid_update(self, lambda: self.params, self._apply)

    def _host_controllers(self, robot: RobotModel) -> Hosted:
        """The controllers of the robot's gz_ros2_control plugin, in this process, and the
        controller manager over them (see :mod:`.hosted`)."""
        path = controllers_file(robot)
        if path is None:
            return Hosted()
        plan = read_plan(path)
        arguments = controller_arguments(plan, [r for r in self.params.controller_remappings if r])
        hosted = host(plan, robot, SimWheels(self.runner), arguments, self.port)
        for name, kind in hosted.left_out:
            self.get_logger().warning(f"controller '{name}' of type {kind} (in {path}): no installed package hosts "
                                      "that type (entry point group pppbot_sim.hosted_controllers): left out")
        if hosted.controllers:
            self.sim.schedule.add(Event(EventKind.CONTROL), plan.update_rate_hz)
            names = ", ".join(c.name for c in hosted.controllers)
            self.get_logger().info(f"controllers from {path} in this process at {plan.update_rate_hz:g} Hz: {names}")
        if hosted.manager is None and plan.controllers:
            self.get_logger().warning("no installed package offers a controller_manager (entry point group "
                                      "pppbot_sim.controller_managers): the controllers run, unlisted")
        return hosted

    def destroy_node(self) -> None:
        self.cameras.close()
        for node in self.composed_nodes:
            node.destroy_node()
        super().destroy_node()

    def _apply(self, params: SimulatorParameters) -> None:
        """Runtime updates: real_time_factor, command_timeout, step_count take effect now."""
        fixed = ("world", "robot_description", "robot_name", "cmd_vel_topic", "controller_remappings",
                 "x", "y", "z", "yaw", "seed", "wheel_slip", "wheel_slip_correlation", "lockstep", "cameras",
                 "lockstep_participants",
                 "joint_states_rate", "ground_truth_rate", "clock_rate")
        changed = [n for n in fixed if getattr(params, n) != getattr(self.params, n)]
        if changed:
            self.get_logger().warning(f"{', '.join(changed)} apply at the next start of the simulator")
        self.params = params
        self.pacer.real_time_factor = params.real_time_factor
        self.pacer.restart()
        self.runner.command_timeout_s = params.command_timeout
        if self.coordinator is not None:
            self.coordinator.timeout_s = params.lockstep_timeout

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
        """A template per topic (:mod:`pppbot_common.ros.wire`): each publish patches the values into
        bytes serialized once and publishes those."""
        self._clock_wire = MessageTemplate(Clock(), stamp_fields("clock"))
        count = len(self.sim.joint_names)
        self._joints_wire = MessageTemplate(JointState(name=list(self.sim.joint_names), position=[0.0] * count,
                                                  velocity=[0.0] * count, effort=[0.0] * count),
                                       [*stamp_fields(), "position", "velocity", "effort"])
        truth = Odometry()
        truth.header.frame_id = "world"
        truth.child_frame_id = self.root_frame
        self._truth_wire = MessageTemplate(truth, [*stamp_fields(), *vector("pose.pose.position"),
                                              *vector("pose.pose.orientation", "xyzw"), *vector("twist.twist.linear"),
                                              *vector("twist.twist.angular")])
        self._scan_wires = []
        for lidar in self.sim.lidars:
            s = lidar.spec
            msg = LaserScan(angle_min=s.angle_min, angle_max=s.angle_max, angle_increment=s.angle_increment,
                            time_increment=0.0, scan_time=1.0 / s.rate_hz, range_min=s.range_min,
                            range_max=s.range_max, ranges=[0.0] * s.samples)
            msg.header.frame_id = s.frame_id
            self._scan_wires.append(MessageTemplate(msg, [*stamp_fields(), "ranges"]))
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
        for warning in self.sim.warnings:
            log.warning(warning)
        p = self.params
        log.info(f"robot '{p.robot_name}' spawned at x={p.x} y={p.y} z={self.sim.spawn.z:.4g} yaw={p.yaw}; "
                 "driven joints: "
                 f"{', '.join(self.sim.handles.wheel_joints) or 'none'}")
        for lidar in self.sim.lidars:
            s = lidar.spec
            log.info(f"lidar '{s.name}': {s.samples} beams, {s.rate_hz:g} Hz, {s.range_min}-{s.range_max} m "
                     f"on /{s.topic.lstrip('/')} (frame {s.frame_id})")
        for imu in self.sim.imus:
            log.info(f"imu '{imu.spec.name}': {imu.spec.rate_hz:g} Hz on /{imu.spec.topic.lstrip('/')}")
        if self.sim.unsimulated_sensors:
            log.warning(f"sensors not simulated: {unsimulated_summary(self.sim.unsimulated_sensors)}")
        if p.lockstep:
            expected = ", ".join(p.expected_participants()) or "nobody named"
            log.info(f"lockstep: time waits for its participants (at start: {expected}); "
                     f"{'as fast as they allow' if p.real_time_factor == 0 else f'at most {p.real_time_factor:g}x'}")

    # -------------------------------------------------------------- commands
    def on_joint_commands(self, msg: JointState) -> None:
        if len(msg.velocity) != len(msg.name):
            self._warn("lengths", f"rejecting a joint command with {len(msg.name)} names and "
                                  f"{len(msg.velocity)} velocities")
            return
        try:
            self.runner.command(dict(zip(msg.name, msg.velocity, strict=False)))
        except (KeyError, ValueError) as exc:
            reason = exc.args[0] if exc.args else str(exc)
            self._warn(type(exc).__name__, f"rejecting a joint command: {reason}")

    # -------------------------------------------------------------- services
    def _pause(self, request: Empty.Request, response: Empty.Response) -> Empty.Response:
        self.runner.pause()
        return response

    def _unpause(self, request: Empty.Request, response: Empty.Response) -> Empty.Response:
        self.runner.unpause()
        self.pacer.restart()
        return response

    def _reset(self, request: Empty.Request, response: Empty.Response) -> Empty.Response:
        at = self.runner.reset_robot()
        for hosted in self.diff_drives:
            if not hosted.spec.body:  # the robot's plugin: its odometry starts over with it
                hosted.reset()
        self.get_logger().info(f"robot reset to its spawn pose at t = {at:.3f} s")
        return response

    def _step(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        if not self.runner.paused:
            response.success, response.message = False, "pause the simulation first (pause_physics)"
            return response
        self._handle(self.runner.step(self.params.step_count))
        response.success = True
        response.message = f"stepped {self.params.step_count} step(s) to t = {self.sim.time_s:.6f} s"
        return response

    # ------------------------------------------------------------ publishing
    def _handle(self, readings: Sequence[Reading]) -> None:
        for r in readings:
            if not isinstance(r, ClockTick | CameraReading):  # a camera publishes later, outside lockstep
                self._published_since_sync = True
            if isinstance(r, ControlTick):
                self._update_controllers()
            elif isinstance(r, PluginTick):
                self.diff_drives[r.index].update(r.stamp_s, self.sim.time_ns)
            elif isinstance(r, ClockTick):
                self._publish_clock()
            elif isinstance(r, JointStatesReading):
                self._publish_joints(r)
            elif isinstance(r, GroundTruthReading):
                self._publish_truth(r)
            elif isinstance(r, LidarReading):
                self._publish_scan(r)
            elif isinstance(r, ImuReadingAt):
                self._publish_imu(r)
            elif isinstance(r, CollisionReading):
                self._publish_collision(r.collision)
            elif isinstance(r, CameraReading):
                self.cameras.submit(r)
            self.published_s = r.stamp_s

    def _wanted(self, event: Event) -> bool:
        if event.kind is EventKind.CAMERA:
            return self.cameras.wanted(event.index)
        publishers = self._listeners.get(event.kind)
        return publishers is None or publishers[event.index].get_subscription_count() > 0

    def _update_controllers(self) -> None:
        now_ns = self.sim.time_ns
        for controller in self.controllers:
            controller.update(now_ns)

    def drive_clocks(self, nodes: Sequence[Node]) -> None:
        """``nodes`` (run in this process beside it: ``--host``) are on the simulation's time from now
        on, set with every /clock (not from /clock: in lockstep their timers and callbacks then see
        the time of the step they run in, on every machine)."""
        for node in nodes:
            if node.get_parameter("use_sim_time").value:  # its own /clock subscription would race the setting
                node.set_parameters([Parameter("use_sim_time", value=False)])
        self._driven = [DrivenClock(node) for node in nodes]
        for clock in self._driven:
            clock.set(self.sim.time_ns)

    def _publish_clock(self, again: bool = False) -> None:
        now_ns = self.sim.time_ns
        if now_ns != self._clock_ns or again:
            self._clock_ns = now_ns
            for clock in self._driven:
                clock.set(now_ns)
            self.clock_pub.publish(self._clock_wire.serialize(stamp_values(now_ns, "clock")))

    def _publish_joints(self, reading: JointStatesReading) -> None:
        if self.broadcasters and not any(b.active for b in self.broadcasters):
            return  # every joint_state_broadcaster deactivated (controller_manager's switch_controller)
        state = reading.state
        self.joint_pub.publish(self._joints_wire.serialize({**stamp_values(_ns(reading.stamp_s)),
                                                       "position": state.positions, "velocity": state.velocities,
                                                       "effort": state.efforts}))

    def _watch_posture(self, reading: GroundTruthReading) -> None:
        """Report a robot that tips over or sinks into the ground (and one upright again) in the log
        and on /diagnostics at once; the status goes out every second of sim time too."""
        truth = reading.truth
        x, y, z, w = truth.orientation_xyzw.tolist()
        changed = self.upright.update(reading.stamp_s, float(truth.position[2]), (x, y, z, w))
        if changed is not None:
            text = f"robot '{self.params.robot_name}' {changed.describe()}"
            # One call site per severity: rclpy raises "Logger severity cannot be changed between
            # calls" when a line logs at another severity than before (this killed the simulator
            # when the robot tipped over after it had been reported upright).
            if changed.upright:
                self.get_logger().info(text)
            else:
                self.get_logger().error(text)
        if changed is not None or reading.stamp_s >= self._next_diagnostics_s:
            self._next_diagnostics_s = reading.stamp_s + DIAGNOSTICS_PERIOD_S
            self.diagnostics_pub.publish(self._diagnostics(reading.stamp_s))

    def _diagnostics(self, stamp_s: float) -> DiagnosticArray:
        now = self.upright.last
        assert now is not None
        status = DiagnosticStatus(
            level=DiagnosticStatus.OK if now.upright else DiagnosticStatus.ERROR,
            name=f"{self.params.robot_name}{UPRIGHT_STATUS}", hardware_id=self.params.robot_name,
            message="upright" if now.upright else now.reason,
            values=[KeyValue(key=key, value=f"{value:.4f}")
                    for key, value in (("roll", now.roll_rad), ("pitch", now.pitch_rad), ("z", now.height_m))])
        array = DiagnosticArray(status=[status])
        set_stamp(array.header.stamp, stamp_s)
        return array

    def _publish_truth(self, reading: GroundTruthReading) -> None:
        self._watch_posture(reading)
        if self.truth_pub.get_subscription_count() == 0:
            return
        truth = reading.truth
        (px, py, pz), (qx, qy, qz, qw) = truth.position.tolist(), truth.orientation_xyzw.tolist()
        (vx, vy, vz), (wx, wy, wz) = truth.linear_velocity.tolist(), truth.angular_velocity.tolist()
        self.truth_pub.publish(self._truth_wire.serialize({
            **stamp_values(_ns(reading.stamp_s)),
            "pose.pose.position.x": px, "pose.pose.position.y": py, "pose.pose.position.z": pz,
            "pose.pose.orientation.x": qx, "pose.pose.orientation.y": qy, "pose.pose.orientation.z": qz,
            "pose.pose.orientation.w": qw, "twist.twist.linear.x": vx, "twist.twist.linear.y": vy,
            "twist.twist.linear.z": vz, "twist.twist.angular.x": wx, "twist.twist.angular.y": wy,
            "twist.twist.angular.z": wz}))

    def _publish_scan(self, reading: LidarReading) -> None:
        self.scan_pubs[reading.index].publish(self._scan_wires[reading.index].serialize(
            {**stamp_values(_ns(reading.scan.stamp_s)), "ranges": reading.scan.ranges}))

    def _publish_collision(self, collision: Collision) -> None:
        msg = PointStamped()
        msg.header.frame_id = "world"
        set_stamp(msg.header.stamp, collision.stamp_s)
        msg.point.x, msg.point.y, msg.point.z = collision.position.tolist()
        self.collision_pub.publish(msg)
        self._warn("collision", f"collision at t = {collision.stamp_s:.2f} s: {collision.robot_part} touched "
                                f"{collision.obstacle} at ({collision.position[0]:.2f}, {collision.position[1]:.2f})")

    def _publish_imu(self, reading: ImuReadingAt) -> None:
        r, msg = reading.sample.reading, self._imu_msgs[reading.index]
        set_stamp(msg.header.stamp, reading.sample.stamp_s)
        o, w, a = msg.orientation, msg.angular_velocity, msg.linear_acceleration
        o.x, o.y, o.z, o.w = r.orientation_xyzw.tolist()
        w.x, w.y, w.z = r.angular_velocity.tolist()
        a.x, a.y, a.z = r.linear_acceleration.tolist()
        self.imu_pubs[reading.index].publish(msg)

    # ------------------------------------------------------------------ loop
    def _next_sync_s(self) -> float | None:
        """Lockstep: the next time to stop at: a participant's timer or a scan (None: free running)."""
        if self.coordinator is None or not self.coordinator.active:
            return None
        times = [self.sim.schedule.next_due_s(Event(EventKind.LIDAR, i)) for i in range(len(self.sim.lidars))]
        wakeup = self.coordinator.next_wakeup_ns()
        candidates = [t for t in times if t is not None] + ([wakeup * 1e-9] if wakeup is not None else [])
        return min(candidates) if candidates else None

    def _at_sync(self, sync_s: float | None) -> bool:
        return sync_s is not None and self.sim.time_s >= sync_s - 0.5 * self.sim.step_s

    def _sync(self, process: Process) -> None:
        """Lockstep at the current time: /clock, then steps until the participants are done (the first
        for what was published since the last sync, if anything, and for the timers due)."""
        assert self.coordinator is not None
        self._publish_clock()
        self.coordinator.sync(process, self.sim.time_ns, readings=self._published_since_sync)
        self._published_since_sync = False

    def run(self, process: Process, until_s: float = math.inf) -> None:
        """Step, publish and serve callbacks until stopped (or until published time reaches ``until_s``)."""
        if self.coordinator is not None:
            self._publish_clock()
            if not self.coordinator.wait_for_start(process, lambda: self._publish_clock(again=True)):
                return
        log_wall, log_sim = time.monotonic(), self.sim.time_s
        last_service = time.monotonic()
        sync_s = self._next_sync_s()
        while process.running() and self.published_s < until_s:
            if self.runner.paused:
                process.spin_once(0.05)
                self.pacer.restart()
                continue
            ahead_s = self.pacer.ahead_s(self.sim.time_s)
            if ahead_s > 0:
                process.spin_once(ahead_s)
                last_service = time.monotonic()
                continue
            self.sim.schedule.stop_at_s = sync_s
            readings = self.runner.advance(wanted=self._wanted)
            if readings:
                self._handle(readings)
            if self._at_sync(sync_s):
                self._sync(process)
                sync_s = self._next_sync_s()
                last_service = time.monotonic()
            elif sync_s is None and self.coordinator is not None and self.coordinator.active:
                sync_s = self._next_sync_s()  # someone joined while time ran freely
            now = time.monotonic()
            if now - last_service >= SERVICE_PERIOD_S:
                process.spin_once(0.0)
                self._sync_viewer()
                last_service = now
            if now - log_wall >= RTF_LOG_PERIOD_S:  # also in lockstep, whose syncs serve callbacks
                self._log_speed(now - log_wall, self.sim.time_s - log_sim)
                log_wall, log_sim = now, self.sim.time_s

    def _log_speed(self, wall_s: float, sim_s: float) -> None:
        rtf = self.params.real_time_factor
        target = ("as fast as possible" if rtf == 0 else f"target {rtf:g}x")
        extra = ""
        if self.coordinator is not None:
            c = self.coordinator
            extra = (f"; lockstep: {c.steps} steps, {c.rounds} rounds with {len(c.barrier.members)} participant(s)"
                     + (f", a step repeated {c.repeats} time(s)" if c.repeats else ""))
        self.get_logger().info(f"real-time factor {sim_s / wall_s:.1f}x ({target}), t = {self.sim.time_s:.1f} s"
                               + extra)


def _spin(nodes: Sequence[Node], process: Process) -> int | None:
    simulator = nodes[0]
    assert isinstance(simulator, Simulator)
    simulator.drive_clocks(nodes[1:])
    try:
        simulator.run(process)
    except LockstepError as exc:
        simulator.get_logger().error(str(exc))
        return 1
    return None


def main(args: list[str] | None = None) -> int:
    """``simulator [--host NODE ...] --ros-args ...``: ``--host`` runs a node registered in
    :data:`pppbot_sim.hosting.NODES` (``robot_state_publisher``, ``twist_mux``) in this process, on
    the simulator's clock and step port: its topics in-process, as a component container runs
    components (give its parameters and remappings scoped to it: ``-p twist_mux:...``)."""
    parser = argparse.ArgumentParser(prog="simulator", description=__doc__.split("\n\n")[0])
    parser.add_argument("--host", action="append", default=[], metavar="NODE",
                        help="run this node in the simulator's process (repeatable)")
    options = parser.parse_args(remove_ros_args(args if args is not None else sys.argv)[1:])
    try:
        hosted = node_factories(options.host)
    except SpawnError as exc:
        parser.error(str(exc))
    made: list[Simulator] = []

    def simulator(port: StepPort) -> Simulator:
        made.append(Simulator(port=port))
        return made[0]

    def beside(factory: Callable[..., Node]) -> Callable[..., Node]:
        return lambda port: factory(port=made[0].port)  # the simulator's port (its lockstep's, when on)
    return run_nodes([simulator, *(beside(f) for f in hosted)], "simulator", args, loop=_spin, lockstep=False,
                     fatal=(ParameterError, DescriptionError, WorldError, SpawnError, LockstepError))


if __name__ == "__main__":
    sys.exit(main())
