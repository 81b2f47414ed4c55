"""The simulation: a MuJoCo world with one robot, stepped in batches between events.

No ROS here. The node asks :meth:`Simulation.advance` to run physics up to the
next due event (a sensor reading or a periodic publication) and gets back what
became due; between events MuJoCo steps in C (``mj_step`` with ``nstep``).
"""
from __future__ import annotations

import dataclasses
import enum
import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from pppbot_common.se2 import yaw_from_quaternion
from pppbot_description.urdf_model import RobotModel, Sensor
from pppbot_sim.camera_model import add_cameras, bind_cameras, camera_tags
from pppbot_sim.contacts import anisotropic_pairs
from pppbot_sim.errors import PluginError, SimulationDiverged, SpawnError, WorldError
from pppbot_sim.gz_plugins import DiffDriveSpec, Plugins, robot_plugins, world_plugins
from pppbot_sim.mj_build import (
    ROBOT_GROUP,
    RobotHandles,
    SpawnPose,
    WheelDrive,
    add_robot,
    add_velocity_servos,
    apply_friction_rule,
    depth_below,
    mjcf_world_spec,
    robot_servos,
    rpy_quat_wxyz,
    surface_below,
    world_spec,
)
from pppbot_sim.render import RenderState
from pppbot_sim.sdf_joints import JointKind
from pppbot_sim.sdf_model import World
from pppbot_sim.sdf_world import read_sdf_world
from pppbot_sim.sensors import Imu, ImuReading, ImuSpec, Lidar, LidarSpec, finalize_ranges, sensor_specs
from pppbot_sim.wheel_slip import SlipModel, WheelSlip
from pppbot_sim.worlds import model_paths

_log = logging.getLogger("pppbot_sim.mujoco")


def route_mujoco_warnings() -> None:
    """Send MuJoCo's warnings to Python logging instead of MUJOCO_LOG.TXT in the working directory."""
    if mujoco.get_mju_user_warning() is None:
        mujoco.set_mju_user_warning(lambda text: _log.warning("MuJoCo: %s", text))


#: Beyond these the state is garbage, not physics (m and m/s or rad/s).
DIVERGED_POSITION_M = 1e5
DIVERGED_VELOCITY = 1e4
#: A robot-obstacle contact that stops for less than this (sim s) is still the same collision.
COLLISION_GAP_S = 0.5


class EventKind(enum.Enum):
    """What a scheduled event is for."""

    CLOCK = "clock"
    JOINT_STATES = "joint_states"
    GROUND_TRUTH = "ground_truth"
    CONTROL = "control"  # a controller hosted in the simulator's process (gz_ros2_control's update)
    PLUGIN = "plugin"  # a Gazebo DiffDrive plugin's update (its index in Simulation.diff_drives)
    LIDAR = "lidar"
    IMU = "imu"
    CAMERA = "camera"


@dataclass(frozen=True)
class Event:
    """A scheduled event: its kind and, for sensors, the sensor's index."""

    kind: EventKind
    index: int = 0

    def __str__(self) -> str:
        indexed = (EventKind.LIDAR, EventKind.IMU, EventKind.PLUGIN, EventKind.CAMERA)
        return f"{self.kind.value}{self.index if self.kind in indexed else ''}"


@dataclass
class Periodic:
    """An event every ``period_s`` of simulated time."""

    event: Event
    period_s: float
    next_due_s: float = 0.0

    def take_if_due(self, time_s: float, dt: float) -> bool:
        if time_s + 0.5 * dt < self.next_due_s:
            return False
        # Missed periods (a long pause, a reset) are skipped, not replayed.
        self.next_due_s += self.period_s * max(1, math.floor((time_s - self.next_due_s) / self.period_s) + 1)
        return True


