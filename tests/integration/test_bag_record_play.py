"""`pppbot bag record/play/info/reindex` against live nodes over DDS.

One recording of the running simulator (20 sim-seconds, all topics, sim time) is
made for the module; the tests check it for loss, read it back with two independent
readers, and play it into a subscriber. Other tests stop recorders with SIGTERM and
SIGKILL.
"""
from __future__ import annotations

import re
import signal
import statistics
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import rclpy
import yaml
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import LaserScan
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage

from pppbot_common.dds_shm import clean_stale
from pppbot_common.errors import TimeoutExpired
from pppbot_common.process import ChildProcess, StopTimeouts
from pppbot_common.ros.wait import wait_until

pytestmark = pytest.mark.ros
ROOT = Path(__file__).resolve().parents[2]
PPPBOT = str(ROOT / "pppbot")
BOX_ROOM = str(ROOT / "tests" / "pppbot_sim" / "data" / "box_room.sdf")
SCRIPTS = ROOT / "tests" / "scripts"
JAZZY = get_typestore(Stores.ROS2_JAZZY)


def decode(raw: Any, msgtype: str) -> Any:
    """A CDR message as rosbags' Jazzy typestore reads it (an independent reader)."""
    return JAZZY.deserialize_cdr(raw, msgtype)
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: The simulator's publishing periods (its defaults and the robot's sensor rates), seconds.
PERIODS = {"/clock": 0.01, "/joint_states": 0.01, "/imu": 0.01, "/ground_truth/odom": 0.02, "/scan": 0.1}
RECORD_SIM_S = 20.0


class IsolatedNode:
    """An rclpy node in a context of its own, spun on demand."""

    def __init__(self, name: str) -> None:
        self.context = Context()
        rclpy.init(context=self.context)
        self.node = Node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)

    def spin_until(self, condition: Any, timeout_s: float, what: str) -> Any:
        deadline = time.monotonic() + timeout_s
        while not (value := condition()):
            if time.monotonic() > deadline:
                raise TimeoutExpired(f"timed out after {timeout_s:.1f} s waiting for {what}")
            self.executor.spin_once(timeout_sec=0.02)
        return value

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)


def stamp_s(msg: Any, topic: str) -> float:
    t = msg.clock if topic == "/clock" else msg.header.stamp
    return t.sec + t.nanosec * 1e-9


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Path, str]]:
    """A bag of the simulator (rtf 2) and a latched topic, recorded with -a --use-sim-time."""
    bag = tmp_path_factory.mktemp("rec") / "sim_bag"
    test = IsolatedNode("bag_test_latched")
    latched = test.node.create_publisher(String, "/latched_note", LATCHED)
    latched.publish(String(data="published before the recorder started"))
    sim_time = {"s": 0.0}
    test.node.create_subscription(Clock, "/clock", lambda m: sim_time.update(s=stamp_s(m, "/clock")), 10)
    with ChildProcess([PPPBOT, "run", "pppbot_sim", "simulator", "--ros-args", "-p", f"world:={BOX_ROOM}",
                       "-p", "real_time_factor:=2.0"], name="simulator") as sim:
        sim.wait_for_output(r"lidar 'laser': 640 beams", 60)
        with ChildProcess([PPPBOT, "bag", "record", "-a", "--use-sim-time", "-o", str(bag)],
                          name="recorder", timeouts=StopTimeouts(20.0, 5.0)) as recorder:
            recorder.wait_for_lines(r"subscribed to '(/scan|/latched_note|/clock|/imu)'", 4, 60)
            start = test.spin_until(lambda: sim_time["s"] or None, 30, "/clock")
            test.spin_until(lambda: sim_time["s"] - start > RECORD_SIM_S + 0.5, 120, "20 sim-seconds")
            recorder.proc.send_signal(signal.SIGINT)
            assert recorder.wait(30) == 0
            output = recorder.output
    test.close()
    yield bag, output


def summary_count(output: str, topic: str) -> int:
    """The count the recorder printed for ``topic`` at the end."""
    counts = [int(line.split()[1]) for line in output.splitlines() if line.split()[:1] == [topic]]
    assert len(counts) == 1, output[-2000:]
    return counts[0]


