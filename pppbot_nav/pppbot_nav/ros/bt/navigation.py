"""A navigator's trees, with no ROS: which tree a goal runs, what the blackboard holds for it, and
what a failed run answers (Nav2 Jazzy's ``BtActionServer`` and navigators).

:class:`NavigatorTrees` loads each tree file once (as Nav2's, unless ``always_reload_bt_xml``);
:meth:`NavigatorTrees.start` halts the tree if it ran, and sets the entries Nav2's navigators
set: the goal (``goal_blackboard_id``) or goals (``goals_blackboard_id``), ``number_recoveries``
0, each of ``error_code_names`` 0, and the navigator's settings the nodes read.
:func:`error_of` is the result's error code: the smallest non-zero of ``error_code_names``
(Nav2's order of priority), with the message of the node that set it.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pppbot_nav.bt.ports import PORTS_KEY, RobotPorts
from pppbot_nav.bt.tree import Blackboard, Tree, TreeNode
from pppbot_nav.errors import BehaviorTreeError
from pppbot_nav.ros.bt.nav2 import DEFAULT_NAV_THROUGH_POSES_BT_XML, DEFAULT_NAV_TO_POSE_BT_XML, nav2_factory
from pppbot_nav.ros.bt.nav2_actions import RECOVERIES_KEY, SERVER_TIMEOUT_KEY


@dataclass(frozen=True)
class TreeSettings:
    """What the navigator gives its trees (bt_navigator's parameters)."""

    default_nav_to_pose_bt_xml: str = ""
    default_nav_through_poses_bt_xml: str = ""
    always_reload_bt_xml: bool = False
    server_timeout_ms: float = 1000.0
    error_code_names: tuple[str, ...] = ("follow_path_error_code", "compute_path_error_code")
    goal_blackboard_id: str = "goal"
    goals_blackboard_id: str = "goals"
    path_blackboard_id: str = "path"
    #: entries every goal's blackboard gets (global_frame, goal_reached_tol, pppbot's replanning_frequency …)
    entries: Mapping[str, Any] = field(default_factory=dict)

    def default_tree(self, through: bool) -> Path:
        chosen = self.default_nav_through_poses_bt_xml if through else self.default_nav_to_pose_bt_xml
        if chosen:
            return Path(chosen).expanduser()
        return DEFAULT_NAV_THROUGH_POSES_BT_XML if through else DEFAULT_NAV_TO_POSE_BT_XML


class NavigatorTrees:
    """The trees a navigator runs, loaded with Nav2's nodes and ``extra`` ones, on ``clock``; what a
    file's load warns of goes to ``warn``."""

    def __init__(self, settings: TreeSettings, clock: Callable[[], float],
                 extra: Mapping[str, type[TreeNode]] | None = None,
                 warn: Callable[[str], None] = lambda _: None) -> None:
        self.settings = settings
        self.warn = warn
        self.factory = nav2_factory(extra)
        self.clock = clock
        self._loaded: dict[Path, Tree] = {}

    def tree(self, file: str | Path, through: bool) -> Tree:
        """The tree of ``file`` ("" : the default for a goal of that kind), loaded once.

        Raises:
            BehaviorTreeError: no such file, or the tree as :mod:`pppbot_nav.bt.xml_tree` refuses it.
        """
        try:
            path = Path(file).expanduser() if str(file) else self.settings.default_tree(through)
            path = path.resolve()
            found = path.is_file()
        except (ValueError, RuntimeError, OSError) as exc:  # a NUL in it, ~nobody, a loop of links
            raise BehaviorTreeError(f"{str(file)!r} is not a behaviour tree file's path ({exc})") from exc
        if path in self._loaded and not self.settings.always_reload_bt_xml:
            return self._loaded[path]
        if not found:
            raise BehaviorTreeError(f"{path}: no such behaviour tree file")
        tree = self.factory.load(path, clock=self.clock, blackboard=Blackboard())
        for warning in tree.warnings:
            self.warn(warning)
        self._loaded[path] = tree
        return tree

    def start(self, tree: Tree, ports: RobotPorts, *, goal: Any = None, goals: Sequence[Any] | None = None) -> None:
        """Make ``tree`` ready for a new goal (halted if it ran; the goal's entries set)."""
        tree.halt()
        board = tree.blackboard
        s = self.settings
        for key, value in s.entries.items():
            board.set(key, value)
        board.set(PORTS_KEY, ports)
        board.set(SERVER_TIMEOUT_KEY, s.server_timeout_ms)
        board.set(RECOVERIES_KEY, 0)
        for name in s.error_code_names:
            board.set(name, 0)
        if goals is not None:
            board.set(s.goals_blackboard_id, list(goals))
        if goal is not None:
            board.set(s.goal_blackboard_id, goal)

    def update_goal(self, tree: Tree, *, goal: Any = None, goals: Sequence[Any] | None = None) -> None:
        """A preempting goal for the same tree: its entries replaced, the tree ticking on (Nav2's)."""
        board = tree.blackboard
        board.set(RECOVERIES_KEY, 0)
        if goals is not None:
            board.set(self.settings.goals_blackboard_id, list(goals))
        if goal is not None:
            board.set(self.settings.goal_blackboard_id, goal)


def error_of(board: Blackboard, names: Sequence[str]) -> tuple[int, str]:
    """The run's error code: the smallest non-zero entry of ``names`` (0 when none), and the
    message of that entry's node (``<name minus _code>_msg``, "" when none wrote one)."""
    found = [(int(board.get(name) or 0), name) for name in names if name in board]
    failed = sorted((code, name) for code, name in found if code)
    if not failed:
        return 0, ""
    code, name = failed[0]
    message = board.get(name.removesuffix("_code") + "_msg") or ""
    return code, str(message)
