"""The simulator node's parameters (``ros2 param`` names, defaults and descriptions) and their checks."""
from __future__ import annotations

import math
from dataclasses import dataclass

from pppbot_common.params import ParameterError, check_finite_range, param
from pppbot_common.upright import MAX_TILT_RAD, MIN_HEIGHT_M
from pppbot_sim.wheel_slip import MAX_SLIP_STDDEV


@dataclass(frozen=True)
class SimulatorParameters:
    world: str = param("empty", "world name (worlds/<name>.sdf) or path to an SDF or MJCF file")
    robot_description: str = param("", "URDF XML, or a .urdf/.xacro path; empty = ppp_bot's robot.urdf.xacro")
    robot_name: str = param("ppp_bot", "name of the spawned robot")
    cmd_vel_topic: str = param("", "the topic the robot's Gazebo DiffDrive plugin listens on instead of its <topic> "
                                   "(what a ros_gz_bridge remapping does); empty: the plugin's own")
    x: float = param(0.0, "spawn x (m)")
    y: float = param(0.0, "spawn y (m)")
    z: float = param(math.nan, "spawn z of the robot's root link (m); nan: resting on whatever lies beneath (x, y) "
                               "(ppp_bot on the ground: 0.05)")
    yaw: float = param(0.0, "spawn yaw (rad)")
    real_time_factor: float = param(1.0, "simulated seconds per wall second; 0 = as fast as possible "
                                         "(with lockstep: as fast as the participants allow)")
    lockstep: bool = param(False, "advance time only when the lockstep participants have done their work")
    lockstep_participants: list = param([""], "lockstep participants that must join before time starts")
    lockstep_timeout: float = param(30.0, "wall seconds a lockstep participant may take to answer a step")
    seed: int = param(0, "seed of the sensor-noise and wheel-slip generators")
    wheel_slip: float = param(0.0, "standard deviation of each wheel's slip fraction as its encoder reports it "
                                   "(0.02 = 2 %); makes odometry drift; 0 = exact encoders")
    wheel_slip_correlation: float = param(2.0, "how long a wheel's slip persists (sim s)")
    controller_remappings: list = param(
        ["/diff_drive_base_controller/odom:=/odom"],
        "remappings (from:=to) of the hosted controllers and the controller manager, as gz_ros2_control's "
        "<ros><remapping>; [''] for none (odometry then on Jazzy's /diff_drive_base_controller/odom)")
    command_timeout: float = param(0.5, "wheels stop when no command came for this long (sim s); 0 = never")
    joint_states_rate: float = param(100.0, "/joint_states rate (Hz, sim time)")
    ground_truth_rate: float = param(50.0, "/ground_truth/odom rate (Hz, sim time)")
    clock_rate: float = param(100.0, "/clock rate (Hz, sim time); with lockstep /clock comes with each step")
    step_count: int = param(1, "physics steps per step_physics call")
    paused: bool = param(False, "start paused")
    viewer: bool = param(False, "open MuJoCo's viewer window (needs a display)")
    cameras: bool = param(True, "render the robot's camera tags while someone subscribes (false: no camera topics)")
    upright_max_tilt: float = param(MAX_TILT_RAD, "roll or pitch (rad) past which the robot has tipped over "
                                                  "(reported in the log and on /diagnostics)")
    upright_min_height: float = param(MIN_HEIGHT_M, "height (m, world z) of the robot's root link below which it "
                                                    "has sunk into the ground")

    def validate(self) -> None:
        for name in ("x", "y", "yaw"):
            check_finite_range(name, getattr(self, name))
        if not math.isnan(self.z):
            check_finite_range("z", self.z)
        check_finite_range("real_time_factor", self.real_time_factor, 0.0, 1000.0)
        check_finite_range("command_timeout", self.command_timeout, 0.0, 3600.0)
        check_finite_range("lockstep_timeout", self.lockstep_timeout, 0.0, 86400.0, low_open=True)
        check_finite_range("wheel_slip", self.wheel_slip, 0.0, MAX_SLIP_STDDEV)
        check_finite_range("upright_max_tilt", self.upright_max_tilt, 0.0, math.pi, low_open=True)
        check_finite_range("upright_min_height", self.upright_min_height, -1000.0, 1000.0)
        check_finite_range("wheel_slip_correlation", self.wheel_slip_correlation, 0.0, 3600.0, low_open=True)
        for name in ("joint_states_rate", "ground_truth_rate", "clock_rate"):
            check_finite_range(name, getattr(self, name), 0.0, 10000.0, low_open=True)
        if not 1 <= self.step_count <= 1_000_000:
            raise ParameterError("step_count", self.step_count, "must be in [1, 1000000]")
        if not self.robot_name or "/" in self.robot_name:
            raise ParameterError("robot_name", self.robot_name, "must be a non-empty name without '/'")
        if not all(isinstance(n, str) for n in self.lockstep_participants):
            raise ParameterError("lockstep_participants", self.lockstep_participants, "must be a list of names")
        for rule in self.controller_remappings:
            source, sep, target = str(rule).partition(":=")
            if rule and not (source and sep and target):
                raise ParameterError("controller_remappings", self.controller_remappings,
                                     f"each must read from:=to ('{rule}' does not)")

    def expected_participants(self) -> list[str]:
        return [n for n in self.lockstep_participants if n]
