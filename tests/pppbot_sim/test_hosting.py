"""The simulator hosts controllers through its entry-point groups (pppbot_sim.hosting), not imports:
pppbot_control's diff drive and controller manager are found by type, satisfy the simulator's
Protocol, run on the clock the simulator sets, and command the joints they are handed."""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from importlib.metadata import EntryPoint
from pathlib import Path
from typing import Any

import pytest

from pppbot_description.urdf_model import parse_urdf
from pppbot_description.xacro_model import process_xacro
from pppbot_lockstep.ros.port import FREE_RUNNING
from pppbot_sim.controllers import ControllerPlan, read_plan
from pppbot_sim.errors import SpawnError
from pppbot_sim.hosting import CONTROLLERS, MANAGERS, HostedController, load, registered
from pppbot_sim.ros.hosted import controller_arguments, host

ROOT = Path(__file__).resolve().parents[2]
CONTROLLERS_FILE = ROOT / "config" / "my_controllers.yaml"
DIFF_DRIVE = "diff_drive_controller/DiffDriveController"


class Joints:
    """Wheels at rest that remember what they were commanded."""

    def __init__(self) -> None:
        self.t_ns = 0
        self.commands: list[Mapping[str, float]] = []

    def read(self) -> tuple[Sequence[str], Sequence[float], Sequence[float], int]:
        return ["left_wheel_joint", "right_wheel_joint"], [0.0, 0.0], [0.0, 0.0], self.t_ns

    def write(self, velocities: Mapping[str, float]) -> None:
        self.commands.append(dict(velocities))


def test_pppbot_control_registers_the_diff_drive_and_the_controller_manager() -> None:
    assert registered(CONTROLLERS)[DIFF_DRIVE].value == "pppbot_control.ros.hosting:diff_drive_controller"
    assert registered(MANAGERS)["controller_manager"].value == "pppbot_control.ros.hosting:controller_manager"


def test_an_entry_point_that_does_not_load_is_named() -> None:
    broken = EntryPoint("acme/Broken", "acme_controllers.nowhere:make", CONTROLLERS)
    with pytest.raises(SpawnError, match=r"'acme/Broken = acme_controllers.nowhere:make' \(group "
                                         r"pppbot_sim.hosted_controllers\) does not load: ModuleNotFoundError"):
        load(broken)


def robot() -> Any:
    return parse_urdf(process_xacro(None, {"controllers_file": str(CONTROLLERS_FILE)}), "ppp_bot")


def not_a_controller(request: Any) -> Any:
    return "not a controller"


def test_types_nobody_hosts_are_left_out_and_a_factory_that_makes_no_controller_is_refused() -> None:
    plan = ControllerPlan(CONTROLLERS_FILE, 50.0, (("arm", "joint_trajectory_controller/JointTrajectoryController"),
                                                   ("joint_broad", "joint_state_broadcaster/JointStateBroadcaster")))
    hosted = host(plan, robot(), Joints(), [], FREE_RUNNING, factory=lambda kind: None, manager=lambda: None)
    assert hosted.left_out == [("arm", "joint_trajectory_controller/JointTrajectoryController")]
    (broadcaster,) = hosted.broadcasters
    assert broadcaster.name == "joint_broad" and isinstance(broadcaster, HostedController)
    assert set(broadcaster.state_interfaces) == {"left_wheel_joint/position", "left_wheel_joint/velocity",
                                                 "right_wheel_joint/position", "right_wheel_joint/velocity"}
    plan = ControllerPlan(CONTROLLERS_FILE, 50.0, (("drive", DIFF_DRIVE),))
    with pytest.raises(SpawnError, match="controller 'drive' of type diff_drive_controller/DiffDriveController: "
                                         "its factory made a str"):
        host(plan, robot(), Joints(), [], FREE_RUNNING, factory=lambda kind: not_a_controller,
             manager=lambda: None)


@pytest.mark.ros
def test_the_registered_diff_drive_runs_on_the_simulators_clock_and_commands_the_joints(ros_node: Any) -> None:
    plan = read_plan(CONTROLLERS_FILE)
    joints = Joints()
    hosted = host(plan, robot(), joints, controller_arguments(plan), FREE_RUNNING)
    try:
        (drive,) = hosted.controllers
        assert isinstance(drive, HostedController) and drive.type == DIFF_DRIVE
        assert drive.name == "diff_drive_base_controller"
        assert drive.command_interfaces == ("left_wheel_joint/velocity", "right_wheel_joint/velocity")
        node = drive.node
        assert "/clock" not in [s.topic_name for s in node.subscriptions]  # its time is the simulator's
        joints.t_ns = 3_250_000_000
        drive.update(joints.t_ns)
        assert node.get_clock().now().nanoseconds == 3_250_000_000
        assert joints.commands[-1] == {"left_wheel_joint": 0.0, "right_wheel_joint": 0.0}
        assert hosted.manager is not None and {c.name for c in [*hosted.controllers, *hosted.broadcasters]} == \
            set(hosted.manager.controllers)
        assert hosted.manager.hostable == ("diff_drive_controller/DiffDriveController",
                                           "joint_state_broadcaster/JointStateBroadcaster")
    finally:
        for node in hosted.nodes:
            node.destroy_node()

