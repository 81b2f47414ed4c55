"""QoS that hears a topic's publishers: what a subscriber asks for, lowered to what they offer."""
from __future__ import annotations

from types import SimpleNamespace

from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from pppbot_common.ros.qos import LATCHED, SENSOR, lowered_for, subscription_qos


def publisher(reliability: ReliabilityPolicy, durability: DurabilityPolicy) -> SimpleNamespace:
    return SimpleNamespace(qos_profile=QoSProfile(depth=1, reliability=reliability, durability=durability))


RELIABLE_LATCHED = publisher(ReliabilityPolicy.RELIABLE, DurabilityPolicy.TRANSIENT_LOCAL)
BEST_EFFORT_VOLATILE = publisher(ReliabilityPolicy.BEST_EFFORT, DurabilityPolicy.VOLATILE)
RELIABLE_VOLATILE = publisher(ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE)


def test_a_latched_subscription_is_lowered_only_as_far_as_its_publishers_need() -> None:
    kept = lowered_for(LATCHED, [RELIABLE_LATCHED])
    assert (kept.reliability, kept.durability, kept.depth) == (LATCHED.reliability, LATCHED.durability, 1)
    # a bag recorded without QoS plays best effort and volatile: a latched subscription would hear nothing
    played = lowered_for(LATCHED, [BEST_EFFORT_VOLATILE])
    assert (played.reliability, played.durability) == (ReliabilityPolicy.BEST_EFFORT, DurabilityPolicy.VOLATILE)
    # one volatile publisher among latched ones: volatile, still reliable
    mixed = lowered_for(LATCHED, [RELIABLE_LATCHED, RELIABLE_VOLATILE])
    assert (mixed.reliability, mixed.durability) == (ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE)
    # never raised above what was asked for: a sensor subscription stays best effort
    assert lowered_for(SENSOR, [RELIABLE_LATCHED]).reliability == ReliabilityPolicy.BEST_EFFORT


def test_subscription_qos_is_latched_only_when_every_publisher_is() -> None:
    assert subscription_qos([RELIABLE_LATCHED]).durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert subscription_qos([RELIABLE_LATCHED, RELIABLE_VOLATILE]).durability == DurabilityPolicy.VOLATILE
    assert subscription_qos([BEST_EFFORT_VOLATILE]).reliability == ReliabilityPolicy.BEST_EFFORT
