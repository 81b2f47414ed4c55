"""Follow waypoints (nav2_simple_commander's demo, in the room): followWaypoints, each a
navigate_to_pose goal with a pause at each. Exit code 0 when every waypoint was reached."""
import sys

import rclpy
from room import LOCALIZED, BasicNavigator, TaskResult, stamped, wait_for


def main() -> int:
    rclpy.init()
    navigator = BasicNavigator()
    navigator.waitUntilNav2Active(localizer=LOCALIZED)
    waypoints = [stamped(navigator, 1.5, 0.5), stamped(navigator, 1.0, -1.0), stamped(navigator, 0.0, 0.0)]
    navigator.followWaypoints(waypoints)
    result = wait_for(navigator, lambda f: f"executing waypoint {f.current_waypoint + 1}/{len(waypoints)}")
    missed = navigator.result_future.result().result.missed_waypoints
    print(f"missed waypoints: {[m.index for m in missed]}", flush=True)
    navigator.destroyNode()
    rclpy.shutdown()
    return 0 if result == TaskResult.SUCCEEDED and not missed else 1


if __name__ == "__main__":
    sys.exit(main())
