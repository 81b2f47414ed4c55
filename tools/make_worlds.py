#!/usr/bin/env python3
"""Generate pppbot's SDF worlds and the traffic-cone model (run: ./pppbot env python tools/make_worlds.py).

The outputs are committed; this script documents how they were made and remakes
them identically (fixed seeds). Worlds:

* ``cones``: 16 traffic cones (COLLADA meshes, via ``<include>``) over 15 × 15 m, none within 1.5 m of the origin.
* ``maze``: 15.4 × 15.4 m, 11 × 11 cells of 1.4 m, walls 0.15 m thick and 2.5 m high,
  a depth-first maze with extra openings so that routes can close loops.
* ``room``: a furnished 12 × 9 m flat: four rooms with doors, a sofa, a bed,
  tables on legs, shelves, a column and plant pots.
* ``office``: 44 × 44 m: corridors, 20 offices with doors, desks and pillars.
* ``maze_boxes``, ``room_boxes``: the maze and the room with boxes that their maps
  (``maps/maze.yaml``, ``maps/room.yaml``) do not have, for navigating around
  obstacles the map does not know: in the maze, boxes that narrow corridors and two
  that close corridors on loops; in the room, boxes in the open floor.
"""
from __future__ import annotations

import math
import random
import sys
from pathlib import Path

import numpy as np
import trimesh

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT / "pppbot_sim")]

from pppbot_sim.worldgen.mazes import maze_edges, merge_collinear  # noqa: E402
from pppbot_sim.worldgen.sdf import FOOTER, WALL_H, WALL_T, Segment, box, cylinder, include, model, wall_segments, world  # noqa: E402
from pppbot_sim.worldgen.sdf import door_wall as sdf_door_wall  # noqa: E402

WORLDS = ROOT / "worlds"
GENERATOR = "tools/make_worlds.py"


def make_maze() -> str:
    n, cell = 11, 1.4  # odd: the origin (the default spawn) is a cell centre
    half = n * cell / 2
    runs = merge_collinear(maze_edges(n, seed=7, extra_openings=16))
    segments = [(x0 * cell - half, y0 * cell - half, x1 * cell - half, y1 * cell - half) for x0, y0, x1, y1 in runs]
    return world("maze", model("maze_walls", wall_segments(segments, "wall")), GENERATOR)


# ---------------------------------------------------------------------- room
def door_wall(x0: float, y0: float, x1: float, y1: float, doors: list[float], width: float = 0.9) -> list[Segment]:
    """A wall with door gaps of ``width`` between the wall pieces' centre-line ends (so
    ``width`` − WALL_T between the jambs' faces) centred at the given distances along it."""
    return sdf_door_wall(x0, y0, x1, y1, [(d, width - WALL_T) for d in doors])


def table(name: str, x: float, y: float, sx: float, sy: float) -> list[str]:
    legs = [cylinder(f"{name}_leg{i}", x + dx * (sx / 2 - 0.05), y + dy * (sy / 2 - 0.05), 0.025, 0.72)
            for i, (dx, dy) in enumerate(((1, 1), (1, -1), (-1, 1), (-1, -1)))]
    return legs + [box(f"{name}_top", x, y, sx, sy, 0.03, z0=0.72)]


#: The room's doors: a grid map shows a 1.1 m door about 0.95 m wide (its jambs' cells are
#: occupied), which leaves a robot with Nav2's inscribed radius of 0.3 m room to steer.
ROOM_DOOR_M = 1.1


