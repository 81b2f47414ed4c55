"""The simulator's controller_manager over DDS: ros2_control's services over the controllers it
hosts (ppp_bot's my_controllers.yaml, through the robot's gz_ros2_control plugin)."""
from __future__ import annotations

from pathlib import Path

import pytest
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
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry

from pppbot_common.ros.wait import wait_for_messages, wait_until

pytestmark = pytest.mark.ros
ROOT = Path(__file__).resolve().parents[2]
PPPBOT = str(ROOT / "pppbot")
CONTROLLERS = ROOT / "config" / "my_controllers.yaml"
CM = "/controller_manager"


@pytest.fixture
def simulator(spawn, tmp_path):
    from pppbot_description.xacro_model import process_xacro

    urdf = tmp_path / "ppp_bot.urdf"
    urdf.write_text(process_xacro(None, {"controllers_file": str(CONTROLLERS)}))
    child = spawn([PPPBOT, "run", "pppbot_sim", "simulator", "--ros-args", "-p", "world:=empty",
                   "-p", f"robot_description:={urdf}", "-p", "real_time_factor:=3.0"], name="simulator")
    child.wait_for_output("controllers from .* in this process", 30)
    return child


def call(node, srv_type, name, request=None, timeout_s=10.0):
    client = node.create_client(srv_type, name)
    assert client.wait_for_service(timeout_sec=timeout_s), name
    future = client.call_async(request or srv_type.Request())
    result = wait_until(lambda: future.result() if future.done() else None, timeout_s, name, node=node)
    node.destroy_client(client)
    return result


def states(node) -> dict[str, str]:
    return {c.name: c.state for c in call(node, ListControllers, f"{CM}/list_controllers").controller}


def test_list_controllers_shows_both_active_with_their_types(ros_node, simulator):
    listed = {c.name: c for c in call(ros_node, ListControllers, f"{CM}/list_controllers").controller}
    assert {n: (c.type, c.state) for n, c in listed.items()} == {
        "diff_drive_base_controller": ("diff_drive_controller/DiffDriveController", "active"),
        "joint_broad": ("joint_state_broadcaster/JointStateBroadcaster", "active")}
    drive = listed["diff_drive_base_controller"]
    assert list(drive.claimed_interfaces) == ["left_wheel_joint/velocity", "right_wheel_joint/velocity"]
    assert list(drive.required_state_interfaces) == ["left_wheel_joint/position", "right_wheel_joint/position"]
    assert drive.update_rate == 100
    hardware = call(ros_node, ListHardwareInterfaces, f"{CM}/list_hardware_interfaces")
    assert {(i.name, i.is_claimed) for i in hardware.command_interfaces} == {
        ("left_wheel_joint/velocity", True), ("right_wheel_joint/velocity", True)}
    assert {i.name for i in hardware.state_interfaces} == {
        f"{w}_wheel_joint/{k}" for w in ("left", "right") for k in ("velocity", "position")}
    types = call(ros_node, ListControllerTypes, f"{CM}/list_controller_types")
    assert "diff_drive_controller/DiffDriveController" in types.types
    assert not call(ros_node, LoadController, f"{CM}/load_controller",
                    LoadController.Request(name="diff_drive_base_controller")).ok  # loaded already
    # The spawner's next step on a loaded controller goes through; unloading one is refused.
    assert call(ros_node, ConfigureController, f"{CM}/configure_controller",
                ConfigureController.Request(name="diff_drive_base_controller")).ok
    assert not call(ros_node, ConfigureController, f"{CM}/configure_controller",
                    ConfigureController.Request(name="no_such_controller")).ok
    assert not call(ros_node, UnloadController, f"{CM}/unload_controller",
                    UnloadController.Request(name="joint_broad")).ok
    # Jazzy's cleanup_controller: an active controller is refused (as ros2_control does), and the
    # controllers stay as they were.
    assert not call(ros_node, CleanupController, f"{CM}/cleanup_controller",
                    CleanupController.Request(name="diff_drive_base_controller")).ok
    assert states(ros_node) == {"diff_drive_base_controller": "active", "joint_broad": "active"}
    simulator.wait_for_output("cleanup_controller diff_drive_base_controller: it is active", 10)


def test_deactivating_the_diff_drive_stops_the_robot_and_reactivating_resumes(ros_node, simulator):
    cmd = ros_node.create_publisher(Twist, "/diff_drive_base_controller/cmd_vel_unstamped", 10)
    wait_until(lambda: cmd.get_subscription_count() > 0, 10, "the controller's command topic")
    go = Twist()
    go.linear.x = 0.5

    def speed() -> float:
        (truth,) = wait_for_messages(ros_node, Odometry, "/ground_truth/odom", timeout_s=10)
        return truth.twist.twist.linear.x

    wait_until(lambda: (cmd.publish(go), speed() > 0.3)[1], 20, "the robot driving", node=ros_node)
    switch = SwitchController.Request(deactivate_controllers=["diff_drive_base_controller"],
                                      strictness=SwitchController.Request.STRICT)
    result = call(ros_node, SwitchController, f"{CM}/switch_controller", switch)
    assert result.ok, result.message
    assert states(ros_node)["diff_drive_base_controller"] == "inactive"
    wait_until(lambda: (cmd.publish(go), abs(speed()) < 0.02)[1], 20, "the robot stopped while commanded",
               node=ros_node)
    switch = SwitchController.Request(activate_controllers=["diff_drive_base_controller"],
                                      strictness=SwitchController.Request.STRICT)
    assert call(ros_node, SwitchController, f"{CM}/switch_controller", switch).ok
    assert states(ros_node)["diff_drive_base_controller"] == "active"
    wait_until(lambda: (cmd.publish(go), speed() > 0.3)[1], 20, "the robot driving again", node=ros_node)


def test_odometry_is_on_odom_by_the_default_remapping(ros_node, simulator):
    (odom,) = wait_for_messages(ros_node, Odometry, "/odom", timeout_s=10)
    assert (odom.header.frame_id, odom.child_frame_id) == ("odom", "base_link")
