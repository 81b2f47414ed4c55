"""A bag whose recorder died mid-file: every flushed chunk comes back with `reindex`."""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import yaml
from rclpy.serialization import serialize_message
from rosbags.rosbag2 import Reader
from std_msgs.msg import String

from pppbot_bag.definitions import type_definition
from pppbot_bag.errors import BagError
from pppbot_bag.metadata import BagMetadata, qos
from pppbot_bag.reader import open_bag
from pppbot_bag.recover import reindex, salvaged
from pppbot_bag.writer import BagWriter, CompressionMode, WriterOptions


def killed_bag(tmp_path: Path, options: WriterOptions, flushed: int, unflushed: int) -> Path:
    """The bag directory as a SIGKILL would leave it: ``flushed`` messages in closed
    chunks, ``unflushed`` more still in memory."""
    writer = BagWriter(tmp_path / "live", options)
    writer.add_topic("/chatter", type_definition("std_msgs/msg/String"), [qos()])
    for i in range(flushed + unflushed):
        writer.write("/chatter", serialize_message(String(data=f"m{i}")), 1_000 + i)
        if i + 1 == flushed:
            writer.flush()
    for job in writer._compressing:  # finished files are compressed by then (a steady state to copy)
        job.result()
    shutil.copytree(tmp_path / "live", tmp_path / "killed")  # the disk at the moment of the kill
    writer.close()
    return tmp_path / "killed"


@pytest.mark.parametrize("mode", [CompressionMode.NONE, CompressionMode.MESSAGE])
def test_reindex_recovers_every_flushed_message(tmp_path, mode):
    bag = killed_bag(tmp_path, WriterOptions(compression_mode=mode, max_bag_size=20_000), 1500, 7)
    # as killed: the files lack their summaries
    with pytest.raises(BagError, match="bag reindex"), open_bag(bag) as reader:
        list(reader.messages())
    report = reindex(bag)
    assert "finished the unfinished file" in report
    with Reader(bag) as reader:
        data = [raw for _, _, raw in reader.messages()]
    assert len(data) >= 1500
    assert [bytes(d) for d in data[:2]] == [serialize_message(String(data="m0")),
                                            serialize_message(String(data="m1"))]
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["compression_mode"] == ("message" if mode is CompressionMode.MESSAGE else "")
    assert info["topics_with_message_count"][0]["message_count"] == len(data)
    assert list(bag.glob("*.unfinished"))  # the original is kept


def test_reindex_of_a_killed_file_compressed_split_bag_compresses_the_last_file(tmp_path):
    bag = killed_bag(tmp_path, WriterOptions(compression_mode=CompressionMode.FILE, max_bag_size=5_000), 1500, 3)
    assert list(bag.glob("*.mcap.zstd")) and list(bag.glob("*.mcap"))  # finished files and the open one
    reindex(bag)
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["compression_mode"] == "file"
    assert all(p.endswith(".mcap.zstd") for p in info["relative_file_paths"])
    with Reader(bag) as reader:
        assert sum(1 for _ in reader.messages()) >= 1500


def test_reindex_of_a_finished_bag_changes_nothing_but_metadata(tmp_path):
    bag = tmp_path / "bag"
    with BagWriter(bag, WriterOptions(compression_mode=CompressionMode.FILE, max_bag_size=5_000)) as w:
        w.add_topic("/chatter", type_definition("std_msgs/msg/String"), [qos()])
        for i in range(2000):
            w.write("/chatter", serialize_message(String(data=f"m{i}")), 1_000 + i)
    before = yaml.safe_load((bag / "metadata.yaml").read_text())
    (bag / "metadata.yaml").unlink()
    reindex(bag)
    after = yaml.safe_load((bag / "metadata.yaml").read_text())
    assert after == before
    assert not list(bag.glob("*.unfinished"))


def test_reindex_refuses_what_is_not_a_bag(tmp_path):
    with pytest.raises(BagError, match="no .mcap files"):
        reindex(tmp_path)
    with pytest.raises(BagError, match="not a bag directory"):
        reindex(tmp_path / "missing")


