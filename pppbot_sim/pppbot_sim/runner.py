"""Run a :class:`Simulation` from event to event and hand out what to publish.

The runner advances from event to event and turns each event into a reading (a
snapshot, safe to use after the state moves on): a typed record per kind, so the node
dispatches on the type. Pacing against the wall clock (``real_time_factor``) and lockstep
are the node's: :meth:`PhysicsRunner.advance` only steps. Everything runs in the
caller's thread: on a two-core machine the second core is busy with DDS and the
subscribers, and a separate physics thread only added GIL hand-offs (measured slower).
"""
from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from pppbot_sim.errors import SimulationDiverged
from pppbot_sim.render import RenderState
from pppbot_sim.simulation import (
    Collision,
    Event,
    EventKind,
    GroundTruth,
    ImuSample,
    LidarScan,
    Simulation,
    WheelState,
)

#: Physics never runs more than this many steps without returning to the caller.
MAX_STEPS_PER_ADVANCE = 1000


@dataclass(frozen=True)
class ClockTick:
    stamp_s: float


@dataclass(frozen=True)
class ControlTick:
    """A hosted controller's update is due (controller_manager's ``update_rate``)."""

    stamp_s: float


@dataclass(frozen=True)
class PluginTick:
    """A Gazebo DiffDrive plugin's update is due (its index in ``Simulation.diff_drives``)."""

    stamp_s: float
    index: int


@dataclass(frozen=True)
class JointStatesReading:
    stamp_s: float
    state: WheelState


@dataclass(frozen=True)
class GroundTruthReading:
    stamp_s: float
    truth: GroundTruth


@dataclass(frozen=True)
class LidarReading:
    stamp_s: float
    index: int
    scan: LidarScan


@dataclass(frozen=True)
class ImuReadingAt:
    stamp_s: float
    index: int
    sample: ImuSample


@dataclass(frozen=True)
class CameraReading:
    """A camera is due: the positions its frame is rendered from (elsewhere: pppbot_sim.camera_worker)."""

    stamp_s: float
    index: int
    state: RenderState


@dataclass(frozen=True)
class CollisionReading:
    stamp_s: float
    collision: Collision


Reading = (ClockTick | ControlTick | PluginTick | JointStatesReading | GroundTruthReading | LidarReading | ImuReadingAt
           | CameraReading | CollisionReading)

#: Readings at one instant go out in this order: controllers first (their odometry at a scan's
#: time is then out before the scan), then the rest.
_ORDER = {EventKind.CONTROL: 0, EventKind.PLUGIN: 0, EventKind.CLOCK: 1, EventKind.JOINT_STATES: 2,
          EventKind.GROUND_TRUTH: 3, EventKind.IMU: 4, EventKind.LIDAR: 5, EventKind.CAMERA: 6}


class PhysicsRunner:
    def __init__(self, sim: Simulation, command_timeout_s: float = 0.5, paused: bool = False,
                 log: Callable[[str], None] = print) -> None:
        self.sim = sim
        self.command_timeout_s = command_timeout_s
        self.log = log
        self.paused = paused
        self._last_command_s: float | None = None

    def pause(self) -> None:
        self.paused = True

    def unpause(self) -> None:
        self.paused = False

    def command(self, velocities: Mapping[str, float]) -> None:
        """Wheel velocity targets (rad/s); raises KeyError/ValueError as Simulation does,
        and ValueError for an empty command (it would keep the last one alive)."""
        if not velocities:
            raise ValueError("empty command (no joint names)")
        self.sim.set_wheel_velocities(velocities)
        self._last_command_s = self.sim.time_s

    def reset_robot(self) -> float:
        """Robot back to its spawn pose; returns the sim time of the reset."""
        self.sim.reset_robot()
        self._last_command_s = None
        return self.sim.time_s

    def step(self, steps: int) -> list[Reading]:
        """Advance ``steps`` physics steps now; return the readings due on the way."""
        readings: list[Reading] = []
        target = self.sim.time_s + steps * self.sim.step_s
        while self.sim.time_s < target - 0.5 * self.sim.step_s:
            readings += self.advance(int(round((target - self.sim.time_s) / self.sim.step_s)))
        return readings

    def advance(self, max_steps: int = MAX_STEPS_PER_ADVANCE,
                wanted: Callable[[Event], bool] | None = None) -> list[Reading]:
        """Step to the next event(s) (or the schedule's stop); their readings, except those ``wanted``
        refuses (nobody would use them: they are not even computed). A diverged state is reset and
        logged."""
        sim = self.sim
        try:
            events = sim.advance(max_steps)
        except SimulationDiverged as exc:
            self.log(f"{exc}; resetting the world and the robot to the spawn pose")
            sim.reset_all()
            self._last_command_s = None
            return []
        if (self._last_command_s is not None and self.command_timeout_s > 0
                and sim.time_s - self._last_command_s > self.command_timeout_s):
            sim.stop_wheels()
            self._last_command_s = None
        if wanted is not None:
            events = [e for e in events if wanted(e)]
        readings = [self.reading(event) for event in sorted(events, key=lambda e: (_ORDER[e.kind], e.index))]
        readings += [CollisionReading(c.stamp_s, c) for c in sim.take_collisions()]
        return readings

    def reading(self, event: Event) -> Reading:
        """The reading of ``event`` now."""
        sim, now, i = self.sim, self.sim.time_s, event.index
        make: dict[EventKind, Callable[[], Reading]] = {
            EventKind.LIDAR: lambda: LidarReading(now, i, sim.lidar_scan(i)),
            EventKind.IMU: lambda: ImuReadingAt(now, i, sim.imu_sample(i)),
            EventKind.JOINT_STATES: lambda: JointStatesReading(now, sim.wheel_state()),
            EventKind.GROUND_TRUTH: lambda: GroundTruthReading(now, sim.ground_truth()),
            EventKind.CONTROL: lambda: ControlTick(now),
            EventKind.PLUGIN: lambda: PluginTick(now, i),
            EventKind.CAMERA: lambda: CameraReading(now, i, sim.render_state()),
        }
        return make.get(event.kind, lambda: ClockTick(now))()


class Pacer:
    """Keeps sim time at ``real_time_factor`` times wall time (0: as fast as possible); restarts
    after a pause or when far behind, rather than sprinting to catch up."""

    #: Further behind than this (wall s), the pace restarts from now.
    MAX_LAG_S = 1.0

    def __init__(self, real_time_factor: float) -> None:
        self.real_time_factor = real_time_factor
        self._origin: tuple[float, float] | None = None

    def restart(self) -> None:
        self._origin = None

    def ahead_s(self, sim_s: float) -> float:
        """Wall seconds to wait before simulating past ``sim_s`` (≤ 0: go on)."""
        rtf = self.real_time_factor
        if rtf <= 0:
            return 0.0
        now = time.monotonic()
        if self._origin is None:
            self._origin = (now, sim_s)
        wall0, sim0 = self._origin
        ahead = wall0 + (sim_s - sim0) / rtf - now
        if ahead < -self.MAX_LAG_S:  # a slow machine, a debugger: do not sprint to catch up
            self._origin = (now, sim_s)
            return 0.0
        return ahead
