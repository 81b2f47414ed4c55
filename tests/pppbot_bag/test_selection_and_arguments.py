"""Topic selection, remapping and `bag` argument checks (no ROS needed)."""
from __future__ import annotations

import argparse
import re

import pytest

from pppbot_bag import cli
from pppbot_bag.errors import BagError
from pppbot_bag.selection import Remapping, TopicSelection, compile_regex


def test_selection_by_name_regex_exclusion_and_hidden():
    s = TopicSelection(topics=("scan", "/_hidden/named"), regex=compile_regex("/odom.*", "-e"),
                       exclude_regex=compile_regex(".*/raw", "-x"))
    assert s.matches("/scan") and s.matches("/odom") and s.matches("/odom/filtered")
    assert s.matches("/_hidden/named")  # named explicitly
    assert not s.matches("/odom/raw") and not s.matches("/imu") and not s.matches("/scan_x")
    every = TopicSelection(all_topics=True, exclude_topics=("/rosout",))
    assert every.matches("/tf") and not every.matches("/rosout") and not every.matches("/a/_action/status")
    assert TopicSelection(all_topics=True, include_hidden=True).matches("/a/_action/status")


def test_remapping():
    remap = Remapping.parse(["/scan:=/scan_bag", "odom:=old_odom"])
    assert remap("/scan") == "/scan_bag" and remap("/odom") == "/old_odom" and remap("/tf") == "/tf"
    with pytest.raises(BagError, match="old_topic:=new_topic"):
        Remapping.parse(["/scan=/x"])
    with pytest.raises(BagError, match="not a valid topic name"):
        Remapping.parse(["/scan:=bad topic"])


def parse(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    cli.add_arguments(parser)
    return parser.parse_args(argv)


def test_record_options_follow_ros2_bag(tmp_path):
    o = cli.record_options(parse("record", "/scan", "--topics", "/odom", "-o", str(tmp_path / "b"),
                                 "-b", "2048", "-d", "30", "--compression-mode", "file", "--use-sim-time"),
                           now=0)
    assert o.selection.topics == ("/scan", "/odom") and o.writer.max_bag_size == 2048
    assert o.writer.max_bag_duration_s == 30 and o.writer.compression_mode.value == "file" and o.use_sim_time
    default = cli.record_options(parse("record", "-a"), now=86400 * 365 + 43200)
    assert re.fullmatch(r"rosbag2_1971_01_0[12]-\d\d_00_00", default.output.name)


@pytest.mark.parametrize("argv, message", [
    (("record",), "nothing to record"),
    (("record", "-e", "(unclosed"), "--regex '(unclosed' is not a valid regular expression"),
    (("record", "-a", "-b", "100"), "at least 1024"),
    (("record", "bad topic"), "'bad topic' is not a valid topic name"),
])
def test_bad_record_arguments_are_refused_before_anything_starts(argv, message, capsys):
    assert cli.main(parse(*argv)) == 1
    assert message in capsys.readouterr().err


def test_existing_output_is_refused(tmp_path, capsys):
    (tmp_path / "taken").mkdir()
    assert cli.main(parse("record", "-a", "-o", str(tmp_path / "taken"))) == 1
    assert "exists already" in capsys.readouterr().err


@pytest.mark.parametrize("argv", [("record", "-a", "-d", "-1"), ("record", "-a", "-b", "1.5"),
                                  ("play", "x", "--rate", "0"), ("record", "-a", "--compression-mode", "lz4"),
                                  ("play", "x", "--wait-for-all-acked", "-2"),
                                  ("play", "x", "--wait-for-all-acked", "0.5")])
def test_argparse_refuses_bad_values(argv, capsys):
    with pytest.raises(SystemExit) as exit_:
        parse(*argv)
    assert exit_.value.code == 2 and "error: argument" in capsys.readouterr().err


def test_play_waits_for_acknowledgements_by_default():
    assert cli.play_options(parse("play", "x")).wait_for_all_acked_ms == 1000
    assert cli.play_options(parse("play", "x", "--wait-for-all-acked", "-1")).wait_for_all_acked_ms == -1
    assert cli.play_options(parse("play", "x", "--wait-for-all-acked", "0")).wait_for_all_acked_ms == 0


def test_info_of_a_missing_bag(tmp_path, capsys):
    assert cli.main(parse("info", str(tmp_path / "nope"))) == 1
    assert f"bag '{tmp_path / 'nope'}' does not exist" in capsys.readouterr().err