def read_all(bag: Path) -> dict[str, list[tuple[int, bytes]]]:
    out: dict[str, list[tuple[int, bytes]]] = {}
    with Reader(bag) as reader:
        for conn, stamp, raw in reader.messages():
            out.setdefault(conn.topic, []).append((stamp, bytes(raw)))
    return out


def test_nothing_the_simulator_published_is_lost(recording):
    bag, output = recording
    messages = read_all(bag)
    with Reader(bag) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
    for topic, period in PERIODS.items():
        stamps = np.array([stamp_s(decode(raw, types[topic]), topic) for _, raw in messages[topic]])
        gaps = np.diff(stamps)
        span = stamps[-1] - stamps[0]
        assert span > RECORD_SIM_S - 1.0, topic
        # Contiguous: no gap longer than one period (plus one 2 ms physics step of jitter),
        # and as many messages as the span holds.
        assert gaps.max() < period + 0.0025, (topic, gaps.max())
        assert abs(len(stamps) - (round(span / period) + 1)) <= 1, (topic, len(stamps), span)
        # The recorder's own summary agrees with the bag.
        assert summary_count(output, topic) == len(stamps)
    # Latched: delivered to the recorder although published before it started.
    note = messages["/latched_note"]
    assert len(note) == 1 and decode(note[0][1], "std_msgs/msg/String").data.startswith("published")
    # Receive times are sim time (the simulator started at 0).
    first = min(stamp for msgs in messages.values() for stamp, _ in msgs)
    assert 0 < first < 120e9


def test_the_mcap_reader_decodes_the_same_messages(recording):
    bag, _ = recording
    ours = read_all(bag)
    theirs: dict[str, list[tuple[int, Any]]] = {}
    for path in sorted(bag.glob("*.mcap")):
        with path.open("rb") as f:
            reader = make_reader(f, decoder_factories=[DecoderFactory()])
            for _, channel, message, decoded in reader.iter_decoded_messages():
                theirs.setdefault(channel.topic, []).append((message.log_time, decoded))
    assert {k: len(v) for k, v in theirs.items()} == {k: len(v) for k, v in ours.items()}
    for (stamp_a, raw), (stamp_b, decoded) in zip(ours["/scan"], theirs["/scan"], strict=True):
        mine = decode(raw, "sensor_msgs/msg/LaserScan")
        assert stamp_a == stamp_b
        assert list(mine.ranges) == list(decoded.ranges) and len(decoded.ranges) == 640
        assert decoded.header.frame_id == "lidar_frame"


def test_info_summarizes_the_recording(recording):
    bag, _ = recording
    info = subprocess.run([PPPBOT, "bag", "info", str(bag)], capture_output=True, text=True, timeout=60)
    assert info.returncode == 0, info.stderr
    counts = {topic: len(msgs) for topic, msgs in read_all(bag).items()}
    assert f"Messages:          {sum(counts.values())}" in info.stdout
    assert "Storage id:        mcap" in info.stdout
    for topic, count in counts.items():
        assert any(f"Topic: {topic} " in line and f"| Count: {count} |" in line for line in info.stdout.splitlines())


def test_play_publishes_the_recorded_bytes_into_a_subscriber(recording):
    bag, _ = recording
    messages = read_all(bag)
    recorded = [raw for _, raw in messages["/scan"]]
    test = IsolatedNode("bag_test_player_sink")
    got: list[bytes] = []
    clock: list[float] = []
    test.node.create_subscription(LaserScan, "/scan_replay", lambda m: got.append(serialize_message(m)),
                                  QoSProfile(depth=1000))
    test.node.create_subscription(Clock, "/clock", lambda m: clock.append(stamp_s(m, "/clock")), 10)
    try:
        with ChildProcess([PPPBOT, "bag", "play", str(bag), "--topics", "/scan", "--remap", "/scan:=/scan_replay",
                           # --delay: time for discovery before the first message (2 s was too
                           # little once, on a machine running two other jobs)
                           "--rate", "5", "--clock", "50", "--delay", "5"], name="player") as player:
            test.spin_until(lambda: player.proc.poll() is not None, 60, "the player to finish")
            assert player.wait(5) == 0
            test.spin_until(lambda: len(got) >= len(recorded), 5,
                            f"the last messages ({len(got)} of {len(recorded)}); player said:\n{player.output}")
    finally:
        test.close()
    assert got == recorded
    assert f"published {len(recorded)} messages" in player.output
    # /clock carried the bag's time, which starts where the recording started: at the bag's
    # first message of any topic, as rosbag2's player does, even with --topics choosing fewer
    # (the recorder may subscribe /clock a second before /scan on a loaded machine).
    bag_start = min(stamps[0][0] for stamps in messages.values()) / 1e9
    first_scan = messages["/scan"][0][0] / 1e9
    assert clock and min(clock) >= bag_start - 0.5 and statistics.median(clock) > first_scan


