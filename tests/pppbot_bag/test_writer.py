"""Bag writing round trips: rosbags' reader and the mcap library's reader (decoding with
the stored definitions) get back what was written; splitting, compression, metadata."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest
import yaml
from geometry_msgs.msg import TransformStamped
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rclpy.serialization import serialize_message
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore
from sensor_msgs.msg import LaserScan
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage

from pppbot_bag.definitions import type_definition
from pppbot_bag.errors import BagError
from pppbot_bag.metadata import qos
from pppbot_bag.reader import format_info, summarize
from pppbot_bag.writer import BagWriter, CompressionMode, WriterOptions

JAZZY = get_typestore(Stores.ROS2_JAZZY)
LATCHED = qos(durability="transient_local", depth=1)


def scan(i: int) -> LaserScan:
    msg = LaserScan(angle_min=-3.14, angle_max=3.14, angle_increment=6.28 / 640, range_max=20.0)
    msg.header.stamp.sec, msg.header.frame_id = i, "lidar_frame"
    msg.ranges = [float(i % 7) + 0.001 * k for k in range(639)] + [math.inf]
    return msg


def tf(i: int) -> TFMessage:
    t = TransformStamped(child_frame_id="base_link")
    t.header.frame_id, t.transform.translation.x = "odom", i * 0.5
    return TFMessage(transforms=[t])


def write_bag(path: Path, n: int = 300, **options: object) -> None:
    with BagWriter(path, WriterOptions(**options)) as w:  # type: ignore[arg-type]
        w.add_topic("/scan", type_definition("sensor_msgs/msg/LaserScan"), [qos(reliability="best_effort")])
        w.add_topic("/tf_static", type_definition("tf2_msgs/msg/TFMessage"), [LATCHED])
        w.add_topic("/chatter", type_definition("std_msgs/msg/String"), [qos(), qos(depth=5)])
        w.write("/tf_static", serialize_message(tf(0)), 5)
        for i in range(n):
            stamp = 1_000_000_000 + i * 100_000_000
            w.write("/scan", serialize_message(scan(i)), stamp, stamp - 1000, sequence=i)
            w.write("/chatter", serialize_message(String(data=f"hello {i}")), stamp + 1)


def read_rosbags(path: Path) -> dict[str, list[Any]]:
    out: dict[str, list[Any]] = {}
    with Reader(path) as reader:
        for conn, _, raw in reader.messages():
            out.setdefault(conn.topic, []).append(JAZZY.deserialize_cdr(raw, conn.msgtype))
    return out


@pytest.mark.parametrize("preset", ["none", "fastwrite", "zstd_fast", "zstd_small"])
def test_rosbags_reads_back_every_message_and_field(tmp_path, preset):
    write_bag(tmp_path / "bag", storage_preset=preset)
    got = read_rosbags(tmp_path / "bag")
    assert {k: len(v) for k, v in got.items()} == {"/tf_static": 1, "/scan": 300, "/chatter": 300}
    s = got["/scan"][123]
    assert s.header.stamp.sec == 123 and s.header.frame_id == "lidar_frame"
    assert list(s.ranges[:3]) == pytest.approx([4.0, 4.001, 4.002]) and math.isinf(s.ranges[-1])
    assert got["/chatter"][7].data == "hello 7"
    assert got["/tf_static"][0].transforms[0].child_frame_id == "base_link"


def test_mcap_reader_decodes_with_the_stored_definitions(tmp_path):
    write_bag(tmp_path / "bag", n=20)
    with (tmp_path / "bag" / "bag_0.mcap").open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == "ros2"
        decoded = [(ch.topic, msg.log_time, msg.publish_time, m) for _, ch, msg, m in reader.iter_decoded_messages()]
        summary = reader.get_summary()
        assert summary is not None
        schemas = {s.name: s for s in summary.schemas.values()}
        channels = {c.topic: c for c in summary.channels.values()}
        records = {m.name: m.metadata for m in reader.iter_metadata()}
    scans = [d for d in decoded if d[0] == "/scan"]
    assert len(scans) == 20 and scans[5][1] == 1_500_000_000 and scans[5][2] == 1_500_000_000 - 1000
    assert scans[5][3].header.stamp.sec == 5 and len(scans[5][3].ranges) == 640
    assert [d[3].data for d in decoded if d[0] == "/chatter"][:2] == ["hello 0", "hello 1"]
    assert schemas["tf2_msgs/msg/TFMessage"].encoding == "ros2msg"
    assert b"MSG: geometry_msgs/msg/TransformStamped" in schemas["tf2_msgs/msg/TFMessage"].data
    assert channels["/tf_static"].metadata["topic_type_hash"] == JAZZY.hash_rihs01("tf2_msgs/msg/TFMessage")
    assert yaml.safe_load(channels["/tf_static"].metadata["offered_qos_profiles"])[0]["durability"] == "transient_local"
    per_file = yaml.safe_load(records["rosbag2"]["serialized_metadata"])
    assert per_file["message_count"] == 41 and per_file["version"] == 9


def test_type_hashes_and_definitions_match_jazzys(tmp_path):
    for name in ("sensor_msgs/msg/LaserScan", "nav_msgs/msg/Odometry", "tf2_msgs/msg/TFMessage"):
        definition = type_definition(name)
        assert definition.type_hash == JAZZY.hash_rihs01(name)
        assert definition.encoding == "ros2msg"
        # Every type it refers to is included once, after the delimiter (rosbag2 names
        # them pkg/msg/Name; rosbags' generator pkg/Name).
        msgdef, _ = JAZZY.generate_msgdef(name, ros_version=2)
        ours = sorted(line.replace("/msg/", "/") for line in definition.text.splitlines() if line.startswith("MSG: "))
        assert ours == sorted(line for line in msgdef.splitlines() if line.startswith("MSG: "))
        assert len(ours) == len(set(ours)) > 0


def test_metadata_yaml_is_version_9_with_counts_and_qos(tmp_path):
    write_bag(tmp_path / "bag", n=10)
    info = yaml.safe_load((tmp_path / "bag" / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["version"] == 9 and info["storage_identifier"] == "mcap" and info["ros_distro"] == "jazzy"
    assert info["relative_file_paths"] == ["bag_0.mcap"] and info["message_count"] == 21
    assert info["starting_time"]["nanoseconds_since_epoch"] == 5
    assert info["duration"]["nanoseconds"] == 1_900_000_001 - 5
    topics = {t["topic_metadata"]["name"]: t for t in info["topics_with_message_count"]}
    assert topics["/chatter"]["message_count"] == 10
    assert [q["depth"] for q in topics["/chatter"]["topic_metadata"]["offered_qos_profiles"]] == [10, 5]
    assert topics["/scan"]["topic_metadata"]["offered_qos_profiles"][0]["reliability"] == "best_effort"


@pytest.mark.parametrize("split", [{"max_bag_size": 200_000}, {"max_bag_duration_s": 7.0}])
def test_split_bags_have_valid_files_that_together_hold_everything(tmp_path, split):
    write_bag(tmp_path / "bag", n=300, **split)
    files = sorted((tmp_path / "bag").glob("bag_*.mcap"))
    assert len(files) >= 3
    total = 0
    for f in files:
        with f.open("rb") as stream:
            summary = make_reader(stream).get_summary()
        assert summary is not None and summary.statistics is not None
        total += summary.statistics.message_count
        if "max_bag_size" in split and f != files[-1]:
            assert f.stat().st_size <= 200_000 * 1.05
        if "max_bag_duration_s" in split:
            s = summary.statistics
            assert s.message_end_time - s.message_start_time < 7.0e9 + 1
    assert total == 601
    assert {k: len(v) for k, v in read_rosbags(tmp_path / "bag").items()} == {
        "/tf_static": 1, "/scan": 300, "/chatter": 300}
    info = summarize(tmp_path / "bag")
    assert info.files == [f.name for f in files] and info.message_count == 601


@pytest.mark.parametrize("mode", ["file", "message"])
def test_compressed_bags_read_back(tmp_path, mode):
    write_bag(tmp_path / "bag", n=200, max_bag_size=100_000, compression_mode=CompressionMode(mode))
    info = yaml.safe_load((tmp_path / "bag" / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert (info["compression_mode"], info["compression_format"]) == (mode, "zstd")
    if mode == "file":
        assert all(p.endswith(".mcap.zstd") for p in info["relative_file_paths"])
        assert not list((tmp_path / "bag").glob("*.mcap"))
    got = read_rosbags(tmp_path / "bag")
    assert len(got["/scan"]) == 200 and got["/chatter"][199].data == "hello 199"
    assert "Compression:       " + mode in format_info(summarize(tmp_path / "bag"))


def test_never_overwrites_and_refuses_misuse(tmp_path):
    (tmp_path / "bag").mkdir()
    with pytest.raises(BagError, match="exists already"):
        BagWriter(tmp_path / "bag")
    w = BagWriter(tmp_path / "new")
    with pytest.raises(BagError, match="not added"):
        w.write("/nope", b"\x00\x01\x00\x00", 1)
    w.add_topic("/a", type_definition("std_msgs/msg/String"), [qos()])
    with pytest.raises(BagError, match="already in the bag"):
        w.add_topic("/a", type_definition("std_msgs/msg/String"), [qos()])
    w.close()
    with pytest.raises(BagError, match="closed"):
        w.write("/a", b"", 1)


@pytest.mark.parametrize("options, message", [
    ({"max_bag_size": 500}, "at least 1024"),
    ({"max_bag_size": -1}, "max_bag_size -1"),
    ({"max_bag_duration_s": math.nan}, "max_bag_duration nan"),
    ({"compression_format": "lz4"}, "allowed: zstd"),
    ({"storage_preset": "fast"}, "allowed: none, fastwrite"),
])
def test_bad_options_are_named(tmp_path, options, message):
    with pytest.raises(BagError, match=message):
        BagWriter(tmp_path / "bag", WriterOptions(**options))
    assert not (tmp_path / "bag").exists()
