"""Go to a pose (nav2_simple_commander's demo, in the room): set the initial pose, wait for Nav2,
goToPose, follow the feedback, report the result. Exit code 0 when the goal was reached."""
import sys

import rclpy
from room import START, BasicNavigator, TaskResult, stamped, wait_for


def main() -> int:
    rclpy.init()
    navigator = BasicNavigator()
    navigator.setInitialPose(stamped(navigator, *START))
    navigator.waitUntilNav2Active()  # amcl and bt_navigator active, a first amcl_pose
    navigator.goToPose(stamped(navigator, 1.5, 0.5, 1.57))
    result = wait_for(navigator, lambda f: f"distance remaining: {f.distance_remaining:.2f} m")
    navigator.destroyNode()
    rclpy.shutdown()
    return 0 if result == TaskResult.SUCCEEDED else 1


if __name__ == "__main__":
    sys.exit(main())