def make_room() -> str:
    w, h = 12.0, 9.0
    x0, y0 = -2.5, -4.5  # the origin (the default spawn) is in the living room
    segments = [
        (x0, y0, x0 + w, y0), (x0 + w, y0, x0 + w, y0 + h), (x0 + w, y0 + h, x0, y0 + h), (x0, y0 + h, x0, y0),
        *door_wall(x0 + 5.0, y0, x0 + 5.0, y0 + h, doors=[2.0, 7.0], width=ROOM_DOOR_M),   # living | kitchen/bedroom
        *door_wall(x0 + 5.0, y0 + 4.5, x0 + w, y0 + 4.5, doors=[1.5], width=ROOM_DOOR_M),  # bedroom | study
        *door_wall(x0 + 9.0, y0 + 4.5, x0 + 9.0, y0 + h, doors=[2.2], width=ROOM_DOOR_M),  # bedroom | bath
    ]
    links = wall_segments(segments, "wall")
    furniture = [
        box("sofa", x0 + 1.0, y0 + 6.0, 0.9, 2.2, 0.8),
        box("shelf_living", x0 + 2.5, y0 + 0.3, 1.8, 0.4, 1.8),
        box("bed", x0 + 7.0, y0 + 7.6, 2.0, 1.6, 0.5),
        box("wardrobe", x0 + 8.6, y0 + 4.9, 0.6, 0.6, 2.0),
        box("desk", x0 + 10.8, y0 + 2.5, 0.7, 1.4, 0.75),
        box("kitchen_counter", x0 + 7.5, y0 + 0.35, 3.0, 0.6, 0.9),
        cylinder("column", x0 + 3.5, y0 + 6.8, 0.2, WALL_H),
        cylinder("plant1", x0 + 4.4, y0 + 8.4, 0.25, 0.6),
        cylinder("plant2", x0 + 11.5, y0 + 8.5, 0.2, 0.5),
        cylinder("bin", x0 + 9.5, y0 + 0.4, 0.15, 0.4),
    ]
    furniture += table("dining", x0 + 2.5, y0 + 2.5, 1.4, 0.9)
    furniture += table("study", x0 + 7.2, y0 + 2.4, 1.0, 0.7)
    return world("room", model("walls", links) + model("furniture", furniture), GENERATOR)


# -------------------------------------------------------------------- office
def make_office() -> str:
    size, corridor = 44.0, 2.4
    half = size / 2
    c = corridor / 2
    segments = [(-half, -half, half, -half), (half, -half, half, half),
                (half, half, -half, half), (-half, half, -half, -half)]
    # A cross of corridors splits the floor into four quadrants; each quadrant has five
    # offices along the corridor and an open hall with pillars behind them.
    room_w = (half - c) / 5
    for sx in (-1, 1):
        for sy in (-1, 1):
            # wall along the horizontal corridor, with a door into each office
            y = sy * c
            doors = [room_w * (k + 0.5) for k in range(5)]
            xa, xb = (c, half) if sx > 0 else (-c, -half)
            segments += door_wall(xa, y, xb, y, doors)
            # office partitions perpendicular to the corridor, 6 m deep, then an open hall
            for k in range(1, 5):
                x = sx * (c + room_w * k)
                segments.append((x, y, x, y + sy * 6.0))
            segments += door_wall(xa, y + sy * 6.0, xb, y + sy * 6.0, [room_w * 2.5], width=1.6)
            # wall along the vertical corridor, with two doors into the hall
            x = sx * c
            ya, yb = (y + sy * 6.0, sy * half)
            segments += door_wall(x, ya, x, yb, [3.0, 10.0], width=1.2)
    links = wall_segments(segments, "wall")
    rng = random.Random(11)
    furniture = []
    for sx in (-1, 1):
        for sy in (-1, 1):
            for k in range(5):
                x = sx * (c + room_w * (k + 0.5))
                y = sy * (c + 4.2)
                furniture.append(box(f"desk_{sx}_{sy}_{k}", x + rng.uniform(-0.5, 0.5), y, 1.4, 0.7, 0.75))
            for k in range(6):
                px = sx * (8.0 + 2.5 * k)
                py = sy * (12.0 + 3.0 * (k % 3))
                furniture.append(cylinder(f"pillar_{sx}_{sy}_{k}", px, py, 0.3, WALL_H))
    return world("office", model("walls", links) + model("furniture", furniture), GENERATOR)


