"""Interface lookup by name and message → YAML (ros2 topic echo's layout)."""
from __future__ import annotations

import pytest
import yaml
from geometry_msgs.msg import TransformStamped, Twist
from tf2_msgs.msg import TFMessage

from pppbot_common.errors import MessageTypeError
from pppbot_common.ros.messages import (
    get_field,
    get_interface,
    message_to_dict,
    message_to_yaml,
    split_type_name,
    type_name_of,
)


@pytest.mark.parametrize("name, parts", [
    ("geometry_msgs/msg/Twist", ("geometry_msgs", "msg", "Twist")),
    ("geometry_msgs/Twist", ("geometry_msgs", "msg", "Twist")),
    ("nav2_msgs/action/NavigateToPose", ("nav2_msgs", "action", "NavigateToPose")),
])
def test_split_type_name(name, parts):
    assert split_type_name(name) == parts


@pytest.mark.parametrize("bad", ["Twist", "geometry_msgs/msg/twist", "a/b/c/D", "", "geometry_msgs/foo/Twist"])
def test_malformed_type_names_are_named_in_the_error(bad):
    with pytest.raises(MessageTypeError, match="not an interface type name"):
        split_type_name(bad)


def test_get_interface_resolves_built_and_wheel_types():
    assert get_interface("tf2_msgs/msg/TFMessage") is TFMessage
    assert get_interface("geometry_msgs/Twist") is Twist
    assert type_name_of(TFMessage) == "tf2_msgs/msg/TFMessage"


def test_get_interface_errors_name_the_missing_part():
    with pytest.raises(MessageTypeError, match="package 'no_such_msgs'"):
        get_interface("no_such_msgs/msg/Thing")
    with pytest.raises(MessageTypeError, match="has no type 'Nope'"):
        get_interface("geometry_msgs/msg/Nope")


def make_tf() -> TFMessage:
    t = TransformStamped()
    t.header.frame_id = "odom"
    t.header.stamp.sec = 7
    t.child_frame_id = "base_link"
    t.transform.translation.x = 1.5
    t.transform.rotation.w = 1.0
    return TFMessage(transforms=[t, t])


def test_yaml_round_trips_and_keeps_field_order():
    text = message_to_yaml(make_tf())
    data = yaml.safe_load(text)
    first = data["transforms"][0]
    assert first["header"] == {"stamp": {"sec": 7, "nanosec": 0}, "frame_id": "odom"}
    assert first["transform"]["translation"] == {"x": 1.5, "y": 0.0, "z": 0.0}
    assert list(first) == ["header", "child_frame_id", "transform"]
    assert text.index("header") < text.index("child_frame_id") < text.index("transform:")


def test_truncation_of_arrays_and_strings():
    data = message_to_dict(make_tf(), truncate_arrays=1, truncate_strings=2)
    assert len(data["transforms"]) == 2 and data["transforms"][1] == "..."
    assert data["transforms"][0]["child_frame_id"] == "ba..."


def test_numpy_backed_arrays_become_lists():
    from sensor_msgs.msg import LaserScan

    scan = LaserScan(ranges=[1.0, 2.0, float("inf")])
    assert message_to_dict(scan)["ranges"] == [1.0, 2.0, float("inf")]


def test_get_field_walks_a_dotted_path():
    msg = make_tf().transforms[0]
    assert get_field(msg, "header.stamp.sec") == 7
    with pytest.raises(MessageTypeError, match="field 'stmp'"):
        get_field(msg, "header.stmp")
