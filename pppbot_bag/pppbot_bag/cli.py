"""``pppbot bag record|play|info|reindex|from-carmen``: record, play, inspect and reindex rosbag2 (MCAP) bags, like
``ros2 bag``; and turn a real robot's CARMEN laser log into one.

Arguments are parsed and checked here (no rclpy), so a bad flag is refused before any
node starts; recording and playing run in ``pppbot_bag.ros.record`` and
``pppbot_bag.ros.play``.
"""
from __future__ import annotations

import argparse
import importlib
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from pppbot_bag.errors import BagError
from pppbot_bag.reader import format_info, summarize
from pppbot_bag.selection import Remapping, TopicSelection, compile_regex
from pppbot_bag.writer import STORAGE_PRESETS, CompressionMode, WriterOptions


@dataclass(frozen=True)
class RecordOptions:
    output: Path
    selection: TopicSelection
    writer: WriterOptions
    use_sim_time: bool = False
    polling_interval_s: float = 0.1
    node_name: str = "rosbag2_recorder"
    include_unpublished_topics: bool = False
    discovery: bool = True
    flush_period_s: float = 1.0
    #: the output may exist: a recording stopped or killed, finished first and recorded on into
    resume: bool = False


@dataclass(frozen=True)
class PlayOptions:
    bag: Path
    selection: TopicSelection
    remap: Remapping
    rate: float = 1.0
    loop: bool = False
    clock_hz: float = 0.0
    start_offset_s: float = 0.0
    delay_s: float = 0.0
    start_paused: bool = False
    keyboard_controls: bool = True
    node_name: str = "rosbag2_player"
    wait_for_all_acked_ms: int = 1000


def _size(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a whole number of bytes") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be 0 (no splitting) or a number of bytes, not {text}")
    return value


