"""Where a loaded pose graph has the robot start: slam_toolbox's rules (no ROS)."""
from __future__ import annotations

import numpy as np
import pytest

from pppbot_slam.errors import SessionStartError
from pppbot_slam.session_start import (
    MatchType,
    localization_start_from_request,
    start_from_parameters,
    start_from_request,
)


@pytest.mark.parametrize("at_dock", [True, False])
def test_a_given_map_start_pose_wins_over_the_dock(at_dock: bool):
    np.testing.assert_array_equal(start_from_parameters([1.0, -2.0, 0.5], at_dock), [1.0, -2.0, 0.5])


def test_without_a_pose_the_dock_or_the_origin():
    assert start_from_parameters([], True) is None
    np.testing.assert_array_equal(start_from_parameters([], False), [0.0, 0.0, 0.0])


@pytest.mark.parametrize("pose", [[1.0, 2.0], [0.0, float("nan"), 0.0]])
def test_a_malformed_map_start_pose_is_named(pose: list[float]):
    with pytest.raises(SessionStartError, match="map_start_pose"):
        start_from_parameters(pose, True)


def test_the_request_starts_at_the_first_node_or_the_given_pose():
    assert start_from_request(MatchType.START_AT_FIRST_NODE, (5.0, 5.0, 5.0)) is None
    np.testing.assert_array_equal(start_from_request(MatchType.START_AT_GIVEN_POSE, (0.5, -0.25, 0.1)),
                                  [0.5, -0.25, 0.1])


@pytest.mark.parametrize(("match_type", "named"), [(0, "UNSET"), (3, "LOCALIZE_AT_POSE"), (7, "match_type = 7")])
def test_unset_localize_and_unknown_match_types_are_refused(match_type: int, named: str):
    with pytest.raises(SessionStartError, match=named):
        start_from_request(match_type, (0.0, 0.0, 0.0))


def test_localization_takes_localize_at_pose_only():
    np.testing.assert_array_equal(localization_start_from_request(MatchType.LOCALIZE_AT_POSE, (0.5, -0.25, 0.1)),
                                  [0.5, -0.25, 0.1])
    with pytest.raises(SessionStartError, match="initial_pose"):
        localization_start_from_request(MatchType.LOCALIZE_AT_POSE, (0.5, float("inf"), 0.1))


@pytest.mark.parametrize(("match_type", "named"), [(0, "UNSET"), (1, "START_AT_FIRST_NODE"),
                                                   (2, "START_AT_GIVEN_POSE"), (9, "match_type = 9")])
def test_localization_refuses_the_other_match_types_by_name(match_type: int, named: str):
    with pytest.raises(SessionStartError, match=f"{named}.*takes LOCALIZE_AT_POSE"):
        localization_start_from_request(match_type, (0.0, 0.0, 0.0))
