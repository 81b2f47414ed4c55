"""``ground_truth_map``: save a world's ground-truth occupancy as a Nav2 map.

    ./pppbot run pppbot_sim ground_truth_map world:=maze [resolution:=0.05] [height:=0.2] [output:=PATH]
"""
from __future__ import annotations

import sys
from pathlib import Path

from pppbot_common.launch_args import Argument, ArgumentError, describe, parse_assignments
from pppbot_common.maps import MapFileError, save_map
from pppbot_common.resources import maps_directory
from pppbot_sim.errors import WorldError
from pppbot_sim.ground_truth import ground_truth_map
from pppbot_sim.simulation import load_world
from pppbot_sim.worlds import find_world, model_paths

ARGUMENTS = [
    Argument("world", "maze", "world name (worlds/<name>.sdf) or path to an SDF or MJCF file"),
    Argument("resolution", 0.05, "cell size (m)"),
    Argument("height", 0.2, "height of the cut (m); ppp_bot's lidar is 0.2 m above the ground"),
    Argument("margin", 1.0, "free border around the world (m)"),
    Argument("output", "", "map path without extension; default maps/<world>_ground_truth"),
]


def default_output(world: str) -> Path:
    return maps_directory() / f"{Path(world).stem}_ground_truth"


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if "--show-args" in argv or "-h" in argv or "--help" in argv:
        print(__doc__.strip(), "", describe(ARGUMENTS), sep="\n")
        return 0
    try:
        args = parse_assignments(argv, ARGUMENTS)
        world_file = find_world(args["world"])
        spec, _ = load_world(world_file, model_paths(world_file))
        grid = ground_truth_map(spec.compile(), args["resolution"], args["height"], margin=args["margin"])
        yaml_path = save_map(grid, args["output"] or default_output(args["world"]))
    except (ArgumentError, WorldError, MapFileError, ValueError) as exc:
        print(f"ground_truth_map: {exc}", file=sys.stderr)
        return 1
    occupied = int((grid.data == 100).sum())
    print(f"saved {yaml_path} ({grid.width} x {grid.height} cells of {grid.resolution} m, "
          f"{occupied} occupied, origin {grid.origin[0]:.2f}, {grid.origin[1]:.2f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
