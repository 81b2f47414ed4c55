"""A bag whose metadata.yaml is not rosbag2 metadata: one message naming the file and what is wrong."""
from __future__ import annotations

import re
from pathlib import Path

import pytest
from rclpy.serialization import serialize_message
from std_msgs.msg import String

from pppbot_bag.definitions import type_definition
from pppbot_bag.errors import BagError
from pppbot_bag.metadata import check_metadata_file, qos
from pppbot_bag.reader import open_bag, summarize
from pppbot_bag.writer import BagWriter, WriterOptions


def small_bag(tmp_path: Path) -> Path:
    writer = BagWriter(tmp_path / "bag", WriterOptions())
    writer.add_topic("/chatter", type_definition("std_msgs/msg/String"), [qos()])
    writer.write("/chatter", serialize_message(String(data="hi")), 1_000)
    writer.close()
    return tmp_path / "bag"


def test_a_written_bags_metadata_passes(tmp_path):
    info = check_metadata_file(small_bag(tmp_path) / "metadata.yaml")
    assert info["message_count"] == 1
    assert info["topics_with_message_count"][0]["topic_metadata"]["name"] == "/chatter"


@pytest.mark.parametrize("content, message", [
    (b"\x00\x01\xff\xfe binary", "line 1, column 3: not a text file: byte 0xff is not UTF-8"),
    (b"- a\n- b\n", "not rosbag2 metadata (it holds ['a', 'b'], not a mapping)"),
    (b"", "not rosbag2 metadata (it is empty)"),
    (b"rosbag2_bagfile_information: [1]\n", "'rosbag2_bagfile_information' is missing or not a mapping"),
    (b"rosbag2_bagfile_information:\n  version: [\n", "line 3, column 1: not valid YAML"),
    (b"rosbag2_bagfile_information:\n  version: 9\n", "rosbag2_bagfile_information has no 'storage_identifier'"),
])
def test_a_bad_metadata_file_is_named_with_what_is_wrong(tmp_path, content, message):
    bag = small_bag(tmp_path)
    (bag / "metadata.yaml").write_bytes(content)
    with pytest.raises(BagError) as info:
        summarize(bag)
    assert str(info.value).startswith(f"{bag / 'metadata.yaml'}: ")
    assert message in str(info.value)


@pytest.mark.parametrize("old, new, message", [
    ("message_count: 1\n", "message_count: many\n", "rosbag2_bagfile_information.message_count must be a whole number"),
    ("version: 9", "version: 10", "rosbag2 metadata version 10 is not supported (1 to 9)"),
    ("- topic_metadata:", "- topic_data:", "topics_with_message_count[0] must be"),
])
def test_a_bad_field_is_named(tmp_path, old, new, message):
    bag = small_bag(tmp_path)
    text = (bag / "metadata.yaml").read_text()
    assert old in text
    (bag / "metadata.yaml").write_text(text.replace(old, new, 1))
    with pytest.raises(BagError, match=re.escape(message)), \
            open_bag(bag):
        pass
