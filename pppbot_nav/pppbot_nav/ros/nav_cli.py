"""``pppbot nav goto X Y YAW``: send a navigate_to_pose goal and print its feedback until it ends.

Like ``ros2 action send_goal /navigate_to_pose nav2_msgs/action/NavigateToPose ... --feedback``,
with the pose given as numbers. Ctrl-C cancels the goal. Exit status 0 when the goal
succeeds, 1 when it fails or is canceled, 2 when no navigator answers.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable
from typing import Any

import rclpy
from action_msgs.msg import GoalStatus
from nav2_msgs.action import NavigateToPose
from rclpy.node import Node

from pppbot_common.errors import TimeoutExpired
from pppbot_common.ros.wait import send_goal
from pppbot_common.se2 import quaternion_from_yaw
from pppbot_lockstep.ros.action_client import ActionClient

#: How long a goal may wait for the navigator's answer (s; resent meanwhile, see send_goal).
GOAL_ANSWER_S = 30.0
STATUS = {GoalStatus.STATUS_SUCCEEDED: "succeeded", GoalStatus.STATUS_ABORTED: "failed",
          GoalStatus.STATUS_CANCELED: "canceled"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="command", required=True)
    goto = sub.add_parser("goto", help="navigate to a pose and print feedback")
    goto.add_argument("x", type=float, help="goal x (m)")
    goto.add_argument("y", type=float, help="goal y (m)")
    goto.add_argument("yaw", type=float, nargs="?", default=0.0, help="goal heading (rad, default 0)")
    goto.add_argument("--frame", default="map", help="the goal's frame (default map)")
    goto.add_argument("--server-timeout", type=float, default=10.0, metavar="S",
                      help="wait this long for the navigator (default 10 s)")


def goal_of(x: float, y: float, yaw: float, frame: str) -> NavigateToPose.Goal:
    if not all(math.isfinite(v) for v in (x, y, yaw)):
        raise ValueError(f"the goal must be finite numbers, not ({x}, {y}, {yaw})")
    goal = NavigateToPose.Goal()
    goal.pose.header.frame_id = frame
    goal.pose.pose.position.x, goal.pose.pose.position.y = x, y
    o = goal.pose.pose.orientation
    o.x, o.y, o.z, o.w = quaternion_from_yaw(yaw)
    return goal


class Progress:
    """What ``nav goto`` prints of the navigator's feedback: nothing before the goal was accepted
    (no stale line before "navigating to"); until the first plan, once a second, that it waits
    for one; then the robot's progress once a second, and each recovery as it starts."""

    def __init__(self, print_line: Callable[[str], None] = lambda text: print(text, flush=True)) -> None:
        self.accepted = False
        self.planned = False
        self.recoveries = 0
        self.last_s = -math.inf
        self.print_line = print_line

    def feedback(self, fb: Any) -> None:
        if not self.accepted:
            return
        now = time.monotonic()
        self.planned = self.planned or fb.distance_remaining > 0.0 or fb.number_of_recoveries > 0
        if fb.number_of_recoveries > self.recoveries:  # each recovery as it starts
            self.recoveries = fb.number_of_recoveries
            self.print_line(f"recovery {fb.number_of_recoveries} started, {fb.distance_remaining:.2f} m to go")
        elif now - self.last_s < 1.0:
            return
        self.last_s = now
        if not self.planned:
            if fb.navigation_time.sec >= 1:
                self.print_line(f"waiting for a plan ({fb.navigation_time.sec} s): the planner has not answered yet")
            return
        p = fb.current_pose.pose.position
        self.print_line(f"at ({p.x:.2f}, {p.y:.2f}), {fb.distance_remaining:.2f} m to go, "
                        f"{fb.navigation_time.sec} s, {fb.number_of_recoveries} recoveries")


def main(args: argparse.Namespace) -> int:
    try:
        goal = goal_of(args.x, args.y, args.yaw, args.frame)
    except ValueError as exc:
        print(f"pppbot nav: {exc}")
        return 2
    rclpy.init()
    node = Node("nav_goto")
    client = ActionClient(node, NavigateToPose, "navigate_to_pose")
    handle = None
    try:
        if not client.wait_for_server(timeout_sec=args.server_timeout):
            print(f"pppbot nav: no navigate_to_pose server after {args.server_timeout} s "
                  "(is launch_sim running with navigation?)")
            return 2
        progress = Progress()
        try:
            handle = send_goal(client, goal, node, GOAL_ANSWER_S,
                               feedback_callback=lambda msg: progress.feedback(msg.feedback))
        except TimeoutExpired:
            print(f"pppbot nav: no answer from navigate_to_pose in {GOAL_ANSWER_S:g} s", file=sys.stderr)
            return 1
        if handle is None or not handle.accepted:
            print("pppbot nav: bt_navigator refused the goal; it takes goals only while active "
                  "(ros2 lifecycle get /bt_navigator; /lifecycle_manager_navigation/manage_nodes brings it up)",
                  file=sys.stderr)
            return 1
        print(f"navigating to ({args.x}, {args.y}, {args.yaw}) in '{args.frame}'", flush=True)
        progress.accepted = True
        result_future = handle.get_result_async()
        rclpy.spin_until_future_complete(node, result_future)
        response = result_future.result()
        status = STATUS.get(response.status, f"status {response.status}")
        detail = f": {response.result.error_msg} (error code {response.result.error_code})" \
            if response.status != GoalStatus.STATUS_SUCCEEDED else \
            (f" ({response.result.error_msg})" if response.result.error_msg else "")
        print(f"goal {status}{detail}")
        return 0 if response.status == GoalStatus.STATUS_SUCCEEDED else 1
    except KeyboardInterrupt:
        if handle is not None:
            cancel = handle.cancel_goal_async()
            rclpy.spin_until_future_complete(node, cancel, timeout_sec=2.0)
            print("goal canceled")
        return 1
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
