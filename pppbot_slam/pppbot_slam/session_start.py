"""Where the robot starts in a loaded pose graph: slam_toolbox's rules, without ROS.

The node's ``mode`` (:class:`SlamMode`) decides what a loaded graph is for: ``mapping`` maps on
from it, ``localization`` localizes in it (:mod:`pppbot_slam.localizer`). Two ways in, as in
slam_toolbox (``slam_toolbox_common.cpp``, ``slam_toolbox_localization.cpp``):

* at startup, from the parameters ``map_file_name``, ``map_start_pose`` and
  ``map_start_at_dock`` (its ``shouldStartWithPoseGraph``): a given ``map_start_pose``
  wins; without one, ``map_start_at_dock`` decides between the graph's first keyframe
  (the dock, where the first session started) and the map origin;
* by the service ``deserialize_map`` (slam_toolbox/srv/DeserializePoseGraph), whose
  ``match_type`` says which. Mapping takes ``START_AT_FIRST_NODE`` or ``START_AT_GIVEN_POSE``
  with ``initial_pose`` (:func:`start_from_request`); localization takes ``LOCALIZE_AT_POSE``
  with ``initial_pose`` only (:func:`localization_start_from_request`), as slam_toolbox's
  mapping nodes refuse ``LOCALIZE_AT_POSE`` and its localization node refuses the others.
  ``UNSET`` is refused in both, as slam_toolbox refuses it.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from enum import Enum, IntEnum

import numpy as np

from pppbot_slam.errors import SessionStartError


class SlamMode(Enum):
    """The ``mode`` parameter: what the node does with scans (slam_toolbox picks it by executable:
    ``async_slam_toolbox_node`` maps, ``localization_slam_toolbox_node`` localizes)."""

    MAPPING = "mapping"
    LOCALIZATION = "localization"


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
        raise SessionStartError("match_type = LOCALIZE_AT_POSE (3) is for mode: localization; while mapping, use "
                                "START_AT_GIVEN_POSE (2) to map on from the pose")
    if kind is MatchType.START_AT_FIRST_NODE:
        return None
    return _initial_pose(initial_pose_xy_yaw)


def localization_start_from_request(match_type: int, initial_pose_xy_yaw: Sequence[float]) -> np.ndarray:
    """Where a DeserializePoseGraph request puts the robot in localization mode: ``initial_pose``
    (x m, y m, yaw rad in the map). slam_toolbox's localization node takes ``LOCALIZE_AT_POSE``
    only.

    Raises:
        SessionStartError: any other match type, or a non-finite pose; the message names it.
    """
    if match_type != MatchType.LOCALIZE_AT_POSE:
        named = next((f"{m.name} ({m.value})" for m in MatchType if m.value == match_type), str(match_type))
        raise SessionStartError(f"match_type = {named}: in mode: localization deserialize_map takes "
                                "LOCALIZE_AT_POSE (3) with initial_pose, as slam_toolbox's localization node does")
    return _initial_pose(initial_pose_xy_yaw)


def _initial_pose(initial_pose_xy_yaw: Sequence[float]) -> np.ndarray:
    pose = np.asarray(initial_pose_xy_yaw, dtype=float)
    if pose.shape != (3,) or not np.all(np.isfinite(pose)):
        raise SessionStartError(f"initial_pose = {list(initial_pose_xy_yaw)}: must be a finite x, y, theta")
    return pose
