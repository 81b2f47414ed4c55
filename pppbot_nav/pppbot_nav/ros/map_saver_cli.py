"""``pppbot map_saver``: save a map topic as a Nav2 map (YAML + image), like Nav2's map_saver_cli.

    pppbot map_saver -f maps/maze                  # /map → maps/maze.yaml + maps/maze.pgm
    pppbot map_saver -f my_map --mode scale        # my_map.png, unknown cells transparent
    pppbot map_saver -f my_map --occ 0.7 --free 0.2 --fmt png -t /other_map

It waits up to ``--timeout`` seconds for one map on the topic (transient local by
default, so a latched ``/map`` arrives at once), writes the files (replacing
existing ones, as Nav2 does) and prints what it saved. Exit status: 0 saved;
1 no map in time, or the files could not be written; 2 bad arguments (nothing
written). Also installed as ``ros2 run pppbot_nav map_saver_cli``.
"""
from __future__ import annotations

import argparse
import math
import sys

import rclpy
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from rclpy.exceptions import InvalidTopicNameException
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy
from rclpy.validate_topic_name import validate_topic_name

from pppbot_common.errors import TimeoutExpired
from pppbot_common.maps import MapFileError
from pppbot_common.resources import maps_directory
from pppbot_common.ros.nodes import unspun_node
from pppbot_common.ros.wait import wait_for_messages
from pppbot_nav.errors import MapSaverError
from pppbot_nav.map_saving import (
    DEFAULT_FREE_THRESH,
    DEFAULT_OCCUPIED_THRESH,
    MAP_MODES,
    SaveSettings,
    resolve_save_settings,
)
from pppbot_nav.ros.map_saver import DEFAULT_MAP_TOPIC, map_qos, saved_summary, write_map

PROG = "pppbot map_saver"
DEFAULT_TIMEOUT_S = 5.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("-f", dest="map_file", metavar="PATH", default="",
                        help="files to write, without extension: PATH.yaml and PATH.<fmt> "
                             "(default: map in the checkout's maps/)")
    parser.add_argument("-t", dest="map_topic", metavar="MAP_TOPIC", default=DEFAULT_MAP_TOPIC,
                        help=f"the map topic (default: {DEFAULT_MAP_TOPIC}, i.e. /{DEFAULT_MAP_TOPIC})")
    parser.add_argument("--occ", type=float, metavar="T", default=None,
                        help=f"occupied threshold: cells >= 100·T are occupied (default {DEFAULT_OCCUPIED_THRESH})")
    parser.add_argument("--free", type=float, metavar="T", default=None,
                        help=f"free threshold: cells <= 100·T are free (default {DEFAULT_FREE_THRESH})")
    parser.add_argument("--fmt", metavar="FORMAT", default="",
                        help="image format: pgm, png or bmp (default: png in scale mode, else pgm)")
    parser.add_argument("--mode", metavar="MODE", default="",
                        help=f"{', '.join(MAP_MODES)} (default trinary: free 254, occupied 0, unknown 205)")
    parser.add_argument("--timeout", type=float, metavar="SECONDS", default=DEFAULT_TIMEOUT_S,
                        help=f"how long to wait for a map (default {DEFAULT_TIMEOUT_S:g})")
    parser.add_argument("--qos-durability", choices=["transient_local", "volatile"], default="transient_local",
                        help="transient_local (default) gets a latched map at once; volatile waits for the next "
                             "map of a publisher that does not latch")


def main(args: argparse.Namespace) -> int:
    if not (math.isfinite(args.timeout) and args.timeout > 0):
        print(f"{PROG}: --timeout must be a positive number of seconds, not {args.timeout}", file=sys.stderr)
        return 2
    try:
        settings = resolve_save_settings(args.map_file, args.fmt, args.mode, args.free, args.occ,
                                         default_path=maps_directory() / "map")
    except MapSaverError as exc:
        print(f"{PROG}: {exc}; nothing saved", file=sys.stderr)
        return 2
    try:
        validate_topic_name(args.map_topic)
    except InvalidTopicNameException as exc:
        reason = str(exc).splitlines()[0].rstrip(":")
        print(f"{PROG}: -t '{args.map_topic}': {reason}; nothing saved", file=sys.stderr)
        return 2
    for warning in settings.warnings():
        print(f"{PROG}: warning: {warning}", file=sys.stderr)
    rclpy.init(args=[])
    try:
        node = unspun_node("map_saver_cli")
        try:
            return _save(node, args, settings)
        finally:
            node.destroy_node()
    except (KeyboardInterrupt, ExternalShutdownException):
        return 130
    finally:
        rclpy.try_shutdown()


def _save(node: Node, args: argparse.Namespace, settings: SaveSettings) -> int:
    transient_local = args.qos_durability == "transient_local"
    topic = node.resolve_topic_name(args.map_topic)
    try:
        (msg,) = wait_for_messages(node, OccupancyGridMsg, topic, count=1, timeout_s=args.timeout,
                                   qos=map_qos(transient_local))
    except TimeoutExpired:
        print(f"{PROG}: no map on {topic} within {args.timeout:g} s ({_why_silent(node, topic, transient_local)}); "
              "nothing saved", file=sys.stderr)
        return 1
    try:
        grid = write_map(msg, settings)
    except (MapFileError, ValueError, OSError) as exc:
        print(f"{PROG}: could not save the map to {settings.yaml_path}: {exc}", file=sys.stderr)
        return 1
    print(saved_summary(grid, settings))
    return 0


def _why_silent(node: Node, topic: str, transient_local: bool) -> str:
    infos = node.get_publishers_info_by_topic(topic)
    if not infos:
        return "it has no publisher"
    if transient_local and not any(i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos):
        return "its publishers do not latch: --qos-durability volatile waits for their next map"
    return f"{len(infos)} publisher(s), but none sent a map"


def cli_main(argv: list[str] | None = None) -> int:
    """The ``map_saver_cli`` executable (``ros2 run pppbot_nav map_saver_cli -f ...``)."""
    parser = argparse.ArgumentParser(prog="map_saver_cli", description=__doc__.split("\n")[0] if __doc__ else None)
    add_arguments(parser)
    return main(parser.parse_args(argv))


if __name__ == "__main__":
    sys.exit(cli_main())
