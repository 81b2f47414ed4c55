"""pppbot_control's controllers as the simulator hosts them (its ``pppbot_sim.hosted_controllers``
and ``pppbot_sim.controller_managers`` entry points, registered in ``setup.py``).

The simulator owns the interface (:mod:`pppbot_sim.hosting`'s Protocols); this module satisfies
it structurally and imports nothing of the simulator: a factory takes the simulator's request
(name, type, joints, node arguments, step port, update rate) and returns the controller.
"""
from __future__ import annotations

from typing import Any

from rclpy.node import Node

from pppbot_common.ros.driven_clock import DrivenClock
from pppbot_control.ros.controller_manager import ControllerManager, HardwareInterfaces, LoadedController
from pppbot_control.ros.diff_drive_controller import NODE_NAME, DiffDriveController


class HostedDiffDrive:
    """ros2_control's diff_drive_controller in the simulator's process: ticked by the physics loop,
    its clock the simulation's."""

    type = "diff_drive_controller/DiffDriveController"

    def __init__(self, request: Any) -> None:
        arguments = list(request.node_arguments)
        if request.name != NODE_NAME:
            arguments += ["-r", f"__node:={request.name}"]
        self._node = DiffDriveController(hosted=request.joints, port=request.port, cli_args=arguments)
        self._clock = DrivenClock(self._node)
        self.name = self._node.get_name()
        p = self._node.params
        wheels = [*p.left_wheel_names, *p.right_wheel_names]
        feedback = "position" if p.position_feedback else "velocity"
        self.command_interfaces = tuple(f"{w}/velocity" for w in wheels)
        self.state_interfaces = () if p.open_loop else tuple(f"{w}/{feedback}" for w in wheels)

    @property
    def node(self) -> Node:
        return self._node

    def update(self, t_ns: int) -> None:
        self._clock.set(t_ns)
        self._node.update()

    def activate(self) -> None:
        self._node.activate()

    def deactivate(self) -> None:
        self._node.deactivate()


def diff_drive_controller(request: Any) -> HostedDiffDrive:
    """The ``diff_drive_controller/DiffDriveController`` entry point."""
    return HostedDiffDrive(request)


def controller_manager(request: Any) -> ControllerManager:
    """The ``controller_manager`` entry point: ros2_control's services over what the simulator hosts."""
    loaded = [LoadedController(c.name, c.type, c, request.update_rate_hz, command_interfaces=c.command_interfaces,
                               state_interfaces=c.state_interfaces) for c in request.controllers]
    hardware = HardwareInterfaces(command=request.command_interfaces, state=request.state_interfaces)
    return ControllerManager(loaded, hardware, request.declared, hostable=request.hostable,
                             cli_args=request.node_arguments, port=request.port)
