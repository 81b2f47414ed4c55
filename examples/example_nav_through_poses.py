"""Go through poses (nav2_simple_commander's demo, in the room): goThroughPoses by one pose to the
last. Exit code 0 when the last pose was reached."""
import sys

import rclpy
from room import LOCALIZED, BasicNavigator, TaskResult, stamped, wait_for


def main() -> int:
    rclpy.init()
    navigator = BasicNavigator()
    navigator.waitUntilNav2Active(localizer=LOCALIZED)
    poses = [stamped(navigator, 1.0, -0.8), stamped(navigator, -1.0, -0.5, 3.14)]
    navigator.goThroughPoses(poses)
    result = wait_for(navigator, lambda f: f"poses remaining: {f.number_of_poses_remaining}, "
                                           f"distance remaining: {f.distance_remaining:.2f} m")
    navigator.destroyNode()
    rclpy.shutdown()
    return 0 if result == TaskResult.SUCCEEDED else 1


if __name__ == "__main__":
    sys.exit(main())
