"""Overrides a node never declares are named, once, instead of dropped without a word."""
from __future__ import annotations

from typing import Any

import pytest
from rclpy.node import Node
from rclpy.parameter import Parameter

from pppbot_common.ros.unread_parameters import LISTED, unread_parameters, warn_unread_parameters

pytestmark = pytest.mark.ros


class Reader(Node):
    """Declares ``speed`` only."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("reader", **kwargs)
        self.declare_parameter("speed", 0.5)
        self.parameter_notes: dict[str, str] = {}


def test_the_overrides_a_node_does_not_declare_are_named(ros_node: Any) -> None:
    node = Reader(parameter_overrides=[Parameter("speed", value=1.0), Parameter("FollowPath.plugin", value="dwb"),
                                       Parameter("critics", value=["RotateToGoal"])])
    try:
        assert unread_parameters(node) == ["FollowPath.plugin", "critics"]
        assert node.get_parameter("speed").value == 1.0
    finally:
        node.destroy_node()


def test_a_node_given_only_what_it_reads_says_nothing(ros_node: Any) -> None:
    node = Reader(parameter_overrides=[Parameter("speed", value=1.0)])
    try:
        assert warn_unread_parameters(node) == []
    finally:
        node.destroy_node()


def test_the_warning_lists_a_dozen_and_counts_the_rest(ros_node: Any, caplog: Any) -> None:
    extra = [Parameter(f"key{i:02d}", value=i) for i in range(LISTED + 3)]
    node = Reader(parameter_overrides=extra)
    messages: list[str] = []
    node.get_logger().warning = messages.append
    try:
        assert len(warn_unread_parameters(node)) == LISTED + 3
    finally:
        node.destroy_node()
    assert len(messages) == 1
    assert messages[0].startswith(f"{LISTED + 3} parameters given to reader have no effect")
    assert "key00" in messages[0] and f"key{LISTED - 1:02d}" in messages[0] and "and 3 more" in messages[0]
    assert f"key{LISTED:02d}" not in messages[0]


def test_keys_with_a_note_are_named_with_its_reason(ros_node: Any) -> None:
    node = Reader(parameter_overrides=[Parameter("voxel_layer.scan.max_obstacle_height", value=2.0),
                                       Parameter("always_send_full_costmap", value=True),
                                       Parameter("use_sim_time", value=True), Parameter("mystery", value=1)])
    node.parameter_notes = {"*.*.max_obstacle_height": "planar", "always_send_full_costmap": "always full",
                            "use_sim_time": ""}
    messages: list[str] = []
    node.get_logger().warning = messages.append
    try:
        named = warn_unread_parameters(node)
    finally:
        node.destroy_node()
    assert sorted(named) == ["always_send_full_costmap", "mystery", "voxel_layer.scan.max_obstacle_height"]
    assert "voxel_layer.scan.max_obstacle_height (planar)" in messages[0]
    assert "always_send_full_costmap (always full)" in messages[0]
    assert "mystery (pppbot's reader does not implement them)" in messages[0]
    assert "use_sim_time" not in messages[0]
