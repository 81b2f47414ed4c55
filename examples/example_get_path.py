"""Plan without driving (in the room): getPath from the room's centre to a pose, getPathThroughPoses,
and smoothPath on the first. Prints each path's length; exit code 0 when all three came back."""
import math
import sys

import rclpy
from nav_msgs.msg import Path
from room import LOCALIZED, BasicNavigator, stamped


def length(path: Path) -> float:
    points = [(p.pose.position.x, p.pose.position.y) for p in path.poses]
    return sum(math.dist(a, b) for a, b in zip(points, points[1:], strict=False))


def main() -> int:
    rclpy.init()
    navigator = BasicNavigator()
    navigator.waitUntilNav2Active(localizer=LOCALIZED)
    start = stamped(navigator, 0.0, 0.0)  # from here, wherever the robot is (use_start)
    path = navigator.getPath(start, stamped(navigator, -1.5, -1.0), use_start=True)
    through = navigator.getPathThroughPoses(start, [stamped(navigator, 1.5, 0.5), stamped(navigator, -1.5, -1.0)],
                                            use_start=True)
    smoothed = navigator.smoothPath(path) if path is not None else None
    for name, found in (("path", path), ("path through poses", through), ("smoothed path", smoothed)):
        print(f"{name}: " + (f"{len(found.poses)} poses, {length(found):.2f} m" if found is not None else "none"),
              flush=True)
    navigator.destroyNode()
    rclpy.shutdown()
    return 0 if None not in (path, through, smoothed) else 1


if __name__ == "__main__":
    sys.exit(main())
