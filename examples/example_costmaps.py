"""The costmaps from a script (in the room): getGlobalCostmap, getLocalCostmap (nav2_msgs/Costmap,
Nav2's 0–254 costs), then clearAllCostmaps. Exit code 0 when both came back."""
import sys

import rclpy
from room import LOCALIZED, BasicNavigator


def main() -> int:
    rclpy.init()
    navigator = BasicNavigator()
    navigator.waitUntilNav2Active(localizer=LOCALIZED)
    costmaps = {"global": navigator.getGlobalCostmap(), "local": navigator.getLocalCostmap()}
    for name, costmap in costmaps.items():
        meta = costmap.metadata
        lethal = sum(1 for cost in bytes(costmap.data) if cost == 254)
        print(f"{name} costmap: {meta.size_x} × {meta.size_y} cells of {meta.resolution:g} m in "
              f"'{costmap.header.frame_id}', {lethal} lethal", flush=True)
    navigator.clearAllCostmaps()
    print("costmaps cleared", flush=True)
    navigator.destroyNode()
    rclpy.shutdown()
    return 0 if all(c.metadata.size_x for c in costmaps.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
