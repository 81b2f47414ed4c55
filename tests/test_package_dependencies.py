"""Every package.xml declares what its package imports: each pppbot package and each ROS package
(rclpy, ament_index_python, message packages) a module of the package imports is one of its
``depend``, ``exec_depend`` or ``build_depend`` entries. colcon orders builds and rosdep installs
from these: a package that imports more than it declares works in this checkout and fails in a
Jazzy workspace."""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
ROS_PACKAGES = ("rclpy", "ament_index_python", "rosidl_runtime_py", "rosbag2_py", "tf2_ros")
PACKAGES = sorted(p.parent.name for p in REPO.glob("pppbot_*/package.xml"))


def imported_packages(package: str) -> set[str]:
    used = set()
    for path in (REPO / package / package).rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module] if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module else []
            for name in names:
                top = name.split(".")[0]
                if top != package and (top.startswith("pppbot_") or top in ROS_PACKAGES
                                       or top.endswith(("_msgs", "_srvs", "_interfaces"))):
                    used.add(top)
    return used


@pytest.mark.parametrize("package", PACKAGES)
def test_package_xml_declares_every_package_imported(package: str) -> None:
    declared = set(re.findall(r"<(?:depend|exec_depend|build_depend)>([\w\-]+)</",
                              (REPO / package / "package.xml").read_text()))
    assert not imported_packages(package) - declared, f"{package}/package.xml lacks these imports"


def test_lockstep_is_below_the_nodes_and_above_the_common_helpers() -> None:
    """pppbot_common imports nothing of pppbot_lockstep (it would be a dependency cycle)."""
    assert "pppbot_lockstep" not in imported_packages("pppbot_common")
    assert imported_packages("pppbot_lockstep") <= {"pppbot_common", "pppbot_interfaces", "rclpy", "builtin_interfaces",
                                                    "lifecycle_msgs", "action_msgs", "tf2_msgs", "rosgraph_msgs",
                                                    "rcl_interfaces", "sensor_msgs", "std_msgs"}


def test_the_simulator_hosts_controllers_through_entry_points_not_imports() -> None:
    """pppbot_sim finds the controllers it hosts by type in its entry-point groups (pppbot_sim.hosting):
    it imports nothing of pppbot_control, nor depends on it."""
    assert "pppbot_control" not in imported_packages("pppbot_sim")
    assert "pppbot_control" not in (REPO / "pppbot_sim" / "package.xml").read_text()
