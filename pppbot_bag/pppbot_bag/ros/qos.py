"""QoS and type hashes between rclpy and the bag files (rosbags' ``Qos``)."""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from rclpy.duration import Duration
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    LivelinessPolicy,
    QoSProfile,
    ReliabilityPolicy,
)
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

_INFINITE_NS = 2**63 - 1


def _time(duration: Any) -> QosTime:
    ns = min(int(duration.nanoseconds), _INFINITE_NS)
    return QosTime(ns // 1_000_000_000, ns % 1_000_000_000)


def _duration(t: QosTime) -> Duration:
    return Duration(nanoseconds=min(t.sec * 1_000_000_000 + t.nsec, _INFINITE_NS))


def _policy(kind: Any, policy: Any) -> Any:
    """rclpy's policy as the rosbags enum of the same name (UNKNOWN if it has none)."""
    return kind.__members__.get(policy.name, kind.UNKNOWN)


def qos_to_bag(profile: QoSProfile) -> Qos:
    """An endpoint's QoS as rosbag2 records it."""
    return Qos(
        history=_policy(QosHistory, profile.history),
        depth=int(profile.depth),
        reliability=_policy(QosReliability, profile.reliability),
        durability=_policy(QosDurability, profile.durability),
        deadline=_time(profile.deadline),
        lifespan=_time(profile.lifespan),
        liveliness=_policy(QosLiveliness, profile.liveliness),
        liveliness_lease_duration=_time(profile.liveliness_lease_duration),
        avoid_ros_namespace_conventions=bool(profile.avoid_ros_namespace_conventions),
    )


def playback_qos(offered: Sequence[Qos], default_depth: int = 10) -> QoSProfile:
    """What ``ros2 bag play`` offers for a topic recorded with ``offered`` profiles:
    reliable / transient local only when every recorded publisher was, the deepest
    recorded history (at least ``default_depth``), and the recorded deadline, lifespan
    and liveliness when there was one publisher."""
    reliable = bool(offered) and all(q.reliability == QosReliability.RELIABLE for q in offered)
    latched = bool(offered) and all(q.durability == QosDurability.TRANSIENT_LOCAL for q in offered)
    depth = max([default_depth, *(q.depth for q in offered if q.history == QosHistory.KEEP_LAST)])
    profile = QoSProfile(
        history=HistoryPolicy.KEEP_LAST, depth=depth,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)
    if len(offered) == 1:
        q = offered[0]
        profile.deadline = _duration(q.deadline)
        profile.lifespan = _duration(q.lifespan)
        profile.liveliness_lease_duration = _duration(q.liveliness_lease_duration)
        if q.liveliness.name in LivelinessPolicy.__members__:
            profile.liveliness = LivelinessPolicy[q.liveliness.name]
    return profile


def type_hash_string(type_hash: Any) -> str:
    """``RIHS01_<hex>`` of an rclpy ``TypeHash`` ('' when the endpoint has none)."""
    if getattr(type_hash, "version", -1) != 1:
        return ""
    return "RIHS01_" + bytes(type_hash.value).hex()
