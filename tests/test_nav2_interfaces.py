"""Jazzy's nav2_msgs, built from its definitions where the environment lacks them
(``interfaces/nav2_msgs``): every type imports, with Jazzy's shapes (not Kilted's)."""
from __future__ import annotations

import importlib
import importlib.util
from pathlib import Path

import pytest

INTERFACES = Path(__file__).resolve().parent.parent / "interfaces" / "nav2_msgs"
#: Built only with geographic_msgs, which PyPI lacks (CMakeLists.txt says so at build time).
NEEDS_GEOGRAPHIC = {"FollowGPSWaypoints"}


def definitions() -> list[tuple[str, str]]:
    return [(kind, path.stem) for kind in ("msg", "srv", "action")
            for path in sorted((INTERFACES / kind).glob(f"*.{kind}"))]


@pytest.mark.parametrize(("kind", "name"), definitions(), ids=[f"{k}/{n}" for k, n in definitions()])
def test_every_definition_imports(kind: str, name: str):
    if name in NEEDS_GEOGRAPHIC and importlib.util.find_spec("geographic_msgs") is None:
        pytest.skip("needs geographic_msgs, which this environment lacks")
    assert hasattr(importlib.import_module(f"nav2_msgs.{kind}"), name)


def test_every_type_of_jazzy_is_there():
    assert len(definitions()) == 50  # 17 messages, 15 services, 18 actions (FollowGPSWaypoints among them)


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
