"""What the examples share: poses in the ``room`` world's map (the shipped ``maps/room.yaml``,
whose frame is the world's; the robot starts at the origin facing +x), and the wait for a task
that nav2_simple_commander's demos write out in each script.

The examples use Nav2's own ``BasicNavigator`` when ``nav2_simple_commander`` is installed (a ROS 2
Jazzy install), and ``robot_navigator.py`` beside them otherwise: the same API on the same
interfaces.
"""
from __future__ import annotations

import math
from typing import Any

from geometry_msgs.msg import PoseStamped

try:
    from nav2_simple_commander.robot_navigator import BasicNavigator, TaskResult
except ImportError:  # no ROS 2 install: the same class, beside this file
    from robot_navigator import BasicNavigator, TaskResult

__all__ = ["LOCALIZED", "START", "BasicNavigator", "TaskResult", "stamped", "wait_for"]

#: Where launch_sim's default spawn puts the robot in the room (x m, y m, yaw rad).
START = (0.0, 0.0, 0.0)
#: ``waitUntilNav2Active(localizer=LOCALIZED)``: wait for the map and the navigator, send no initial
#: pose. With ``localizer="amcl"`` (its default) BasicNavigator publishes its ``initial_pose`` (the
#: origin unless ``setInitialPose`` was called) until AMCL answers, which would move AMCL's estimate
#: of a robot that has driven elsewhere; launch_sim's AMCL starts localized at the spawn pose.
LOCALIZED = "map_server"


def stamped(navigator: BasicNavigator, x: float, y: float, yaw: float = 0.0) -> PoseStamped:
    """A pose in the map frame, stamped now."""
    pose = PoseStamped()
    pose.header.frame_id = "map"
    pose.header.stamp = navigator.get_clock().now().to_msg()
    pose.pose.position.x, pose.pose.position.y = x, y
    pose.pose.orientation.z, pose.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
    return pose


def wait_for(navigator: BasicNavigator, describe: Any = None) -> TaskResult:
    """Wait for the running task as Nav2's demos do (isTaskComplete, printing the feedback now and
    then with ``describe(feedback)``) and return its result, printed."""
    i = 0
    while not navigator.isTaskComplete():
        i += 1
        feedback = navigator.getFeedback()
        if describe is not None and feedback is not None and i % 10 == 0:
            print(describe(feedback), flush=True)
    result = navigator.getResult()
    print(f"result: {result.name}", flush=True)
    return result