@dataclass
class Schedule:
    events: list[Periodic] = field(default_factory=list)
    #: A one-off stop (a lockstep sync time, sim s): stepping never runs past it.
    stop_at_s: float | None = None

    def add(self, event: Event, rate_hz: float, start_s: float = 0.0) -> None:
        if not (math.isfinite(rate_hz) and rate_hz > 0):
            raise ValueError(f"rate of '{event}' must be a positive number, not {rate_hz}")
        self.events.append(Periodic(event, 1.0 / rate_hz, start_s))

    def next_due_s(self, event: Event) -> float | None:
        """When ``event`` is next due (None: not scheduled)."""
        due = [e.next_due_s for e in self.events if e.event == event]
        return min(due) if due else None

    def steps_to_next(self, time_s: float, dt: float, max_steps: int) -> int:
        """Whole steps until the earliest event or the stop (at least 1, at most ``max_steps``).

        Counted in whole nanoseconds, as sim time goes out (/clock, lockstep): MuJoCo's time is a
        sum of steps whose rounding error grows with time, and a stop counted in float steps
        overshot by a step when that error fell the wrong way. A lockstep sync at 23.252 s
        instead of 23.250 s put the timers restarted there (the controller's, at each new path)
        2 ms off every other's, and a navigation made a fifth more sync times.
        """
        deadlines = [e.next_due_s for e in self.events]
        if self.stop_at_s is not None:
            deadlines.append(self.stop_at_s)
        if not deadlines:
            return max_steps
        gap_ns = round(min(deadlines) * 1e9) - round(time_s * 1e9)
        step_ns = max(1, round(dt * 1e9))
        return int(min(max_steps, max(1, -(-gap_ns // step_ns))))

    def due(self, time_s: float, dt: float) -> list[Event]:
        return [e.event for e in self.events if e.take_if_due(time_s, dt)]


@dataclass(frozen=True)
class GroundTruth:
    """The robot root's true state: pose in the world, velocities in its own frame (REP-105 odom)."""

    position: np.ndarray
    orientation_xyzw: np.ndarray
    linear_velocity: np.ndarray
    angular_velocity: np.ndarray

    @property
    def yaw(self) -> float:
        x, y, z, w = self.orientation_xyzw
        return yaw_from_quaternion(x, y, z, w)


@dataclass(frozen=True)
class LidarScan:
    spec: LidarSpec
    stamp_s: float
    ranges: np.ndarray


@dataclass(frozen=True)
class ImuSample:
    spec: ImuSpec
    stamp_s: float
    reading: ImuReading


@dataclass(frozen=True)
class Collision:
    """The robot started touching something other than the ground (one per contact episode)."""

    stamp_s: float
    position: np.ndarray  # world frame (m)
    robot_part: str
    obstacle: str


@dataclass(frozen=True)
class WheelState:
    names: list[str]
    positions: np.ndarray
    velocities: np.ndarray
    efforts: np.ndarray


def load_world(path: Path, model_paths: list[Path]) -> tuple[mujoco.MjSpec, World | None]:
    """A MuJoCo spec of a world file: SDF (``.sdf``, ``.world``) or MJCF (``.xml``, ``.mjcf``).

    Raises:
        WorldError: unknown extension or a bad file.
    """
    suffix = path.suffix.lower()
    if suffix in (".sdf", ".world"):
        world = read_sdf_world(path, model_paths)
        return world_spec(world), world
    if suffix in (".xml", ".mjcf"):
        if not path.is_file():
            raise WorldError(f"{path}: world file not found")
        return mjcf_world_spec(path), None
    raise WorldError(f"{path}: unknown world format '{suffix}' (use .sdf, .world or MJCF .xml)")


def check_world(path: Path) -> None:
    """Load and build the world at ``path`` as the simulator will (a bringup calls this before it
    starts anything).

    Raises:
        WorldError: the file cannot be read or built; the message names the file, line and element.
    """
    spec, world = load_world(path, model_paths(path))
    if world is not None:
        _world_servos(world, world_plugins(world.plugins).diff_drives)
    try:
        spec.compile()
    except ValueError as exc:
        raise WorldError(f"{path}: MuJoCo cannot build the world: {exc}") from exc


class Simulation:
    """A world, one robot, its wheel servos and sensors."""

    def __init__(self, spec: mujoco.MjSpec, robot: RobotModel, spawn: SpawnPose = SpawnPose(),
                 name: str = "ppp_bot", seed: int = 0, drive: WheelDrive = WheelDrive(),
                 slip: SlipModel = SlipModel(), world: World | None = None) -> None:
        """``spec``: the world (:func:`load_world`), ``world`` its SDF data when it has one (its
        models' joints and plugins).

        Raises:
            SpawnError: the robot cannot be built into the world.
            PluginError: a DiffDrive plugin that cannot work as written.
        """
        route_mujoco_warnings()
        self.spawn = spawn
        world_servos = self._add_robot_and_drives(spec, robot, name, drive, world)
        world_actuators = add_velocity_servos(spec, world_servos, drive)
        apply_friction_rule(spec)
        lidar_specs, imu_specs, others = sensor_specs(list(robot.sensors))
        cameras, self.unsimulated_sensors = camera_tags(others)
        sensor_sites = {s.name: self._add_sensor_site(spec, name, s.name, s.link, s.pose) for s in lidar_specs}
        sensor_sites.update({s.name: self._add_sensor_site(spec, name, s.name, s.link, s.pose) for s in imu_specs})
        for imu_spec in imu_specs:
            Imu.add_to(spec, sensor_sites[imu_spec.name], f"{name}/{imu_spec.name}/")
        placed_cameras, camera_notes = add_cameras(spec, robot, cameras, name,
                                                   world.name if world is not None else spec.modelname or "default")
        self.warnings += camera_notes
        try:
            self.model = spec.compile()
        except ValueError as exc:
            raise SpawnError(f"MuJoCo could not compile the world with the robot: {exc}") from exc
        self.data = mujoco.MjData(self.model)
        # One generator per sensor: a reading skipped (nobody listens) never shifts another's noise.
        self.lidar_rngs = [np.random.default_rng((seed, 2, i)) for i in range(len(lidar_specs))]
        self.imu_rngs = [np.random.default_rng((seed, 3, i)) for i in range(len(imu_specs))]
        self.lidars = [Lidar(s, self.model, sensor_sites[s.name]) for s in lidar_specs]
        self.imus = [Imu(s, self.model, f"{name}/{s.name}/") for s in imu_specs]
        #: the robot's cameras (rendered outside the physics loop: pppbot_sim.camera_worker)
        self.cameras = bind_cameras(self.model, placed_cameras, self.handles.sites)
        self.schedule = Schedule()
        for i, lidar in enumerate(self.lidars):
            self.schedule.add(Event(EventKind.LIDAR, i), lidar.spec.rate_hz)
        for i, imu in enumerate(self.imus):
            self.schedule.add(Event(EventKind.IMU, i), imu.spec.rate_hz)
        for i, diff_drive in enumerate(self.diff_drives):
            self.schedule.add(Event(EventKind.PLUGIN, i), diff_drive.update_rate_hz)
        # Due whether or not anyone renders them: physics steps the same with cameras on or off.
        for i, camera in enumerate(self.cameras):
            self.schedule.add(Event(EventKind.CAMERA, i), camera.spec.rate_hz)
        prefix = f"{name}/"
        self._root_body = self.model.body(self.handles.root_body).id
        free = self.model.joint(self.handles.free_joint)
        self._free_qpos = int(free.qposadr[0])
        self._free_qvel = int(free.dofadr[0])
        self.joint_names = list(self.handles.moving_joints)
        joints = [self.model.joint(f"{prefix}{j}") for j in self.joint_names]
        self._joint_qpos = np.array([int(j.qposadr[0]) for j in joints], dtype=int)
        self._joint_qvel = np.array([int(j.dofadr[0]) for j in joints], dtype=int)
        self._actuator = {j: self.model.actuator(a).id for j, a in self.handles.actuators.items()}
        self._velocity_limits = dict(self.handles.velocity_limits)
        for joint, actuator in world_actuators.items():
            self._actuator[joint] = self.model.actuator(actuator).id
            self._velocity_limits[joint] = world_servos[joint][:2]
        self._world_joint_qpos = {j: int(self.model.joint(j).qposadr[0]) for j in world_actuators}
        self._effort_index = np.array([self._actuator.get(j, -1) for j in self.joint_names], dtype=int)
        wheels = np.array([j in self.handles.wheel_joints for j in self.joint_names], dtype=bool)
        # Its own generator: slip does not change the sensor noise of a seed.
        self.slip = WheelSlip(slip, wheels, np.random.default_rng((seed, 1)))
        robot_geoms = self.model.geom_group == ROBOT_GROUP
        ground = np.isin(self.model.geom_type, (mujoco.mjtGeom.mjGEOM_PLANE, mujoco.mjtGeom.mjGEOM_HFIELD))
        self._robot_geom = robot_geoms
        self._obstacle_geom = ~robot_geoms & ~ground
        self._last_contact_s = -math.inf  # last time the robot touched an obstacle (sim s)
        self.collisions: list[Collision] = []
        # Views into MjData's buffers (each attribute access would build a new one).
        self._qpos, self._qvel, self._ctrl = self.data.qpos, self.data.qvel, self.data.ctrl
        if world is not None:
            self._set_joint_positions(world.joint_positions)
        if math.isnan(spawn.z):
            self._put_down()
        mujoco.mj_forward(self.model, self.data)
        self._spawn_qpos = self._qpos.copy()
        self._resume_at_s = 0.0
        self._wheel_state: tuple[float, WheelState] | None = None  # the last reading and its time

    def _put_down(self) -> None:
        """Spawned without a height: the robot rests on whatever lies beneath its (x, y), its lowest
        collision shape touching it."""
        mujoco.mj_kinematics(self.model, self.data)
        root = self.model.body(self.handles.root_body).id
        depth = depth_below(self.model, self.data, root)
        surface = surface_below(self.model, self.data, self.spawn.x, self.spawn.y)
        z = (0.0 if surface is None else surface) + depth
        self._qpos[self._free_qpos + 2] = z
        self.spawn = dataclasses.replace(self.spawn, z=z)

    def _add_robot_and_drives(self, spec: mujoco.MjSpec, robot: RobotModel, name: str, drive: WheelDrive,
                              world: World | None) -> dict[str, tuple[float, float, float]]:
        """Add the robot; find the DiffDrive plugins and what is not simulated; return the world
        joints a plugin drives, with their limits."""
        on_robot = robot_plugins(robot.plugins, robot.name, robot.root)
        on_world = world_plugins(world.plugins) if world is not None else Plugins([], [])
        #: the Gazebo DiffDrive plugins of the robot and the world's models, in that order
        self.diff_drives: list[DiffDriveSpec] = [*on_robot.diff_drives, *on_world.diff_drives]
        torques = {joint: d.max_wheel_torque for d in on_robot.diff_drives for joint in d.joints}
        self.handles: RobotHandles = add_robot(spec, robot, self.spawn, name, drive, robot_servos(robot, torques))
        #: what of the robot's description and the world is not simulated, one line each
        self.warnings = [*on_robot.warnings, *on_world.warnings, *self.handles.warnings]
        if world is None:
            return {}
        shapes = [*world.static_shapes, *(s for body in world.bodies for s in body.shapes)]
        self.warnings += anisotropic_pairs([(f"link '{k}'", v) for k, v in self.handles.surfaces.items()],
                                           [(f"'{s.name}'", s.surface) for s in shapes])
        return _world_servos(world, on_world.diff_drives)

    def _set_joint_positions(self, positions: Mapping[str, Mapping[int, float]]) -> None:
        """World joints' starting positions (a saved world's ``<state>``): ``{joint: {axis: value}}``."""
        for name, axes in positions.items():
            for axis, value in axes.items():
                joint = name if axis == 0 else f"{name}::axis2"
                try:
                    found = self.model.joint(joint)
                except KeyError:
                    continue  # a fixed or ball joint: no angle to set
                if int(found.type[0]) in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)):
                    self._qpos[int(found.qposadr[0])] = value

    @staticmethod
    def _add_sensor_site(spec: mujoco.MjSpec, robot: str, sensor: str, link: str,
                         pose: tuple[float, float, float, float, float, float]) -> str:
        """A site at the sensor tag's <pose> in its link's frame; returns its name."""
        body = spec.body(f"{robot}/{link}")
        if body is None:
            raise SpawnError(f"sensor '{sensor}' is on link '{link}', which the robot does not have")
        site = f"{robot}/sensor/{sensor}"
        x, y, z, roll, pitch, yaw = pose
        body.add_site(name=site, pos=[x, y, z], quat=rpy_quat_wxyz(roll, pitch, yaw))
        return site

    # --------------------------------------------------------------- stepping
    @property
    def time_s(self) -> float:
        return float(self.data.time)

    @property
    def time_ns(self) -> int:
        """Sim time in integer nanoseconds (what /clock and lockstep carry)."""
        return int(round(float(self.data.time) * 1e9))

    @property
    def step_s(self) -> float:
        return float(self.model.opt.timestep)

    def advance(self, max_steps: int) -> list[Event]:
        """Step up to the next due event (or ``max_steps``); return the events now due.

        Raises:
            SimulationDiverged: the state became non-finite or absurd.
        """
        steps = self.schedule.steps_to_next(self.time_s, self.step_s, max_steps)
        end_s = self.time_s + steps * self.step_s
        warnings = self._bad_state_warnings()
        mujoco.mj_step(self.model, self.data, nstep=steps)
        # MuJoCo resets the data itself (time included) on a bad qpos/qvel/qacc and
        # counts a warning: that is a divergence too, and time must not go back.
        if self._bad_state_warnings() != warnings or self.diverged():
            self._resume_at_s = end_s
            raise SimulationDiverged(f"simulation diverged at t = {end_s:.3f} s")
        self._track_collisions()
        return self.schedule.due(self.time_s, self.step_s)

    def _track_collisions(self) -> None:
        """Append a :class:`Collision` when the robot starts touching anything but the ground.

        One crash is one collision, however many bodies and walls it involves at once
        (a corner is two walls); contacts of a robot pushing on a wall flicker from step
        to step, so an episode ends only after :data:`COLLISION_GAP_S` without contact.
        """
        count = int(self.data.ncon)
        if not count:
            return
        geoms = self.data.contact.geom[:count]
        g1, g2 = geoms[:, 0], geoms[:, 1]
        robot_first = self._robot_geom[g1] & self._obstacle_geom[g2]
        hits = np.flatnonzero(robot_first | (self._robot_geom[g2] & self._obstacle_geom[g1]))
        if not len(hits):
            return
        now = self.time_s
        if now - self._last_contact_s > COLLISION_GAP_S:
            i = int(hits[0])
            robot, obstacle = (g1[i], g2[i]) if robot_first[i] else (g2[i], g1[i])
            self.collisions.append(Collision(now, self.data.contact.pos[i].copy(),
                                             self.model.body(int(self.model.geom_bodyid[robot])).name,
                                             self._geom_label(int(obstacle))))
        self._last_contact_s = now

    def _geom_label(self, geom: int) -> str:
        name = self.model.geom(geom).name
        body = self.model.body(int(self.model.geom_bodyid[geom])).name
        return name or f"{body or 'world'} geom {geom}"

    def take_collisions(self) -> list[Collision]:
        """Collisions since the last call."""
        taken, self.collisions = self.collisions, []
        return taken

    def _bad_state_warnings(self) -> int:
        w = self.data.warning
        return int(w[mujoco.mjtWarning.mjWARN_BADQPOS].number + w[mujoco.mjtWarning.mjWARN_BADQVEL].number
                   + w[mujoco.mjtWarning.mjWARN_BADQACC].number)

    def diverged(self) -> bool:
        """Non-finite or absurd state (one dot product each: NaN and inf propagate into it)."""
        speed2 = float(self._qvel @ self._qvel)
        x, y, z = self._qpos[self._free_qpos:self._free_qpos + 3]
        return not (speed2 <= DIVERGED_VELOCITY ** 2 and x * x + y * y + z * z <= DIVERGED_POSITION_M ** 2
                    and math.isfinite(float(self._qpos @ self._qpos)))

    # ------------------------------------------------------------------ wheels
    def set_wheel_velocities(self, commands: Mapping[str, float]) -> None:
        """Velocity targets (rad/s) by joint name, clamped to each joint's limits.

        Raises:
            KeyError: a name that is not a driven joint (nothing is applied).
            ValueError: a non-finite value (nothing is applied).
        """
        unknown = [n for n in commands if n not in self._actuator]
        if unknown:
            raise KeyError(f"not a driven joint: {', '.join(unknown)} (driven: {', '.join(self._actuator)})")
        bad = [f"{n}={v}" for n, v in commands.items() if not math.isfinite(v)]
        if bad:
            raise ValueError(f"non-finite velocity command: {', '.join(bad)}")
        for name, value in commands.items():
            low, high = self._velocity_limits[name]
            self._ctrl[self._actuator[name]] = min(max(value, low), high)

    def stop_wheels(self) -> None:
        for actuator in self._actuator.values():
            self._ctrl[actuator] = 0.0

    def wheel_state(self) -> WheelState:
        """The wheels as their encoders report them now (one reading per instant: asked twice at one
        time, the same reading)."""
        if self._wheel_state is not None and self._wheel_state[0] == self.data.time:
            return self._wheel_state[1]
        efforts = np.where(self._effort_index >= 0, self.data.actuator_force[self._effort_index], 0.0)
        # Fancy indexing copies: the state is a snapshot. Slip changes what the encoders report.
        positions, velocities = self.slip.apply(self.time_s, self._qpos[self._joint_qpos],
                                                self._qvel[self._joint_qvel])
        state = WheelState(list(self.joint_names), positions, velocities, efforts)
        self._wheel_state = (float(self.data.time), state)
        return state

    def joint_positions(self, names: Sequence[str]) -> list[float]:
        """Positions (rad or m) of driven joints: the robot's wheels as their encoders report them
        (:meth:`wheel_state`), a world model's joints (``model::joint``) as they are.

        Raises:
            KeyError: a name that is not a driven joint.
        """
        state: WheelState | None = None
        positions = []
        for name in names:
            if name in self._world_joint_qpos:
                positions.append(float(self._qpos[self._world_joint_qpos[name]]))
                continue
            if name not in self._actuator:
                raise KeyError(f"not a driven joint: {name}")
            state = state or self.wheel_state()
            positions.append(float(state.positions[state.names.index(name)]))
        return positions

    def planar_state(self, body: str = "") -> tuple[float, float, float, float, float]:
        """(x, y, yaw, forward speed, yaw rate) of a world body (``model::link``) in the world, or
        of the robot's root with ``body`` empty (m, rad, m/s, rad/s)."""
        if not body:
            truth = self.ground_truth()
            return (float(truth.position[0]), float(truth.position[1]), truth.yaw,
                    float(truth.linear_velocity[0]), float(truth.angular_velocity[2]))
        index = self.model.body(body).id
        rotation = self.data.xmat[index].reshape(3, 3)
        velocity = np.zeros(6)  # angular, then linear, in the world frame
        mujoco.mj_objectVelocity(self.model, self.data, mujoco.mjtObj.mjOBJ_BODY, index, velocity, 0)
        x, y = self.data.xpos[index][:2]
        return (float(x), float(y), math.atan2(rotation[1, 0], rotation[0, 0]),
                float((rotation.T @ velocity[3:])[0]), float(velocity[2]))

    # --------------------------------------------------------------- readings
    def ground_truth(self) -> GroundTruth:
        q = self._qpos[self._free_qpos:self._free_qpos + 7]
        w, x, y, z = q[3:7]
        # A free joint's qvel is (world linear velocity, body angular velocity).
        v = self._qvel[self._free_qvel:self._free_qvel + 6]
        rotation = self.data.xmat[self._root_body].reshape(3, 3)
        return GroundTruth(q[:3].copy(), np.array([x, y, z, w]), rotation.T @ v[:3], v[3:6].copy())

    def lidar_scan(self, index: int) -> LidarScan:
        lidar = self.lidars[index]
        return LidarScan(lidar.spec, self.time_s, finalize_ranges(lidar.scan(self.data), lidar.spec,
                                                                  self.lidar_rngs[index]))

    def imu_sample(self, index: int) -> ImuSample:
        imu = self.imus[index]
        return ImuSample(imu.spec, self.time_s, imu.read(self.data, self.imu_rngs[index]))

    def render_state(self) -> RenderState:
        """A copy of the positions, all a camera frame is rendered from."""
        return RenderState.of(self.data)

    # ------------------------------------------------------------------- reset
    def reset_robot(self) -> None:
        """Robot back to its spawn pose at rest, wheels stopped; time goes on."""
        free = slice(self._free_qpos, self._free_qpos + 7)
        self.data.qpos[free] = self._spawn_qpos[free]
        self.data.qpos[self._joint_qpos] = self._spawn_qpos[self._joint_qpos]
        self.data.qvel[self._free_qvel:self._free_qvel + 6] = 0.0
        self.data.qvel[self._joint_qvel] = 0.0
        self.data.qacc_warmstart[:] = 0.0
        self.stop_wheels()
        self.slip.reset()
        self._wheel_state = None
        self._last_contact_s = -math.inf
        mujoco.mj_forward(self.model, self.data)

    def reset_all(self) -> None:
        """After divergence: the whole world back to its initial state; time goes on."""
        time_s = max(self.time_s, self._resume_at_s)
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[:] = self._spawn_qpos
        self.data.time = time_s
        self.slip.reset()
        self._wheel_state = None
        self._last_contact_s = -math.inf
        mujoco.mj_forward(self.model, self.data)


def _world_servos(world: World, diff_drives: Sequence[DiffDriveSpec]) -> dict[str, tuple[float, float, float]]:
    """The world joints the DiffDrive plugins drive: (min, max) velocity and effort from each joint's
    ``<limit>``.

    Raises:
        PluginError: a wheel that is not a revolute or continuous joint of the world.
    """
    joints = {joint.name: joint for joint in world.joints}
    servos = {}
    for diff_drive in diff_drives:
        for name in diff_drive.joints:
            joint = joints.get(name)
            if joint is None or joint.kind not in (JointKind.REVOLUTE, JointKind.CONTINUOUS):
                raise PluginError(f"{diff_drive.where}: the DiffDrive plugin's wheel '{name}' is not a revolute or "
                                  f"continuous joint of model '{diff_drive.model}'")
            axis = joint.axes[0]
            servos[name] = (-axis.velocity, axis.velocity, axis.effort)
    return servos


def unsimulated_summary(sensors: list[Sensor]) -> str:
    return ", ".join(f"{s.name} ({s.type})" for s in sensors)
