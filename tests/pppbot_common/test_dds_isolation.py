"""dds_isolation: a domain of one's own, and a new one when this process crowds it."""
from __future__ import annotations

import os

import pytest
import rclpy

from pppbot_common.dds_isolation import DOMAIN_IDS, domain_id_problem, fresh_domain_if_crowded, own_participants

pytestmark = pytest.mark.ros


def test_each_context_is_a_participant_counted_until_it_is_let_go(monkeypatch: pytest.MonkeyPatch) -> None:
    """own_participants counts this process's DDS participants in a domain (one per rclpy context);
    fresh_domain_if_crowded moves the process to another domain once it holds ``limit`` of them."""
    domain = int(os.environ["ROS_DOMAIN_ID"])
    before = own_participants(domain)
    contexts = []
    try:
        for i in range(3):
            context = rclpy.Context()
            rclpy.init(context=context)
            contexts.append((context, rclpy.create_node(f"crowd_{i}", context=context)))
        assert own_participants(domain) == before + 3
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
