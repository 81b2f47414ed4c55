"""Seeded, procedurally generated worlds of several families, for testing autonomy on worlds
nobody tuned it for.

:func:`generate` makes a :class:`Layout` (walls, boxes, pillars, cones, and what the
layout was asked to be) from a family and a seed; :meth:`Layout.sdf` writes it as an SDF
world the simulator loads like any other. The robot spawns at the origin facing +x, in
free space with at least 0.45 m around it. Families:

* ``maze`` — a perfect maze (one path between any two cells), corridors 0.9–2.0 m wide,
  carved with a bias to go straight, so straight runs reach 25 m;
* ``looped_maze`` — the same with inner walls removed: loops, as in a real building;
* ``office`` — a corridor with rooms on both sides, doors 0.9–1.2 m, desks and
  cabinets, some rooms connected to their neighbour;
* ``corridor`` — a long featureless ring corridor (20–36 m) — the degenerate case of
  scan matching, nothing but two parallel walls for most of the way;
* ``hall`` — a large hall (up to 28 × 22 m) with a few sparse pillars;
* ``symmetric`` — a row of identical rooms between two corridors, each room with a door
  on both at the same place: near-symmetric and repetitive (one box tells two ends apart);
* ``cones`` — outdoor ground with traffic cones (ppp_bot's cones world), no walls;
* ``clutter`` — BARN's kind of world (:mod:`pppbot_sim.worldgen.clutter`): a field of blob-like
  obstacles grown by a cellular automaton across a 4.5 m corridor, a goal 10 m ahead beyond it,
  always reachable through gaps wider than 0.8 m; the layout carries the goal and the shortest
  passable path to it;
* ``self_similar`` — places that look alike (:mod:`pppbot_sim.worldgen.self_similar`): 2–3 identical
  wings, each a corridor with the same row of identical rooms, the corridors parallel and joined at
  both ends, above a hall with 15–21 m of plain walls; one small box is the only cue.

A layout also carries its coverage route's settings; the route itself is computed from
the world by :func:`pppbot_eval.coverage.coverage_route`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum

import numpy as np
from shapely.geometry import Point, Polygon
from shapely.geometry import box as shapely_box
from shapely.ops import unary_union

from pppbot_sim.errors import WorldGenError
from pppbot_sim.worldgen import clutter, mazes, sdf, self_similar
from pppbot_sim.worldgen.sdf import WALL_T, Segment, door_wall

#: Free radius around the spawn pose (m).
SPAWN_CLEARANCE_M = 0.45
#: Height of furniture boxes (m): above the lidar (0.2 m), below the walls.
FURNITURE_H = 0.75


class Family(str, Enum):
    MAZE = "maze"
    LOOPED_MAZE = "looped_maze"
    OFFICE = "office"
    CORRIDOR = "corridor"
    HALL = "hall"
    SYMMETRIC = "symmetric"
    CONES = "cones"
    CLUTTER = "clutter"
    SELF_SIMILAR = "self_similar"  # last: each family's rng is seeded with its index


@dataclass(frozen=True)
class Box:
    x: float
    y: float
    size_x: float
    size_y: float
    height: float = FURNITURE_H


@dataclass(frozen=True)
class Pillar:
    x: float
    y: float
    radius: float


@dataclass(frozen=True)
class RouteSettings:
    """The coverage route's lattice spacing, wall clearance, inset from the outer bounds and
    planning resolution (m), as :class:`pppbot_eval.coverage.Coverage` takes them."""

    spacing_m: float
    clearance_m: float
    inset_m: float = 0.0
    resolution_m: float = 0.1


@dataclass(frozen=True)
class Layout:
    """A generated world. Walls are centre lines ``WALL_T`` thick; cones are (x, y, yaw)."""

    name: str
    family: Family
    seed: int
    walls: tuple[Segment, ...]
    route: RouteSettings
    small: bool = False
    boxes: tuple[Box, ...] = ()
    pillars: tuple[Pillar, ...] = ()
    cones: tuple[tuple[float, float, float], ...] = ()
    #: the narrowest and widest corridor the family made (m, clear between wall faces); None without corridors
    corridor_width_m: tuple[float, float] | None = None
    #: the longest straight corridor (m, clear length); None without corridors
    longest_run_m: float | None = None
    #: what else the generator chose (sizes, counts), for reports
    parameters: dict[str, float] = field(default_factory=dict)
    #: the goal (x, y, yaw; m, rad) of a world made to be crossed; None in the others
    goal: tuple[float, float, float] | None = None
    #: the shortest passable path (m) from the spawn to ``goal``, both included; None without a goal
    path: tuple[tuple[float, float], ...] | None = None

    def obstacles(self) -> list[Polygon]:
        """Every wall, box and pillar as a footprint polygon (cones as 0.16 m discs)."""
        shapes = [_wall_polygon(w) for w in self.walls]
        shapes += [shapely_box(b.x - b.size_x / 2, b.y - b.size_y / 2, b.x + b.size_x / 2, b.y + b.size_y / 2)
                   for b in self.boxes]
        shapes += [Point(p.x, p.y).buffer(p.radius, 16) for p in self.pillars]
        shapes += [Point(x, y).buffer(0.16, 16) for x, y, _ in self.cones]
        return shapes

    @property
    def loops(self) -> int:
        """Independent loops a robot can drive around: obstacles standing free of the outer walls
        (pillars, cones and inner wall islands count; a world without outer walls counts each)."""
        parts = unary_union(self.obstacles())
        pieces = list(getattr(parts, "geoms", [parts]))
        if not self.walls:
            return len(pieces)
        outer = max(pieces, key=lambda p: p.convex_hull.area)
        return len(pieces) - 1 if outer.convex_hull.contains(Point(0.0, 0.0)) else len(pieces)

    def sdf(self, generator: str) -> str:
        """The SDF world text; ``generator`` is named in its header comment."""
        body = ""
        if self.walls:
            body += sdf.model("walls", sdf.wall_segments(list(self.walls), "wall"))
        furniture = [sdf.box(f"box{i}", b.x, b.y, b.size_x, b.size_y, b.height) for i, b in enumerate(self.boxes)]
        furniture += [sdf.cylinder(f"pillar{i}", p.x, p.y, p.radius, sdf.WALL_H) for i, p in enumerate(self.pillars)]
        if furniture:
            body += sdf.model("furniture", furniture)
        body += "".join(sdf.include("model://traffic_cone", f"cone_{i}", x, y, yaw)
                        for i, (x, y, yaw) in enumerate(self.cones))
        return sdf.world(self.name, body, generator)


def _wall_polygon(segment: Segment) -> Polygon:
    x0, y0, x1, y1 = segment
    half = WALL_T / 2
    return Polygon([(min(x0, x1) - half, min(y0, y1) - half), (max(x0, x1) + half, min(y0, y1) - half),
                    (max(x0, x1) + half, max(y0, y1) + half), (min(x0, x1) - half, max(y0, y1) + half)])


def _rectangle(x0: float, y0: float, x1: float, y1: float) -> list[Segment]:
    return [(x0, y0, x1, y0), (x1, y0, x1, y1), (x1, y1, x0, y1), (x0, y1, x0, y0)]


def _r(value: float) -> float:
    return round(float(value), 3)


# ---------------------------------------------------------------------- mazes
def _maze(rng: np.random.Generator, small: bool, loops: bool) -> dict:
    width = _r(rng.uniform(0.9, 2.0))
    pitch = width + WALL_T
    long_m, short_m = (rng.uniform(8.0, 11.0), rng.uniform(5.0, 7.0)) if small else \
        (rng.uniform(14.0, 25.0), rng.uniform(7.0, 13.0))
    nx, ny = max(3, int(long_m // pitch)), max(3, int(short_m // pitch))
    if rng.random() < 0.5:
        nx, ny = ny, nx
    start = (nx // 2, ny // 2)
    straightness = _r(rng.uniform(0.3, 0.9))
    edges = mazes.carve(nx, ny, rng, straightness=straightness, start=start)
    opened = 0
    if loops:
        opened = max(2, round(0.06 * nx * ny))
        edges = mazes.open_loops(edges, nx, ny, opened, rng)
    ox, oy = (start[0] + 0.5) * pitch, (start[1] + 0.5) * pitch
    walls = tuple((a * pitch - ox, b * pitch - oy, c * pitch - ox, d * pitch - oy)
                  for a, b, c, d in mazes.merge_collinear(edges))
    clearance = min(0.4, width / 2 - 0.1)
    return dict(walls=walls, corridor_width_m=(width, width),
                longest_run_m=_r(mazes.longest_corridor_cells(edges, nx, ny) * pitch - WALL_T),
                route=RouteSettings(pitch, clearance, resolution_m=0.05 if width < 1.3 else 0.1),
                parameters={"cells_x": nx, "cells_y": ny, "straightness": straightness, "opened_walls": opened})


# --------------------------------------------------------------------- office
def _office(rng: np.random.Generator, small: bool) -> dict:
    corridor = _r(rng.uniform(1.4, 2.4))
    depth = _r(rng.uniform(3.5, 5.5))
    rooms = int(rng.integers(2, 4)) if small else int(rng.integers(3, 7))
    widths = np.round(rng.uniform(2.8, 4.5, size=rooms), 3)
    length = float(widths.sum())
    x0 = -length / 2
    c = (corridor + WALL_T) / 2  # the corridor's walls' centre lines: ``corridor`` clear between them
    walls: list[Segment] = _rectangle(x0, -c - depth, x0 + length, c + depth)
    boxes: list[Box] = []
    linked = 0
    edges = np.concatenate([[0.0], np.cumsum(widths)])
    for side in (1, -1):
        doors = []
        for k in range(rooms):
            w = float(widths[k])
            door = _r(rng.uniform(0.9, 1.2))
            doors.append((float(edges[k]) + _r(rng.uniform(door / 2 + 0.4, w - door / 2 - 0.4)), door))
            # a desk or cabinet against the back wall, away from the door side
            size_x, size_y = _r(rng.uniform(0.6, 1.4)), _r(rng.uniform(0.4, 0.7))
            bx = x0 + float(edges[k]) + _r(rng.uniform(size_x / 2 + 0.2, w - size_x / 2 - 0.2))
            by = side * (c + depth - WALL_T / 2 - size_y / 2 + 0.01)  # touching the wall: no gap to map
            boxes.append(Box(bx, by, size_x, size_y))
        walls += door_wall(x0, side * c, x0 + length, side * c, doors)
        for k in range(1, rooms):  # partitions, some with a door to the neighbour
            x = x0 + float(edges[k])
            if rng.random() < 0.35:
                walls += door_wall(x, side * c, x, side * (c + depth), [(depth * 0.6, 0.9)])
                linked += 1
            else:
                walls.append((x, side * c, x, side * (c + depth)))
    return dict(walls=tuple(walls), boxes=tuple(boxes), corridor_width_m=(corridor, corridor),
                longest_run_m=_r(length - WALL_T), route=RouteSettings(1.0, 0.3, resolution_m=0.05),
                parameters={"rooms": 2 * rooms, "room_depth_m": depth, "linked_rooms": linked})


# ------------------------------------------------------------------- corridor
def _corridor(rng: np.random.Generator, small: bool) -> dict:
    width = _r(rng.uniform(1.4, 2.4))
    lx = _r(rng.uniform(12.0, 16.0) if small else rng.uniform(20.0, 36.0))
    ly = _r(rng.uniform(6.5, 8.0) if small else rng.uniform(8.0, 16.0))
    # the ring's outer wall faces span lx × ly; the robot starts halfway along the bottom corridor
    y0 = -width / 2 - WALL_T / 2
    outer = _rectangle(-lx / 2, y0, lx / 2, y0 + ly)
    t = width + WALL_T  # from the outer wall's centre line to the inner one's
    inner = _rectangle(-lx / 2 + t, y0 + t, lx / 2 - t, y0 + ly - t)
    return dict(walls=tuple(outer + inner), corridor_width_m=(width, width), longest_run_m=_r(lx - WALL_T),
                route=RouteSettings(2.0, min(0.4, width / 2 - 0.1)),
                parameters={"length_x_m": lx, "length_y_m": ly})


# ----------------------------------------------------------------------- hall
def _spread(rng: np.random.Generator, count: int, x_range: tuple[float, float], y_range: tuple[float, float],
            separation_m: float, keep_out_m: float) -> list[tuple[float, float]]:
    places: list[tuple[float, float]] = []
    for _ in range(count * 200):
        if len(places) == count:
            break
        x, y = float(rng.uniform(*x_range)), float(rng.uniform(*y_range))
        if math.hypot(x, y) > keep_out_m and all(math.hypot(x - a, y - b) > separation_m for a, b in places):
            places.append((_r(x), _r(y)))
    return places


def _hall(rng: np.random.Generator, small: bool) -> dict:
    lx = _r(rng.uniform(10.0, 13.0) if small else rng.uniform(14.0, 28.0))
    ly = _r(rng.uniform(8.0, 10.0) if small else rng.uniform(12.0, 22.0))
    cx, cy = _r(rng.uniform(-lx / 4, lx / 4)), _r(rng.uniform(-ly / 4, ly / 4))  # the origin is off centre
    count = int(rng.integers(3, 6)) if small else int(rng.integers(4, 11))
    places = _spread(rng, count, (cx - lx / 2 + 1.5, cx + lx / 2 - 1.5), (cy - ly / 2 + 1.5, cy + ly / 2 - 1.5),
                     separation_m=3.0, keep_out_m=1.5)
    pillars = tuple(Pillar(x, y, _r(rng.uniform(0.15, 0.35))) for x, y in places)
    return dict(walls=tuple(_rectangle(cx - lx / 2, cy - ly / 2, cx + lx / 2, cy + ly / 2)), pillars=pillars,
                route=RouteSettings(2.5, 0.5), parameters={"length_x_m": lx, "length_y_m": ly, "pillars": len(pillars)})


# ------------------------------------------------------------------ symmetric
def _symmetric(rng: np.random.Generator, small: bool) -> dict:
    corridor = _r(rng.uniform(1.4, 2.0))
    room = _r(rng.uniform(3.5, 5.0))
    count = int(rng.integers(2, 4)) if small else int(rng.integers(4, 7))
    door = _r(rng.uniform(0.9, 1.2))
    offset = _r(rng.uniform(door / 2 + 0.4, room - door / 2 - 0.4))
    length = count * room
    # bottom corridor centred on y = 0, rooms above it, the top corridor above them, joined at both ends
    c = (corridor + WALL_T) / 2  # centre line to centre line: ``corridor`` clear between wall faces
    x0, x1 = -length / 2 - corridor - WALL_T, length / 2 + corridor + WALL_T
    walls: list[Segment] = _rectangle(x0, -c, x1, c + room + corridor + WALL_T)
    for y in (c, c + room):
        walls += door_wall(-length / 2, y, length / 2, y, [(k * room + offset, door) for k in range(count)])
    for k in range(count + 1):
        x = -length / 2 + k * room
        walls.append((x, c, x, c + room))
    # one box in one room: the only thing that tells the rooms apart
    k = int(rng.integers(count))
    cue = Box(_r(-length / 2 + k * room + room / 2), _r(c + room / 2), 0.4, 0.4)
    return dict(walls=tuple(walls), boxes=(cue,), corridor_width_m=(corridor, corridor),
                longest_run_m=_r(x1 - x0 - WALL_T), route=RouteSettings(1.0, 0.35, resolution_m=0.05),
                parameters={"rooms": count, "room_m": room, "door_m": door})


# ---------------------------------------------------------------------- cones
def _cones(rng: np.random.Generator, small: bool) -> dict:
    half = _r(rng.uniform(5.0, 7.0) if small else rng.uniform(7.0, 14.0))
    count = max(8, round((2 * half) ** 2 / rng.uniform(10.0, 20.0)))
    places = _spread(rng, count, (-half, half), (-half, half), separation_m=1.8, keep_out_m=1.5)
    cones = tuple((x, y, _r(rng.uniform(-math.pi, math.pi))) for x, y in places)
    return dict(walls=(), cones=cones, route=RouteSettings(2.5, 0.6, inset_m=1.5),
                parameters={"half_size_m": half, "cones": len(cones)})


# -------------------------------------------------------------------- clutter
def _clutter(rng: np.random.Generator, small: bool) -> dict:
    world = clutter.clutter(rng, small)
    return dict(walls=world.walls, boxes=tuple(Box(*b) for b in world.boxes), goal=world.goal, path=world.path,
                corridor_width_m=(clutter.CORRIDOR_M, clutter.CORRIDOR_M),
                route=RouteSettings(1.0, clutter.CLEARANCE_M, resolution_m=0.05), parameters=world.parameters)


# --------------------------------------------------------------- self-similar
def _self_similar(rng: np.random.Generator, small: bool) -> dict:
    plan = self_similar.draw(rng, small)
    return dict(walls=plan.walls(), boxes=(Box(*plan.cue()),), corridor_width_m=(plan.corridor_m, plan.hall_m),
                longest_run_m=plan.longest_run_m, parameters=plan.parameters(),
                route=RouteSettings(plan.route_spacing_m, self_similar.ROUTE_CLEARANCE_M,
                                    resolution_m=self_similar.ROUTE_RESOLUTION_M))


_MAKERS = {
    Family.MAZE: lambda rng, small: _maze(rng, small, loops=False),
    Family.LOOPED_MAZE: lambda rng, small: _maze(rng, small, loops=True),
    Family.OFFICE: _office,
    Family.CORRIDOR: _corridor,
    Family.HALL: _hall,
    Family.SYMMETRIC: _symmetric,
    Family.CONES: _cones,
    Family.CLUTTER: _clutter,
    Family.SELF_SIMILAR: _self_similar,
}


def family_of(name: str) -> Family:
    """The family called ``name``.

    Raises:
        WorldGenError: no such family; the message lists them.
    """
    try:
        return Family(name)
    except ValueError:
        raise WorldGenError(f"unknown world family '{name}'; known: {', '.join(f.value for f in Family)}") from None


def world_name(family: Family, seed: int, small: bool = False) -> str:
    return f"{family.value}{'_small' if small else ''}_{seed:03d}"


def generate(family: Family | str, seed: int, *, small: bool = False) -> Layout:
    """The world of ``family`` made from ``seed`` (the same layout on every machine).

    Args:
        family: a :class:`Family` or its name.
        seed: the layout's seed (0 or more).
        small: about half the size (for tests and CI: short routes).

    Raises:
        WorldGenError: an unknown family or a negative seed.
    """
    fam = family if isinstance(family, Family) else family_of(family)
    if not isinstance(seed, int) or seed < 0:
        raise WorldGenError(f"seed must be a non-negative integer, not {seed!r}")
    rng = np.random.default_rng([list(Family).index(fam), seed, int(small)])
    layout = Layout(name=world_name(fam, seed, small), family=fam, seed=seed, small=small,
                    **_MAKERS[fam](rng, small))
    spawn = Point(0.0, 0.0).buffer(SPAWN_CLEARANCE_M)
    hit = [s for s in layout.obstacles() if s.intersects(spawn)]
    if hit:  # a generator bug, not bad input: every family leaves its spawn free by construction
        raise AssertionError(f"{layout.name}: the spawn pose is within {SPAWN_CLEARANCE_M} m of an obstacle")
    return layout
