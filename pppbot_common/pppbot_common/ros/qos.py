"""QoS profiles pppbot uses, and QoS that matches a topic's publishers."""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from rclpy.node import Node
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)

#: Latched topics (/robot_description, /map, /tf_static): late joiners get the last message.
LATCHED = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=1,
    reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL,
)

#: A map subscribed to without transient local (a costmap's ``map_subscribe_transient_local: false``).
MAP_VOLATILE = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=1,
    reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE,
)

#: High-rate sensor streams (/scan, /imu) as their drivers usually publish them.
SENSOR = qos_profile_sensor_data

#: Ordinary reliable topics.
DEFAULT = QoSProfile(depth=10)


def qos_matching_publishers(node: Node, topic: str, depth: int = 10) -> QoSProfile:
    """A subscription QoS compatible with every current publisher of ``topic``.

    Reliable and transient-local only when all publishers offer them (what
    ``ros2 topic echo`` does), so latched topics deliver their stored message and
    best-effort publishers are still heard.
    """
    return subscription_qos(node.get_publishers_info_by_topic(topic), depth)


def subscription_qos(infos: Sequence[Any], depth: int = 10) -> QoSProfile:
    """A subscription QoS compatible with every publisher in ``infos`` (endpoint infos)."""
    reliability = ReliabilityPolicy.RELIABLE
    durability = DurabilityPolicy.VOLATILE
    if infos:
        if any(i.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT for i in infos):
            reliability = ReliabilityPolicy.BEST_EFFORT
        if all(i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos):
            durability = DurabilityPolicy.TRANSIENT_LOCAL
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                      reliability=reliability, durability=durability)


def lowered_for(profile: QoSProfile, infos: Sequence[Any]) -> QoSProfile:
    """``profile`` made compatible with every publisher in ``infos`` (endpoint infos): best effort
    when one of them is, volatile when one of them is. A reliable subscription hears no
    best-effort publisher and a transient-local one no volatile publisher, as with a bag
    recorded without QoS, or another tool's node."""
    reliability, durability = profile.reliability, profile.durability
    if any(i.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT for i in infos):
        reliability = ReliabilityPolicy.BEST_EFFORT
    if any(i.qos_profile.durability == DurabilityPolicy.VOLATILE for i in infos):
        durability = DurabilityPolicy.VOLATILE
    return QoSProfile(history=profile.history, depth=profile.depth, reliability=reliability, durability=durability)
