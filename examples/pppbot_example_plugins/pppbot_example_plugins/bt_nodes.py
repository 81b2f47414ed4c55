"""``GoalFartherThan``: a behaviour-tree condition of a user's own, for Nav2-format XML trees.

SUCCESS while the robot is farther than ``distance`` (m) from ``goal``; FAILURE within it, or
while the robot's pose is unknown. A tree can skip planning for a goal the robot already stands
on, or pick a different branch near the goal. The library is named in ``bt_navigator``'s
``plugin_lib_names`` as ``pppbot_example_bt_nodes`` (the ``pppbot_nav.bt_plugins`` entry point:
a mapping of XML names to node classes).
"""
from __future__ import annotations

import math

from pppbot_nav.bt.ports import setting
from pppbot_nav.bt.tree import Status, TreeNode, input_port
from pppbot_nav.ros.bt.nav2_conditions import robot_pose_in


class GoalFartherThan(TreeNode):
    PORTS = (input_port("goal", None), input_port("distance", float, 1.0))

    def tick(self) -> Status:
        goal = self.get_input("goal")
        robot = robot_pose_in(self, goal.header.frame_id or setting(self.config.blackboard, "global_frame"))
        if robot is None:
            return Status.FAILURE
        away = math.hypot(goal.pose.position.x - robot[0], goal.pose.position.y - robot[1])
        return Status.SUCCESS if away > self.get_input("distance") else Status.FAILURE


BT_NODES = {"GoalFartherThan": GoalFartherThan}
