"""Nav2's behaviours from a script (in the room): spin a quarter turn, back up, drive on the
heading. Exit code 0 when each succeeded."""
import sys

import rclpy
from room import LOCALIZED, BasicNavigator, TaskResult, wait_for


def main() -> int:
    rclpy.init()
    navigator = BasicNavigator()
    navigator.waitUntilNav2Active(localizer=LOCALIZED)
    results = []
    navigator.spin(spin_dist=1.57)
    results.append(wait_for(navigator, lambda f: f"turned {f.angular_distance_traveled:.2f} rad"))
    navigator.backup(backup_dist=0.15, backup_speed=0.1)
    results.append(wait_for(navigator, lambda f: f"backed up {f.distance_traveled:.2f} m"))
    navigator.driveOnHeading(dist=0.15, speed=0.1)
    results.append(wait_for(navigator, lambda f: f"drove {f.distance_traveled:.2f} m"))
    navigator.destroyNode()
    rclpy.shutdown()
    return 0 if all(r == TaskResult.SUCCEEDED for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