def _non_negative(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a number") from None
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, not {text}")
    return value


def _acked_timeout(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'{text}' is not a whole number of milliseconds") from None
    if value < -1:
        raise argparse.ArgumentTypeError(f"must be milliseconds >= 0, or -1 not to wait, not {text}")
    return value


def _positive(text: str) -> float:
    value = _non_negative(text)
    if value == 0:
        raise argparse.ArgumentTypeError("must be greater than 0")
    return value


def _selection_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--topics", nargs="+", default=[], metavar="TOPIC", help="topics to take")
    p.add_argument("-e", "--regex", default="", help="also take topics matching this regular expression")
    p.add_argument("-x", "--exclude-regex", default="", help="leave out topics matching this regular expression")
    p.add_argument("--exclude-topics", nargs="+", default=[], metavar="TOPIC", help="leave out these topics")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="bag_verb", required=True, metavar="<record|play|info|reindex>")

    p = sub.add_parser("record", help="record topics into a rosbag2 (MCAP) bag",
                       description="Record topics into a rosbag2 bag (storage mcap, metadata version 9).")
    p.add_argument("topics_positional", nargs="*", metavar="TOPIC", help="topics to record")
    p.add_argument("-a", "--all", "--all-topics", dest="all", action="store_true",
                   help="record all topics, including ones that appear later")
    _selection_arguments(p)
    p.add_argument("-o", "--output", help="bag directory to create (default rosbag2_YYYY_MM_DD-HH_MM_SS)")
    p.add_argument("-s", "--storage", default="mcap", choices=["mcap"], help="storage plugin (mcap)")
    p.add_argument("-f", "--serialization-format", default="cdr", choices=["cdr"])
    p.add_argument("-b", "--max-bag-size", type=_size, default=0, metavar="BYTES",
                   help="start a new file when this size is reached (0: never; at least 1024)")
    p.add_argument("-d", "--max-bag-duration", type=_non_negative, default=0.0, metavar="SECONDS",
                   help="start a new file after this much message time (0: never)")
    p.add_argument("--compression-mode", default="none", choices=[m.value for m in CompressionMode])
    p.add_argument("--compression-format", default="zstd", choices=["zstd"])
    p.add_argument("--storage-preset-profile", default="none", choices=list(STORAGE_PRESETS),
                   help="MCAP chunking/compression preset, as rosbag2_storage_mcap (default none: "
                        "zstd chunks of 768 KiB)")
    p.add_argument("--use-sim-time", action="store_true", help="stamp messages with /clock time")
    p.add_argument("-p", "--polling-interval", type=_positive, default=100.0, metavar="MS",
                   help="how often to look for new topics, in milliseconds (default 100)")
    p.add_argument("--no-discovery", action="store_true",
                   help="subscribe only to topics present at start")
    p.add_argument("--include-hidden-topics", action="store_true")
    p.add_argument("--include-unpublished-topics", action="store_true",
                   help="also subscribe to topics that have subscribers but no publisher yet")
    p.add_argument("--node-name", default="rosbag2_recorder")
    p.add_argument("--resume", action="store_true",
                   help="if the output exists (a recording that stopped or was killed), finish it as "
                        "'bag reindex' does and record on into it, as its next file")

    p = sub.add_parser("play", help="publish a bag's messages with their recorded timing and QoS")
    p.add_argument("bag_path", help="bag directory (or one .mcap file)")
    _selection_arguments(p)
    p.add_argument("-r", "--rate", type=_positive, default=1.0, help="playback speed factor (default 1)")
    p.add_argument("-l", "--loop", action="store_true", help="play again from the start when done")
    p.add_argument("--clock", nargs="?", type=_positive, const=40.0, default=0.0, metavar="HZ",
                   help="publish /clock with the bag's time (default 40 Hz when given)")
    p.add_argument("--start-offset", type=_non_negative, default=0.0, metavar="SECONDS",
                   help="start this many seconds into the bag")
    p.add_argument("-d", "--delay", type=_non_negative, default=0.0, metavar="SECONDS",
                   help="wait this long (for subscribers to connect) before playing")
    p.add_argument("-p", "--start-paused", action="store_true", help="start paused (space resumes)")
    p.add_argument("-m", "--remap", nargs="+", default=[], metavar="OLD:=NEW", help="publish OLD on NEW")
    p.add_argument("--disable-keyboard-controls", action="store_true",
                   help="ignore the keyboard (space pause/resume, s step, up/down rate)")
    p.add_argument("--wait-for-all-acked", type=_acked_timeout, default=1000, metavar="TIMEOUT_MS",
                   help="at the end, wait up to this long for reliable subscribers to acknowledge "
                        "every message (0: as long as it takes, -1: not at all; default 1000)")
    p.add_argument("--include-hidden-topics", action="store_true")
    p.add_argument("--node-name", default="rosbag2_player")

    p = sub.add_parser("info", help="a bag's files, duration, start/end, and topics with counts")
    p.add_argument("bag_path")

    p = sub.add_parser("reindex", help="rebuild metadata.yaml (and unfinished MCAP files) of a bag "
                                       "whose recorder was killed")
    p.add_argument("bag_path")

    p = sub.add_parser("from-carmen", help="a CARMEN laser log (.log, .log.gz) as a bag: /scan, /odom, /tf, "
                                           "/tf_static on the log's clock, odometry made with AMCL's noise model")
    p.add_argument("log", help="the CARMEN log, e.g. ../shared/datasets/carmen/intel.log.gz")
    p.add_argument("-o", "--output", help="the bag directory (default: <log name>_bag); never overwritten")
    p.add_argument("--alphas", type=float, nargs=4, default=[0.05, 0.05, 0.05, 0.05], metavar="A",
                   help="odometry noise as AMCL's alpha1..alpha4 (the corrected logs have none of their own)")
    p.add_argument("--seed", type=int, default=0, help="seed of the odometry noise")
    p.add_argument("--scans", type=int, default=0, help="only the log's first N scans (0: all)")
    p.add_argument("--base-frame", default="base_footprint", help="the robot's frame (the slam node's base_frame)")
    p.add_argument("--laser-frame", default="laser_frame", help="the scans' frame")


def _selection(args: argparse.Namespace, positional: list[str], all_topics: bool) -> TopicSelection:
    return TopicSelection(
        all_topics=all_topics, topics=tuple(positional + args.topics),
        regex=compile_regex(args.regex, "--regex"),
        exclude_regex=compile_regex(args.exclude_regex, "--exclude-regex"),
        exclude_topics=tuple(args.exclude_topics), include_hidden=args.include_hidden_topics)


def record_options(args: argparse.Namespace, now: float | None = None) -> RecordOptions:
    """Raises: BagError for a combination argparse can't check."""
    selection = _selection(args, args.topics_positional, args.all)
    if not selection.selects_anything:
        raise BagError("nothing to record: name topics, or use -a/--all or -e/--regex")
    writer = WriterOptions(max_bag_size=args.max_bag_size, max_bag_duration_s=args.max_bag_duration,
                           compression_mode=CompressionMode(args.compression_mode),
                           compression_format=args.compression_format,
                           storage_preset=args.storage_preset_profile)
    writer.validate()
    stamp = time.strftime("rosbag2_%Y_%m_%d-%H_%M_%S", time.localtime(now))
    output = Path(args.output) if args.output else Path(stamp)
    if output.exists() and not args.resume:
        raise BagError(f"output '{output}' exists already; pppbot never overwrites a bag "
                       "(choose another name with -o, or --resume to record on into it)")
    return RecordOptions(output=output, selection=selection, writer=writer, use_sim_time=args.use_sim_time,
                         polling_interval_s=args.polling_interval / 1000.0, node_name=args.node_name,
                         include_unpublished_topics=args.include_unpublished_topics,
                         discovery=not args.no_discovery, resume=args.resume)


def play_options(args: argparse.Namespace) -> PlayOptions:
    all_topics = not (args.topics or args.regex)
    if all_topics:
        args.include_hidden_topics = True  # like ros2 bag play: every topic in the bag
    return PlayOptions(
        bag=Path(args.bag_path),
        selection=_selection(args, [], all_topics),
        remap=Remapping.parse(args.remap), rate=args.rate, loop=args.loop, clock_hz=args.clock,
        start_offset_s=args.start_offset, delay_s=args.delay, start_paused=args.start_paused,
        keyboard_controls=not args.disable_keyboard_controls, node_name=args.node_name,
        wait_for_all_acked_ms=args.wait_for_all_acked)


def main(args: argparse.Namespace) -> int:
    try:
        if args.bag_verb == "info":
            print(format_info(summarize(args.bag_path)))
            return 0
        if args.bag_verb == "reindex":
            from pppbot_bag.recover import reindex
            report = reindex(Path(args.bag_path))
            print(report)
            return 0
        if args.bag_verb == "from-carmen":
            return from_carmen(args)
        if args.bag_verb == "record":
            options: RecordOptions | PlayOptions = record_options(args)
            module = "pppbot_bag.ros.record"
        else:
            options = play_options(args)
            module = "pppbot_bag.ros.play"
    except BagError as exc:
        print(f"pppbot bag {args.bag_verb}: {exc}", file=sys.stderr)
        return 1
    return int(importlib.import_module(module).main(options))


def from_carmen(args: argparse.Namespace) -> int:
    """``pppbot bag from-carmen``: the log as a bag (:func:`pppbot_bag.carmen.write_bag`).

    Raises:
        BagError: a bad log, output or value.
    """
    import numpy as np

    from pppbot_bag.carmen import BagFrames, read_carmen, synthesize_odometry, write_bag
    if any(not (math.isfinite(a) and a >= 0) for a in args.alphas):
        raise BagError(f"--alphas must be four numbers >= 0, not {args.alphas}")
    if args.scans < 0:
        raise BagError(f"--scans must be 0 (all) or more, not {args.scans}")
    log = read_carmen(Path(args.log))
    if args.scans:
        log = log.head(args.scans)
    output = Path(args.output) if args.output else Path(f"{log.name}_bag")
    odometry = synthesize_odometry(log.poses, tuple(args.alphas), np.random.default_rng(args.seed))
    count = write_bag(log, odometry, output, BagFrames(base=args.base_frame, laser=args.laser_frame))
    print(f"{output}: {len(log.poses)} scans of {log.name} over {log.duration_s:.0f} s, {count} messages "
          f"(/scan in {args.laser_frame}, /odom and /tf odom → {args.base_frame}, seed {args.seed})")
    return 0
