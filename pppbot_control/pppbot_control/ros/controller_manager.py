"""``controller_manager``: ros2_control's controller manager services over the controllers a
process hosts (the simulator's, as gz_ros2_control runs its controller manager inside Gazebo).

Node name ``controller_manager``; services with controller_manager_msgs' types, so
``ros2 control list_controllers`` and ros2_control's spawner talk to it:

* ``~/list_controllers``: each loaded controller, its type, state (``active`` / ``inactive``),
  update rate, required and (when active) claimed interfaces;
* ``~/list_hardware_interfaces``: the robot's ``<ros2_control>`` command and state interfaces
  (``joint/interface``), command interfaces marked claimed by the active controllers;
* ``~/switch_controller``: activate and deactivate by name (:mod:`pppbot_control.switching`
  has the rules); a deactivated diff drive commands its wheels to zero and ignores commands;
* ``~/load_controller``: every controller the parameters file declares that pppbot can host is
  loaded at start, so loading answers ``ok`` false naming why (already loaded, a type pppbot
  does not host, no ``<name>.type`` parameter);
* ``~/list_controller_types``: the types pppbot hosts;
* ``~/configure_controller``: ``ok`` for a loaded controller (hosted ones are configured at start),
  so the spawner's load-configure-activate sequence goes through on them; ``~/unload_controller``
  and ``~/cleanup_controller`` (Jazzy's, from ros2_control 4.42: an inactive controller back to
  unconfigured) are refused, saying why (hosted controllers stay loaded and configured; an active
  one must be deactivated first, as ros2_control has it).

Its parameters are the ``controller_manager`` section of the controllers file (``update_rate``,
``<controller>.type``), read as given.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from controller_manager_msgs.msg import ControllerState, HardwareInterface
from controller_manager_msgs.srv import (
    CleanupController,
    ConfigureController,
    ListControllers,
    ListControllerTypes,
    ListHardwareInterfaces,
    LoadController,
    SwitchController,
    UnloadController,
)

from pppbot_common.ros.params import refuse_sets
from pppbot_control.switching import ControllerInfo, ControllerStatus, Strictness, plan_switch
from pppbot_lockstep.ros.node import StepNode

NODE_NAME = "controller_manager"
#: the base class of every hosted type, as ros2_control's plugin registry names it
BASE_CLASS = "controller_interface::ControllerInterface"


class Switchable(Protocol):
    """A hosted controller the manager switches (a diff drive, the joint state broadcaster)."""

    def activate(self) -> None: ...

    def deactivate(self) -> None: ...


@dataclass
class LoadedController:
    """One controller the manager hosts, and its state."""

    name: str
    type: str
    handle: Switchable
    update_rate_hz: float
    command_interfaces: tuple[str, ...] = ()  # required, and claimed while active
    state_interfaces: tuple[str, ...] = ()
    status: ControllerStatus = ControllerStatus.ACTIVE


@dataclass(frozen=True)
class HardwareInterfaces:
    """The robot's ros2_control interfaces, ``joint/interface``."""

    command: tuple[str, ...] = ()
    state: tuple[str, ...] = ()