def test_a_bag_without_metadata_says_how_to_recover(tmp_path):
    bag = killed_bag(tmp_path, WriterOptions(), 10, 0)
    (bag / "metadata.yaml").unlink()
    with pytest.raises(BagError, match="bag reindex"), open_bag(bag):
        pass


def test_a_killed_bag_salvaged_is_recorded_on_into_as_its_next_file(tmp_path):
    bag = killed_bag(tmp_path, WriterOptions(), 1200, 5)
    metadata, report = salvaged(bag)
    assert report.startswith(f"reindexed '{bag}': 1 file(s), 1200 messages")
    with BagWriter(bag, WriterOptions(), continuing=metadata) as writer:
        with pytest.raises(BagError, match="'/chatter' is already in the bag as std_msgs/msg/String, not "):
            writer.add_topic("/chatter", type_definition("std_msgs/msg/Int32"), [qos()])
        writer.add_topic("/chatter", type_definition("std_msgs/msg/String"), [qos()])  # recorded on
        writer.add_topic("/other", type_definition("std_msgs/msg/String"), [qos()])
        for i in range(1300, 1310):
            writer.write("/chatter", serialize_message(String(data=f"m{i}")), 10_000 + i)
        writer.write("/other", serialize_message(String(data="o")), 20_000)
    with Reader(bag) as reader:  # an independent reader: both recordings, in order, one bag
        chatter = [bytes(raw) for c, _, raw in reader.messages() if c.topic == "/chatter"]
        assert {c.topic: c.msgcount for c in reader.connections} == {"/chatter": 1210, "/other": 1}
    assert chatter == [serialize_message(String(data=f"m{i}")) for i in [*range(1200), *range(1300, 1310)]]
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    # (the first file was written as 'live' and copied to 'killed': the next is named after the bag)
    assert info["relative_file_paths"] == ["live_0.mcap", "killed_1.mcap"] and info["message_count"] == 1211


def test_a_bag_is_recorded_on_into_only_with_its_own_compression(tmp_path):
    bag = killed_bag(tmp_path, WriterOptions(compression_mode=CompressionMode.MESSAGE), 100, 0)
    with pytest.raises(BagError, match="compression mode 'message'; recording on into it needs the same"):
        BagWriter(bag, WriterOptions(), continuing=salvaged(bag)[0])
    with pytest.raises(BagError, match="exists already; pppbot never overwrites a bag"):
        BagWriter(bag, WriterOptions(compression_mode=CompressionMode.MESSAGE))


def test_recording_on_numbers_the_next_file_after_the_highest_and_a_bag_killed_before_its_first_file_starts_anew(
        tmp_path):
    bag = killed_bag(tmp_path, WriterOptions(max_bag_size=5_000), 1500, 0)
    (bag / "live_0.mcap").unlink()  # a gap in the numbering: the files left are live_1 ... live_N
    metadata, _ = salvaged(bag)
    last = max(int(f.path.split("_")[-1].split(".")[0]) for f in metadata.files)
    with BagWriter(bag, WriterOptions(max_bag_size=5_000), continuing=metadata) as writer:
        writer.add_topic("/chatter", type_definition("std_msgs/msg/String"), [qos()])
        writer.write("/chatter", serialize_message(String(data="after")), 99_000)
    assert writer.metadata.files[-1].path == f"killed_{last + 1}.mcap"
    empty = tmp_path / "empty"
    empty.mkdir()
    with BagWriter(empty, WriterOptions(), continuing=BagMetadata()) as writer:
        writer.add_topic("/chatter", type_definition("std_msgs/msg/String"), [qos()])
        writer.write("/chatter", serialize_message(String(data="first")), 1)
    with Reader(empty) as reader:
        assert [bytes(raw) for _, _, raw in reader.messages()] == [serialize_message(String(data="first"))]