def record_talker(tmp_path: Path, limit_kib: int | None = None) -> tuple[ChildProcess, ChildProcess, Path]:
    """The talker at 50 Hz and a recorder of its topics; with ``limit_kib``, files the recorder
    writes cannot grow beyond that (``ulimit -f``, as a full disk stops them)."""
    talker = ChildProcess([sys.executable, str(SCRIPTS / "publish_tf_and_particles.py"), "50"], name="talker")
    talker.wait_for_output(r"^ready$", 30)
    bag = tmp_path / "talk"
    record = [PPPBOT, "bag", "record", "/tf", "/particle_cloud", "-o", str(bag)]
    if limit_kib is not None:
        record = ["bash", "-c", f'ulimit -f {limit_kib} && exec "$@"', "record", *record]
    recorder = ChildProcess(record, name="recorder", timeouts=StopTimeouts(20.0, 5.0))
    recorder.wait_for_lines(r"subscribed to '/(tf|particle_cloud)'", 2, 60)
    return talker, recorder, bag


def recorded_tf_numbers(bag: Path) -> list[int]:
    """The talker's numbers of the /tf messages in ``bag``, read by rosbags."""
    with Reader(bag) as reader:
        return [decode(raw, c.msgtype).transforms[0].header.stamp.nanosec
                for c, _, raw in reader.messages() if c.topic == "/tf"]


def test_sigterm_finishes_the_bag(tmp_path):
    talker, recorder, bag = record_talker(tmp_path)
    with talker, recorder:
        wait_until(lambda: recorder.proc.poll() is None and len(list(bag.glob("*.mcap"))) == 1, 10, "bag file")
        time.sleep(2.0)
        recorder.proc.send_signal(signal.SIGTERM)
        assert recorder.wait(30) == 0
    with Reader(bag) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        tf_nanosec = [decode(raw, c.msgtype).transforms[0].header.stamp.nanosec
                      for c, _, raw in reader.messages() if c.topic == "/tf"]
    assert counts["/tf"] >= 20 and counts["/particle_cloud"] >= 20
    # In order and without gaps (the talker numbers its messages).
    assert tf_nanosec == list(range(tf_nanosec[0], tf_nanosec[0] + len(tf_nanosec)))
    assert summary_count(recorder.output, "/tf") == counts["/tf"]


def test_a_killed_recorder_leaves_a_bag_that_reindex_recovers_to_the_last_second(tmp_path):
    listener = IsolatedNode("bag_test_kill")
    heard: list[int] = []
    def on_tf(msg: Any) -> None:
        heard.append(msg.transforms[0].header.stamp.nanosec)

    listener.node.create_subscription(TFMessage, "/tf", on_tf, 50)
    try:
        talker, recorder, bag = record_talker(tmp_path)
        with talker, recorder:
            listener.spin_until(lambda: heard, 30, "the talker")
            first = heard[-1]
            listener.spin_until(lambda: heard[-1] >= first + 150, 60, "3 s of /tf (three chunk flushes)")
            recorder.proc.send_signal(signal.SIGKILL)
            last_heard = heard[-1]
            recorder.wait(10)
    finally:
        listener.close()
    fixed = subprocess.run([PPPBOT, "bag", "reindex", str(bag)], capture_output=True, text=True, timeout=60)
    assert fixed.returncode == 0, fixed.stderr
    numbers = recorded_tf_numbers(bag)
    assert numbers == list(range(numbers[0], numbers[0] + len(numbers)))  # in order, without gaps
    # What was lost is what came in the last second before the kill (the recorder flushes every second), and
    # what DDS had not handed over yet (a few messages): 50 Hz, so at most 50 + 10 of what the test heard.
    assert numbers[-1] >= last_heard - 60, (numbers[-1], last_heard)


