"""Where the robot starts in a loaded pose graph: slam_toolbox's rules, without ROS.

Two ways in, as in slam_toolbox (``slam_toolbox_common.cpp``):

* at startup, from the parameters ``map_file_name``, ``map_start_pose`` and
  ``map_start_at_dock`` (its ``shouldStartWithPoseGraph``): a given ``map_start_pose``
  wins; without one, ``map_start_at_dock`` decides between the graph's first keyframe
  (the dock, where the first session started) and the map origin;
* by the service ``deserialize_map`` (slam_toolbox/srv/DeserializePoseGraph), whose
  ``match_type`` says which: ``START_AT_FIRST_NODE`` or ``START_AT_GIVEN_POSE`` with
  ``initial_pose``. ``LOCALIZE_AT_POSE`` is slam_toolbox's localization mode, which this
  mapper does not do (AMCL localizes on a saved map here), and ``UNSET`` is refused as
  slam_toolbox refuses it.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from enum import IntEnum

import numpy as np

from pppbot_slam.errors import SessionStartError


class MatchType(IntEnum):
    """DeserializePoseGraph's ``match_type`` constants (same values)."""

    UNSET = 0
    START_AT_FIRST_NODE = 1
    START_AT_GIVEN_POSE = 2
    LOCALIZE_AT_POSE = 3


def check_start_pose(pose: Sequence[float]) -> None:
    """``map_start_pose`` is either unset (empty) or three finite numbers [x (m), y (m), yaw (rad)].

    Raises:
        SessionStartError: anything else; the message names the value.
    """
    if len(pose) == 0:
        return
    if len(pose) != 3 or not all(isinstance(v, (int, float)) and math.isfinite(v) for v in pose):
        raise SessionStartError(f"map_start_pose = {list(pose)}: must be three finite numbers [x, y, yaw], "
                                "or empty (not given)")


def start_from_parameters(map_start_pose: Sequence[float], map_start_at_dock: bool) -> np.ndarray | None:
    """The start pose at startup: ``map_start_pose`` when given (it wins over the dock), else the
    first keyframe (None) with ``map_start_at_dock``, else the map origin.

    Raises:
        SessionStartError: a malformed ``map_start_pose``.
    """
    check_start_pose(map_start_pose)
    if len(map_start_pose) == 3:
        return np.array(map_start_pose, dtype=float)
    return None if map_start_at_dock else np.zeros(3)


def start_from_request(match_type: int, initial_pose_xy_yaw: Sequence[float]) -> np.ndarray | None:
    """The start pose asked by a DeserializePoseGraph request: None for the first keyframe,
    else ``initial_pose`` (x m, y m, yaw rad in the map).

    Raises:
        SessionStartError: ``UNSET``, ``LOCALIZE_AT_POSE`` (localization is not done here), an
            unknown match type or a non-finite pose; the message names it.
    """
    try:
        kind = MatchType(match_type)
    except ValueError as exc:
        raise SessionStartError(f"match_type = {match_type}: not one of "
                                f"{', '.join(f'{m.name} ({m.value})' for m in MatchType)}") from exc
    if kind is MatchType.UNSET:
        raise SessionStartError("match_type = UNSET (0): say where the robot is, START_AT_FIRST_NODE (1) or "
                                "START_AT_GIVEN_POSE (2) with initial_pose")
    if kind is MatchType.LOCALIZE_AT_POSE:
        raise SessionStartError("match_type = LOCALIZE_AT_POSE (3): localization on a pose graph is not done by "
                                "this node; use START_AT_GIVEN_POSE (2) to map on from the pose, or AMCL to localize")
    if kind is MatchType.START_AT_FIRST_NODE:
        return None
    pose = np.asarray(initial_pose_xy_yaw, dtype=float)
    if pose.shape != (3,) or not np.all(np.isfinite(pose)):
        raise SessionStartError(f"initial_pose = {list(initial_pose_xy_yaw)}: must be a finite x, y, theta")
    return pose
