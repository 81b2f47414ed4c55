"""ppp_bot's own parameter files, as pppbot ships them, give each node nothing it leaves unread:
every key is honoured (the nav2 file is checked server by server in tests/pppbot_nav/test_nav2_plugins.py)."""
from __future__ import annotations

import importlib
from pathlib import Path

import pytest
import rclpy

from pppbot_common.ros.unread_parameters import reasons, unread_parameters

pytestmark = pytest.mark.ros

CONFIG = Path(__file__).resolve().parent.parent / "config"


@pytest.mark.parametrize("file, node_class, node_name", [
    ("mapper_params_online_async.yaml", "pppbot_slam.ros.slam:Slam", None),
    ("twist_mux.yaml", "pppbot_control.ros.twist_mux:TwistMuxNode", None),
    ("my_controllers.yaml", "pppbot_control.ros.diff_drive_controller:DiffDriveController", None),
    ("joystick.yaml", "pppbot_control.ros.joy_node:JoyNode", None),
    ("joystick.yaml", "pppbot_control.ros.teleop_joy:TeleopTwistJoyNode", "teleop_node"),
    ("nav2_params.yaml", "pppbot_nav.ros.amcl:Amcl", None),
    ("nav2_params.yaml", "pppbot_nav.ros.map_server:MapServer", None),
])
def test_each_node_reads_every_key_of_its_section(file: str, node_class: str, node_name: str | None) -> None:
    args = ["--ros-args", "--params-file", str(CONFIG / file)]
    if node_name:
        args += ["-r", f"__node:={node_name}"]
    rclpy.init(args=args)
    try:
        module, name = node_class.split(":")
        node = getattr(importlib.import_module(module), name)()
        try:
            overrides = getattr(node, "_parameter_overrides", {})
            assert len(overrides) > 1, f"{file} gave {node.get_name()} nothing: the wrong section"
            assert unread_parameters(node) == []
        finally:
            node.destroy_node()
    finally:
        rclpy.shutdown()


def test_slam_toolboxs_own_file_leaves_no_key_without_its_reason() -> None:
    """slam_toolbox's full online async file (solver, interactive and matcher keys pppbot's SLAM
    does not have): each key it leaves unread is named with a reason of its own."""
    path = Path(__file__).resolve().parent / "data" / "ppp_bot" / "mapper_params_online_async.yaml"
    rclpy.init(args=["--ros-args", "--params-file", str(path)])
    try:
        from pppbot_slam.ros.slam import Slam

        node = Slam()
        try:
            grouped = reasons(unread_parameters(node), node.parameter_notes, "GENERIC")
            assert "GENERIC" not in grouped
            assert "ceres_linear_solver" in grouped[node.parameter_notes["ceres_*"]]
        finally:
            node.destroy_node()
    finally:
        rclpy.shutdown()
