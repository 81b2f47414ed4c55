"""Every behaviour-tree node Nav2 Jazzy's bt_navigator registers by default, by its XML name, and
the factory that builds trees with them (BehaviorTree.CPP's own nodes included)."""
from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from pppbot_nav.bt.tree import TreeNode
from pppbot_nav.bt.xml_tree import TreeFactory
from pppbot_nav.ros.bt.nav2_actions import NAV2_ACTION_NODES
from pppbot_nav.ros.bt.nav2_conditions import NAV2_CONDITION_NODES
from pppbot_nav.ros.bt.nav2_path_nodes import NAV2_PATH_NODES

#: Nav2's nodes beyond its controls (which every :class:`TreeFactory` has)
NAV2_NODES: dict[str, type[TreeNode]] = {**NAV2_ACTION_NODES, **NAV2_CONDITION_NODES, **NAV2_PATH_NODES}


def nav2_factory(extra: Mapping[str, type[TreeNode]] | None = None) -> TreeFactory:
    """A factory with BehaviorTree.CPP's nodes, Nav2's, and ``extra`` (a user's, by XML name)."""
    return TreeFactory({**NAV2_NODES, **(extra or {})})


#: pppbot's default trees (bt_navigator's default_nav_to_pose_bt_xml and default_nav_through_poses_bt_xml)
TREES = Path(__file__).resolve().parents[2] / "behavior_trees"
DEFAULT_NAV_TO_POSE_BT_XML = TREES / "navigate_to_pose_w_replanning_and_recovery.xml"
DEFAULT_NAV_THROUGH_POSES_BT_XML = TREES / "navigate_through_poses_w_replanning_and_recovery.xml"