def test_a_killed_recorder_started_again_with_resume_records_on_into_its_own_bag(tmp_path):
    listener = IsolatedNode("bag_test_resume")
    heard: list[int] = []

    def on_tf(msg: Any) -> None:
        heard.append(msg.transforms[0].header.stamp.nanosec)

    listener.node.create_subscription(TFMessage, "/tf", on_tf, 50)
    try:
        talker, recorder, bag = record_talker(tmp_path)
        with talker:
            with recorder:
                listener.spin_until(lambda: heard, 30, "the talker")
                first = heard[-1]
                listener.spin_until(lambda: heard[-1] >= first + 100, 60, "2 s of /tf")
                recorder.proc.send_signal(signal.SIGKILL)
                killed_at = heard[-1]
                recorder.wait(10)
            clean_stale()  # as the launch does before it starts a killed node again
            again = ChildProcess([PPPBOT, "bag", "record", "/tf", "/particle_cloud", "-o", str(bag), "--resume"],
                                 name="recorder again", timeouts=StopTimeouts(20.0, 5.0))
            with again:
                again.wait_for_lines(r"subscribed to '/(tf|particle_cloud)'", 2, 60)
                second = bag / "talk_1.mcap"
                wait_until(second.exists, 30, "the second recorder's file")
                opened = second.stat().st_size
                # Matched once a chunk of messages reached the file (flushed every second); then 2 s more.
                wait_until(lambda: second.stat().st_size > opened + 2000, 60, "the second recorder's messages")
                count = len(heard)  # what the listener holds but has not handled: at most its depth, 50
                listener.spin_until(lambda: len(heard) >= count + 150, 60, "2 s more of /tf")
                again.proc.send_signal(signal.SIGTERM)
                assert again.wait(30) == 0
    finally:
        listener.close()
    assert f"recording on into '{bag}' (reindexed '{bag}': 1 file(s)" in again.output
    numbers = recorded_tf_numbers(bag)  # both recordings, one bag, by an independent reader
    gaps = [(a, b) for a, b in zip(numbers, numbers[1:], strict=False) if b != a + 1]
    # In order: what the first kept (to the last second before its kill), then what the second recorded.
    assert len(gaps) == 1 and gaps[0][0] < gaps[0][1], gaps
    (end_first, start_second), = gaps
    assert end_first >= killed_at - 60 and numbers[-1] - start_second >= 100, (end_first, killed_at, numbers[-1])
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["relative_file_paths"] == ["talk_0.mcap", "talk_1.mcap"]
    counts = {t["topic_metadata"]["name"]: t["message_count"] for t in info["topics_with_message_count"]}
    assert counts["/tf"] == len(numbers) and summary_count(again.output, "/tf") == len(numbers)


def test_a_full_disk_ends_the_recording_with_one_message_and_a_readable_bag(tmp_path):
    talker, recorder, bag = record_talker(tmp_path, limit_kib=60)
    with talker, recorder:
        assert recorder.wait(120) == 1  # it stops by itself when the file can grow no more
    failed = [line for line in recorder.output.splitlines() if "pppbot bag record:" in line]
    assert len(failed) == 1 and f"writing '{bag}' failed, recording stopped: File too large" in failed[0], failed
    assert "the bag is readable" in failed[0]
    kept = re.search(r"(\d+) messages", failed[0])
    assert kept is not None
    numbers = recorded_tf_numbers(bag)  # read as it was left, by an independent reader
    assert numbers == list(range(numbers[0], numbers[0] + len(numbers))) and len(numbers) >= 250  # 5 s and more
    with (bag / "talk_0.mcap").open("rb") as f:  # the file on its own, by the MCAP project's reader
        assert sum(1 for _ in make_reader(f).iter_messages()) == int(kept.group(1))
    assert sum(f.stat().st_size for f in bag.glob("*.mcap")) <= 60 * 1024
