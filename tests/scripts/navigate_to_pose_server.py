"""A NavigateToPose action server that 'drives' straight to the goal in 4 steps.

Feedback k (k = 1..4, every 50 ms) reports current_pose at k/4 of the way from the origin and
distance_remaining accordingly; the result is error_code NONE with an empty
error_msg. With ``--reject`` it rejects every goal (an inactive bt_navigator). Prints "ready"
when the server is up. Stops on SIGINT.
"""
from __future__ import annotations

import math
import sys
import time

import rclpy
from nav2_msgs.action import NavigateToPose
from rclpy.action import ActionServer, GoalResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node

STEPS = 4
STEP_S = 0.05
FEEDBACK_TOPIC = "/navigate_to_pose/_action/feedback"


def feedback_subscribed(node: Node, timeout_s: float = 5.0) -> bool:
    """Feedback published before discovery matched the client's subscription is lost."""
    deadline = time.monotonic() + timeout_s
    while node.count_subscribers(FEEDBACK_TOPIC) == 0 and time.monotonic() < deadline:
        time.sleep(0.01)
    return node.count_subscribers(FEEDBACK_TOPIC) > 0


def execute(node: Node, goal_handle: ServerGoalHandle) -> NavigateToPose.Result:
    feedback_subscribed(node)
    goal = goal_handle.request.pose
    gx, gy = goal.pose.position.x, goal.pose.position.y
    for k in range(1, STEPS + 1):
        feedback = NavigateToPose.Feedback()
        feedback.current_pose.header.frame_id = goal.header.frame_id
        feedback.current_pose.pose.position.x = gx * k / STEPS
        feedback.current_pose.pose.position.y = gy * k / STEPS
        feedback.distance_remaining = math.hypot(gx, gy) * (STEPS - k) / STEPS
        feedback.navigation_time.sec = k
        goal_handle.publish_feedback(feedback)
        # Paced like a navigator's control loop: rclpy drops feedback that arrives
        # after the goal's terminal status, and topics are not ordered across.
        time.sleep(STEP_S)
    goal_handle.succeed()
    return NavigateToPose.Result(error_code=NavigateToPose.Result.NONE, error_msg="")


def main() -> None:
    rclpy.init()
    node = rclpy.create_node("navigate_to_pose_server")
    reject = "--reject" in sys.argv[1:]
    ActionServer(node, NavigateToPose, "navigate_to_pose", lambda handle: execute(node, handle),
                 goal_callback=lambda _goal: GoalResponse.REJECT if reject else GoalResponse.ACCEPT)
    print("ready", flush=True)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
