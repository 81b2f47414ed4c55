"""bt_navigator's trees as a Nav2 user gives them: a default tree written wrong, or a plugin module
that is not one, fails the configure naming the file, the line and what is known; pppbot's own
defaults and a user's file load."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from rclpy.lifecycle import TransitionCallbackReturn
from rclpy.parameter import Parameter

from pppbot_nav.ros.bt.nav2 import DEFAULT_NAV_THROUGH_POSES_BT_XML, DEFAULT_NAV_TO_POSE_BT_XML

GOOD = ('<root BTCPP_format="4"><BehaviorTree ID="MainTree">\n'
        '<Sequence><Spin spin_dist="3.14"/><Wait wait_duration="1"/></Sequence>\n</BehaviorTree></root>\n')
UNKNOWN = '<root BTCPP_format="4"><BehaviorTree ID="MainTree">\n<Sequence>\n<Fly/>\n</Sequence></BehaviorTree></root>\n'


def configured(**parameters: Any) -> Any:
    """A bt_navigator configured with ``parameters``: (its answer, why it failed, its trees)."""
    import rclpy

    from pppbot_nav.ros.navigator import Navigator

    rclpy.init()
    try:
        navigator = Navigator(parameter_overrides=[Parameter(k, value=v) for k, v in parameters.items()])
        answer = navigator.trigger_configure()
        outcome = (answer, navigator.configure_failure, navigator.trees)
        navigator.destroy_node()
        return outcome
    finally:
        rclpy.shutdown()


@pytest.mark.ros
def test_the_default_trees_are_pppbots_unless_the_parameters_name_others(tmp_path: Path) -> None:
    answer, failure, trees = configured()
    assert answer == TransitionCallbackReturn.SUCCESS, failure
    assert trees.tree("", False) is trees.tree(str(DEFAULT_NAV_TO_POSE_BT_XML), False)  # loaded once
    assert trees.tree("", True) is trees.tree(str(DEFAULT_NAV_THROUGH_POSES_BT_XML), True)
    mine = tmp_path / "spin_and_wait.xml"
    mine.write_text(GOOD)
    answer, failure, trees = configured(default_nav_to_pose_bt_xml=str(mine))
    assert answer == TransitionCallbackReturn.SUCCESS, failure
    assert [type(node).__name__ for node in trees.tree("", False).nodes()] == ["SequenceNode", "SpinNode", "WaitNode"]


@pytest.mark.ros
def test_a_default_tree_written_wrong_fails_the_configure_naming_file_line_and_node(tmp_path: Path) -> None:
    bad = tmp_path / "bad.xml"
    bad.write_text(UNKNOWN)
    answer, failure, _ = configured(default_nav_through_poses_bt_xml=str(bad))
    assert answer == TransitionCallbackReturn.FAILURE
    assert failure.startswith(f"{bad.resolve()}:3: unknown node 'Fly'; known: ")
    assert "ComputePathThroughPoses" in failure
    answer, failure, _ = configured(default_nav_to_pose_bt_xml=str(tmp_path / "missing.xml"))
    assert answer == TransitionCallbackReturn.FAILURE and failure.endswith("missing.xml: no such behaviour tree file")


@pytest.mark.ros
def test_plugin_lib_names_add_a_modules_nodes_and_nav2s_own_names_are_known_already(tmp_path: Path,
                                                                                       monkeypatch: Any) -> None:
    (tmp_path / "my_bt_nodes.py").write_text(
        "from pppbot_nav.bt.tree import Status, TreeNode\n\n\n"
        "class Beep(TreeNode):\n    def tick(self):\n        return Status.SUCCESS\n\n\n"
        "BT_NODES = {'Beep': Beep}\n")
    (tmp_path / "not_nodes.py").write_text("VALUE = 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    tree = tmp_path / "beep.xml"
    tree.write_text('<root BTCPP_format="4"><BehaviorTree ID="MainTree"><Beep/></BehaviorTree></root>')
    answer, failure, trees = configured(plugin_lib_names=["nav2_spin_action_bt_node", "my_bt_nodes"],
                                        default_nav_to_pose_bt_xml=str(tree))
    assert answer == TransitionCallbackReturn.SUCCESS, failure
    assert type(trees.tree("", False).root).__name__ == "Beep"
    answer, failure, _ = configured(plugin_lib_names=["not_nodes"])
    assert answer == TransitionCallbackReturn.FAILURE and "'not_nodes' gives no mapping of XML names" in failure
    answer, failure, _ = configured(plugin_lib_names=["no_such_module_here"])
    assert answer == TransitionCallbackReturn.FAILURE
    assert "'no_such_module_here' is neither an installed library" in failure and "pppbot_nav.bt_plugins" in failure


@pytest.mark.ros
def test_a_goals_tree_path_that_is_no_path_is_named(tmp_path: Path) -> None:
    from pppbot_nav.errors import BehaviorTreeError

    answer, failure, trees = configured()
    assert answer == TransitionCallbackReturn.SUCCESS, failure
    for text, why in (("bad\x00name.xml", "embedded null byte"), ("~no_such_user_here/t.xml", "home directory")):
        with pytest.raises(BehaviorTreeError, match=why):
            trees.tree(text, False)