# --------------------------------------------------------------------- cones
def make_cone_model() -> None:
    folder = WORLDS / "models" / "traffic_cone"
    (folder / "meshes").mkdir(parents=True, exist_ok=True)
    cone = trimesh.creation.cone(radius=0.16, height=0.7, sections=32)
    base = trimesh.creation.box(extents=[0.4, 0.4, 0.03])
    base.apply_translation([0, 0, 0.015])
    mesh = trimesh.util.concatenate([cone, base])
    (folder / "meshes" / "traffic_cone.dae").write_bytes(trimesh.exchange.dae.export_collada(mesh))
    (folder / "model.config").write_text("""<?xml version="1.0"?>
<model>
  <name>traffic_cone</name>
  <version>1.0</version>
  <sdf version="1.8">model.sdf</sdf>
  <description>A 0.7 m traffic cone on a 0.4 m square base (generated by tools/make_worlds.py).</description>
</model>
""")
    (folder / "model.sdf").write_text("""<?xml version="1.0"?>
<sdf version="1.8">
  <model name="traffic_cone">
    <static>true</static>
    <link name="link">
      <collision name="collision">
        <geometry><mesh><uri>model://traffic_cone/meshes/traffic_cone.dae</uri></mesh></geometry>
      </collision>
      <visual name="visual">
        <geometry><mesh><uri>model://traffic_cone/meshes/traffic_cone.dae</uri></mesh></geometry>
      </visual>
    </link>
  </model>
</sdf>
""")


def make_cones() -> str:
    rng = np.random.default_rng(3)
    places: list[tuple[float, float]] = []
    while len(places) < 16:
        x, y = rng.uniform(-7.0, 7.0, 2)
        if math.hypot(x, y) > 1.5 and all(math.hypot(x - a, y - b) > 1.8 for a, b in places):
            places.append((float(x), float(y)))
    includes = "".join(include("model://traffic_cone", f"cone_{i}", x, y, rng.uniform(-math.pi, math.pi))
                       for i, (x, y) in enumerate(places))
    return world("cones", includes, GENERATOR)


# ---------------------------------------------------------------- with boxes
BOX_H = 0.5  # above the lidar's 0.2 m: the scan sees them
#: (x, y, size x, size y) of the maze's unmapped boxes. Cells are 1.4 m with their centres on
#: multiples of 1.4 and 1.25 m between wall faces; a 0.35 m box in a cell's corner (0.45 m off
#: its centre both ways) leaves 0.9 m whether a wall or an opening is beside it. The two long
#: ones close corridors that lie on loops.
MAZE_BOXES = [(3.25, 1.85, 0.35, 0.35), (-1.85, -3.25, 0.35, 0.35), (4.65, 4.65, 0.35, 0.35),
              (-4.65, 2.35, 0.35, 0.35), (0.95, -3.75, 0.35, 0.35), (-2.35, 5.15, 0.35, 0.35),
              (6.05, -0.95, 0.35, 0.35), (-5.15, -5.15, 0.35, 0.35),
              (0.0, 2.8, 0.35, 1.2), (1.4, -4.2, 0.35, 1.2)]
#: The room's: on the open floor of each room, clear of doors and furniture.
ROOM_BOXES = [(0.5, 1.2, 0.4, 0.4), (-1.0, -3.2, 0.5, 0.3), (6.5, -1.5, 0.4, 0.4), (3.5, -3.2, 0.4, 0.4),
              (3.2, 1.2, 0.4, 0.4), (8.0, 2.0, 0.4, 0.4)]


def with_boxes(base: str, world: str, boxes: list[tuple[float, float, float, float]]) -> str:
    """The world ``base`` (its SDF text) as ``<base>_boxes``, with one static model of ``boxes``."""
    links = [box(f"box{i}", x, y, sx, sy, BOX_H) for i, (x, y, sx, sy) in enumerate(boxes)]
    renamed = world.replace(f'<world name="{base}">', f'<world name="{base}_boxes">', 1)
    return renamed.removesuffix(FOOTER) + model("unmapped_boxes", links) + FOOTER


def main() -> None:
    make_cone_model()
    for name, make in (("cones", make_cones), ("maze", make_maze), ("room", make_room), ("office", make_office),
                       ("maze_boxes", lambda: with_boxes("maze", make_maze(), MAZE_BOXES)),
                       ("room_boxes", lambda: with_boxes("room", make_room(), ROOM_BOXES))):
        (WORLDS / f"{name}.sdf").write_text(make())
        print(f"wrote worlds/{name}.sdf")


if __name__ == "__main__":
    main()
