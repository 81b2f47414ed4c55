"""Jazzy's nav2_msgs, built from its definitions where the environment lacks them
(``interfaces/nav2_msgs``): every type imports, with Jazzy's shapes (not Kilted's)."""
from __future__ import annotations

import importlib
from pathlib import Path

import pytest

INTERFACES = Path(__file__).resolve().parent.parent / "interfaces" / "nav2_msgs"


def definitions() -> list[tuple[str, str]]:
    return [(kind, path.stem) for kind in ("msg", "srv", "action")
            for path in sorted((INTERFACES / kind).glob(f"*.{kind}"))]


@pytest.mark.parametrize(("kind", "name"), definitions(), ids=[f"{k}/{n}" for k, n in definitions()])
def test_every_definition_imports(kind: str, name: str):
    assert hasattr(importlib.import_module(f"nav2_msgs.{kind}"), name)


def test_every_type_of_jazzy_is_there():
    # 17 messages, 15 services, 19 actions: FollowGPSWaypoints (with geographic_msgs) and 1.3.13's FollowObject
    assert len(definitions()) == 51


def test_the_shapes_are_jazzys():
    from nav2_msgs.action import ComputePathThroughPoses, FollowWaypoints, NavigateThroughPoses, Spin
    from nav2_msgs.srv import ManageLifecycleNodes

    # Jazzy: geometry_msgs/PoseStamped[] (Kilted made it nav2_msgs/PoseStampedArray, then nav_msgs/Goals).
    assert NavigateThroughPoses.Goal.get_fields_and_field_types()["poses"] == "sequence<geometry_msgs/PoseStamped>"
    assert ComputePathThroughPoses.Goal.get_fields_and_field_types()["goals"] == "sequence<geometry_msgs/PoseStamped>"
    # Jazzy's results carry error_code and error_msg, which BasicNavigator.isTaskComplete() reads.
    for action in (NavigateThroughPoses, FollowWaypoints, Spin):
        assert {"error_code", "error_msg"} <= action.Result.get_fields_and_field_types().keys()
    assert FollowWaypoints.Result.get_fields_and_field_types()["missed_waypoints"] == \
        "sequence<nav2_msgs/MissedWaypoint>"
    request = ManageLifecycleNodes.Request
    assert (request.STARTUP, request.PAUSE, request.RESUME, request.RESET, request.SHUTDOWN, request.CONFIGURE,
            request.CLEANUP) == (0, 1, 2, 3, 4, 5, 6)