class ControllerManager(StepNode):
    def __init__(self, controllers: Sequence[LoadedController], hardware: HardwareInterfaces,
                 declared: Mapping[str, str] | None = None, hostable: Sequence[str] = (), **kwargs: Any) -> None:
        """``declared``: every controller the parameters file names (name → type), hosted or not;
        ``hostable``: the types the process can host."""
        super().__init__(NODE_NAME, automatically_declare_parameters_from_overrides=True, **kwargs)
        refuse_sets(self, "the controllers are loaded from the robot's controllers file at start-up; switch them "
                          "with switch_controller")
        self.controllers = {c.name: c for c in controllers}
        self.hardware = hardware
        self.declared = dict(declared or {})
        self.hostable = tuple(hostable)
        self.create_service(ListControllers, "~/list_controllers", self._list_controllers)
        self.create_service(ListHardwareInterfaces, "~/list_hardware_interfaces", self._list_hardware_interfaces)
        self.create_service(SwitchController, "~/switch_controller", self._switch_controller)
        self.create_service(LoadController, "~/load_controller", self._load_controller)
        self.create_service(ListControllerTypes, "~/list_controller_types", self._list_controller_types)
        self.create_service(ConfigureController, "~/configure_controller", self._configure_controller)
        self.create_service(UnloadController, "~/unload_controller", self._unload_controller)
        self.create_service(CleanupController, "~/cleanup_controller", self._cleanup_controller)
        self.get_logger().info(
            "controllers: " + (", ".join(f"{c.name} ({c.type}, {c.status.value})" for c in controllers) or "none"))

    def active(self, name: str) -> bool:
        controller = self.controllers.get(name)
        return controller is not None and controller.status is ControllerStatus.ACTIVE

    def _claimed(self) -> set[str]:
        return {i for c in self.controllers.values() if c.status is ControllerStatus.ACTIVE
                for i in c.command_interfaces}

    # -------------------------------------------------------------- services
    def _list_controllers(self, request: ListControllers.Request,
                          response: ListControllers.Response) -> ListControllers.Response:
        response.controller = [ControllerState(
            name=c.name, state=c.status.value, type=c.type, is_async=False,
            update_rate=round(c.update_rate_hz), required_command_interfaces=list(c.command_interfaces),
            required_state_interfaces=list(c.state_interfaces),
            claimed_interfaces=list(c.command_interfaces) if c.status is ControllerStatus.ACTIVE else [])
            for c in self.controllers.values()]
        return response

    def _list_hardware_interfaces(self, request: ListHardwareInterfaces.Request,
                                  response: ListHardwareInterfaces.Response) -> ListHardwareInterfaces.Response:
        claimed = self._claimed()
        response.command_interfaces = [HardwareInterface(name=n, data_type="double", is_available=True,
                                                         is_claimed=n in claimed) for n in self.hardware.command]
        response.state_interfaces = [HardwareInterface(name=n, data_type="double", is_available=True,
                                                       is_claimed=False) for n in self.hardware.state]
        return response

    def _switch_controller(self, request: SwitchController.Request,
                           response: SwitchController.Response) -> SwitchController.Response:
        if request.strictness == Strictness.UNSET:
            self.get_logger().warning("switch_controller without a strictness: read as BEST_EFFORT (1); "
                                      "give STRICT (2) or BEST_EFFORT (1)")
        infos = {c.name: ControllerInfo(c.status, c.command_interfaces) for c in self.controllers.values()}
        try:
            plan = plan_switch(infos, request.activate_controllers, request.deactivate_controllers,
                               request.strictness)
        except ValueError as exc:
            response.ok, response.message = False, str(exc)
            self.get_logger().error(f"switch_controller refused: {exc}")
            return response
        for name in plan.deactivate:
            self.controllers[name].handle.deactivate()
            self.controllers[name].status = ControllerStatus.INACTIVE
        for name in plan.activate:
            self.controllers[name].handle.activate()
            self.controllers[name].status = ControllerStatus.ACTIVE
        response.ok, response.message = plan.ok, plan.message
        # One call site per severity: rclpy raises when a line's severity changes between calls.
        if plan.ok:
            self.get_logger().info(f"switch_controller done: {plan.message}")
        else:
            self.get_logger().error(f"switch_controller refused: {plan.message}")
        return response

    def _load_controller(self, request: LoadController.Request,
                         response: LoadController.Response) -> LoadController.Response:
        name = request.name
        kind = self.declared.get(name)
        if name in self.controllers:
            reason = f"a controller named '{name}' is already loaded"
        elif kind is None:
            reason = f"no '{name}.type' parameter declares controller '{name}'"
        else:
            reason = (f"controller '{name}' of type {kind} is not one pppbot hosts "
                      f"({', '.join(self.hostable) or 'none'})")
        self.get_logger().warning(f"load_controller {name}: {reason}")
        response.ok = False
        return response

    def _configure_controller(self, request: ConfigureController.Request,
                              response: ConfigureController.Response) -> ConfigureController.Response:
        """A hosted controller is configured when the process starts: ``ok`` for a loaded one (what
        the spawner asks after finding it loaded), false naming why for any other."""
        response.ok = request.name in self.controllers
        if not response.ok:
            self.get_logger().warning(f"configure_controller {request.name}: no controller of that name is loaded")
        return response

    def _unload_controller(self, request: UnloadController.Request,
                           response: UnloadController.Response) -> UnloadController.Response:
        """Hosted controllers stay loaded (the simulator's process owns them): refused, saying so."""
        self.get_logger().warning(f"unload_controller {request.name}: pppbot's hosted controllers stay loaded "
                                  "(deactivate one with switch_controller)")
        response.ok = False
        return response

    def _cleanup_controller(self, request: CleanupController.Request,
                            response: CleanupController.Response) -> CleanupController.Response:
        """Refused, naming why: no such controller, an active one (deactivate it first, as ros2_control
        asks), or a hosted one, which stays configured while the simulator's process runs."""
        controller = self.controllers.get(request.name)
        if controller is None:
            reason = "no controller of that name is loaded"
        elif controller.status is ControllerStatus.ACTIVE:
            reason = "it is active: deactivate it with switch_controller first"
        else:
            reason = "pppbot's hosted controllers stay configured (it is inactive: activate it with switch_controller)"
        self.get_logger().warning(f"cleanup_controller {request.name}: {reason}")
        response.ok = False
        return response

    def _list_controller_types(self, request: ListControllerTypes.Request,
                               response: ListControllerTypes.Response) -> ListControllerTypes.Response:
        response.types = list(self.hostable)
        response.base_classes = [BASE_CLASS] * len(self.hostable)
        return response
