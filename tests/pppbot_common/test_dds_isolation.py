"""dds_isolation: a domain of one's own, and a new one when this process crowds it; dds_participants:
whose participants a domain holds on this machine."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest
import rclpy

from pppbot_common.dds_isolation import DOMAIN_IDS, domain_id_problem, fresh_domain_if_crowded
from pppbot_common.dds_participants import (
    discovery_stays_on_this_machine,
    others_on_this_machine,
    own_participants,
    participant_ids,
)

pytestmark = pytest.mark.ros


def test_each_context_is_a_participant_counted_until_it_is_let_go(monkeypatch: pytest.MonkeyPatch) -> None:
    """own_participants counts this process's DDS participants in a domain (one per rclpy context);
    fresh_domain_if_crowded moves the process to another domain once it holds ``limit`` of them."""
    domain = int(os.environ["ROS_DOMAIN_ID"])
    before, ids_before = own_participants(domain), participant_ids(domain)
    contexts = []
    try:
        for i in range(3):
            context = rclpy.Context()
            rclpy.init(context=context)
            contexts.append((context, rclpy.create_node(f"crowd_{i}", context=context)))
        assert own_participants(domain) == before + 3
        ids = participant_ids(domain)  # Fast DDS takes the lowest free IDs
        assert len(ids) == len(ids_before) + 3 and ids == sorted(ids) and set(ids_before) < set(ids)
        monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))  # restored after the test
        assert fresh_domain_if_crowded(limit=before + 4) is None  # room left: it stays
        moved = fresh_domain_if_crowded(limit=before + 3)
        assert moved is not None and moved != domain and moved in DOMAIN_IDS
        assert os.environ["ROS_DOMAIN_ID"] == str(moved) and own_participants(moved) == 0
    finally:
        for context, node in contexts:
            node.destroy_node()
            rclpy.shutdown(context=context)
    assert own_participants(domain) == before  # a context shut down with its nodes is let go


def test_a_domain_id_out_of_range_is_named() -> None:
    assert domain_id_problem("233") is not None and "0 to 232" in str(domain_id_problem("233"))
    assert domain_id_problem("ten") is not None
    assert domain_id_problem("42") is None and domain_id_problem(None) is None


def test_participants_of_other_processes_are_told_from_this_ones_and_its_parents() -> None:
    """others_on_this_machine counts a child's participant, never this process's own contexts."""
    domain = int(os.environ["ROS_DOMAIN_ID"])
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node("mine", context=context)
    child = subprocess.Popen([sys.executable, "-c", CHILD_WITH_A_NODE], stdout=subprocess.PIPE, text=True)
    try:
        assert own_participants(domain) >= 1
        assert child.stdout is not None and child.stdout.readline().strip() == "up"
        assert others_on_this_machine(domain) == 1  # the child; this process's contexts are its own
    finally:
        child.kill()  # rclpy's signal handlers would only shut its context down
        child.wait(timeout=30)
        node.destroy_node()
        rclpy.shutdown(context=context)
    assert others_on_this_machine(domain) == 0  # the child's port went with it


CHILD_WITH_A_NODE = """
import sys, time, rclpy
rclpy.init()
node = rclpy.create_node("theirs")
print("up", flush=True)
time.sleep(60)
"""


@pytest.mark.parametrize(("environ", "stays"), [
    ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}, True),
    ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "off"}, True),
    ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"}, False),
    ({}, False),  # Jazzy's default reaches the subnet
    ({"ROS_LOCALHOST_ONLY": "1"}, True),
    ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "ROS_STATIC_PEERS": "192.168.0.7"}, False),
])
def test_whether_discovery_stays_on_this_machine(environ: dict[str, str], stays: bool) -> None:
    assert discovery_stays_on_this_machine(environ) is stays
