"""Change the map (in the room): changeMap on map_server's load_map with a map YAML. Usage:
example_change_map.py [MAP_YAML] (default: the shipped maps/room.yaml). Exit code 0 when map_server
loaded it."""
import sys
from pathlib import Path

import rclpy
from room import LOCALIZED, BasicNavigator


def main() -> int:
    map_yaml = sys.argv[1] if len(sys.argv) > 1 else str(Path(__file__).resolve().parents[1] / "maps" / "room.yaml")
    rclpy.init()
    navigator = BasicNavigator()
    navigator.waitUntilNav2Active(localizer=LOCALIZED)
    changed = navigator.changeMap(map_yaml)
    print(f"map {'changed to' if changed else 'not changed:'} {map_yaml}", flush=True)
    navigator.destroyNode()
    rclpy.shutdown()
    return 0 if changed else 1


if __name__ == "__main__":
    sys.exit(main())
