"""Run a :class:`Simulation` against the wall clock and hand out what to publish.

The runner advances from event to event, turns each event into a
:class:`Reading` (a snapshot, safe to use after the state moves on), hands the
batch to the caller, paces to ``real_time_factor`` and gives the caller idle
time for its own work (a ROS node serves its callbacks then). Everything runs in
the caller's thread: on a two-core machine the second core is busy with DDS and
the subscribers, and a separate physics thread only added GIL hand-offs
(measured slower).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Callable, Mapping

from pppbot_sim.errors import SimulationDiverged
from pppbot_sim.simulation import Simulation

#: Physics never runs more than this many steps without returning to the caller.
MAX_STEPS_PER_ADVANCE = 1000


@dataclass(frozen=True)
class Reading:
    """One thing to publish: ``kind`` is clock, joint_states, ground_truth, lidar, imu or collision."""

    kind: str
    stamp_s: float
    value: Any = None
    index: int = 0


class PhysicsRunner:
    def __init__(self, sim: Simulation, real_time_factor: float = 1.0, command_timeout_s: float = 0.5,
                 paused: bool = False, log: Callable[[str], None] = print) -> None:
        self.sim = sim
        self.real_time_factor = real_time_factor
        self.command_timeout_s = command_timeout_s
        self.log = log
        self.paused = paused
        self._pace_reset = True
        self._last_command_s: float | None = None

    def pause(self) -> None:
        self.paused = True

    def unpause(self) -> None:
        self._pace_reset = True
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

    def advance(self, max_steps: int = MAX_STEPS_PER_ADVANCE) -> list[Reading]:
        """Step to the next event(s); their readings. A diverged state is reset and logged."""
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
        now = sim.time_s
        readings = []
        for event in events:
            if event.startswith("lidar"):
                i = int(event[5:])
                readings.append(Reading("lidar", now, sim.lidar_scan(i), i))
            elif event.startswith("imu"):
                i = int(event[3:])
                readings.append(Reading("imu", now, sim.imu_sample(i), i))
            elif event == "joint_states":
                readings.append(Reading("joint_states", now, sim.wheel_state()))
            elif event == "ground_truth":
                readings.append(Reading("ground_truth", now, sim.ground_truth()))
            else:
                readings.append(Reading(event, now))
        readings += [Reading("collision", c.stamp_s, c) for c in sim.take_collisions()]
        return readings

    def run_until(self, stop_when: Callable[[], bool], handle: Callable[[list[Reading]], None],
                  idle: Callable[[float], None], service_period_s: float = 0.005) -> None:
        """Advance, ``handle`` each batch of readings and pace, until ``stop_when()``.

        ``idle(timeout_s)`` gets the time to wait when ahead of the wall clock or
        paused, and is called with 0 at least every ``service_period_s`` otherwise.
        """
        wall0 = sim0 = 0.0
        last_idle = time.monotonic()
        while not stop_when():
            if self.paused:
                idle(0.05)
                continue
            if self._pace_reset:
                wall0, sim0 = time.monotonic(), self.sim.time_s
                self._pace_reset = False
            rtf = self.real_time_factor
            if rtf > 0:
                # Checked before every advance: idle() may return early (a callback ran).
                ahead_s = wall0 + (self.sim.time_s - sim0) / rtf - time.monotonic()
                if ahead_s > 0:
                    idle(ahead_s)
                    last_idle = time.monotonic()
                    continue
                if ahead_s < -1.0:
                    # Far behind (a slow machine, a debugger): do not sprint to catch up.
                    wall0, sim0 = time.monotonic(), self.sim.time_s
            readings = self.advance()
            if readings:
                handle(readings)
            if time.monotonic() - last_idle >= service_period_s:
                idle(0.0)
                last_idle = time.monotonic()
