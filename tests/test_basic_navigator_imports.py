"""Every interface Nav2 Jazzy's own ``nav2_simple_commander.robot_navigator`` imports is there:
on a pip install it failed with ``cannot import name 'FollowGPSWaypoints' from 'nav2_msgs.action'``
until geographic_msgs was built (interfaces/README.md)."""
from __future__ import annotations

import importlib

import pytest

#: What robot_navigator.py (jazzy branch) imports from interface packages, by module.
IMPORTED = {
    "action_msgs.msg": ["GoalStatus"],
    "builtin_interfaces.msg": ["Duration"],
    "geographic_msgs.msg": ["GeoPose"],
    "geometry_msgs.msg": ["Point", "PoseStamped", "PoseWithCovarianceStamped"],
    "lifecycle_msgs.srv": ["GetState"],
    "nav2_msgs.action": ["AssistedTeleop", "BackUp", "ComputePathThroughPoses", "ComputePathToPose", "DockRobot",
                         "DriveOnHeading", "FollowGPSWaypoints", "FollowPath", "FollowWaypoints",
                         "NavigateThroughPoses", "NavigateToPose", "SmoothPath", "Spin", "UndockRobot"],
    "nav2_msgs.srv": ["ClearEntireCostmap", "GetCostmap", "LoadMap", "ManageLifecycleNodes"],
}


@pytest.mark.parametrize("module", sorted(IMPORTED))
def test_every_name_basic_navigator_imports_is_there(module: str) -> None:
    imported = importlib.import_module(module)
    assert [name for name in IMPORTED[module] if not hasattr(imported, name)] == []


def test_a_gps_waypoint_goal_is_built_as_basic_navigator_builds_it() -> None:
    from geographic_msgs.msg import GeoPose
    from nav2_msgs.action import FollowGPSWaypoints

    pose = GeoPose()
    pose.position.latitude, pose.position.longitude = 52.5163, 13.3777
    pose.orientation.w = 1.0
    goal = FollowGPSWaypoints.Goal(gps_poses=[pose])
    assert goal.gps_poses[0].position.latitude == pytest.approx(52.5163)
    assert FollowGPSWaypoints.Result().missed_waypoints == []
