"""The ``self_similar`` family: places that look alike, where SLAM is tempted to close false loops.

A world is a building of identical *wings* stacked along y above a long plain *hall*::

    +----+-----------------------------------+----+
    |    | room | room | room |   (closed)   |    |   wing 1: a row of rooms,
    +----+--d---+--d---+--d---+--------------+----+   doors (d) on corridor 1
    |                  corridor 1                 |
    |    +------+------+------+--------------+    |
    |    | room | room | room |   (closed)   |    |   wing 0: the same, a pitch lower
    |    +--d---+--d---+--d---+--------------+    |
    |                  corridor 0                 |
    |    +-----------------------------------+    |   a wall, or a closed strip
    |  S→                  hall                   |
    +---------------------------------------------+

* The wings' corridors are the **parallel identical corridors**: the same width and length,
  joined at both ends by cross corridors (as wide; the columns at the ends of the sketch), so a
  route drives around each block.
* Each wing has the same **row of identical rooms** on the same side of its corridor: the same
  size, the same door at the same place, the row at the same distance along the corridor; the
  rest of the block is closed (unreachable). Neighbouring rooms lie 2.55–3.55 m apart, about the
  slam node's local loop search distance (3 m), the corridors 4–6 m apart, well within its global
  one (15 m).
* The **hall** below corridor 0 runs the building's whole length, wider than the corridors; its
  walls are plain between the cross corridors: :attr:`Plan.corridor_length_m`, 15–21 m (5–6 m
  when small), straight walls and nothing else — scan matching cannot tell how far along it is.

The robot spawns on the hall's centre line, ``start_m`` past the west cross corridor, facing +x
down the hall. The only cue is one 0.4 m box in the back corner of one room
(``cue_room``, rooms counted wing by wing from the west; ``cue_east``: the corner by the east
partition): everything else has a twin. Sizes are multiples of :data:`GRAIN_M`, so twins fall on
a map's cells alike (shifted by whole cells of 0.05 m).

The coverage route's lattice (aligned with the spawn) is fitted to the building: its spacing is a
quarter of the wings' pitch; the hall's centre line is a lattice row, and the hall is narrow enough
to hold no other; between the hall and corridor 0 stands a wall or a closed strip as deep as puts
every corridor's centre line on a lattice row, and so every room's centre (half a pitch above its
corridor's); the cross corridors' centre lines are lattice columns. So the route drives down the
middle of every corridor and of the hall, once, instead of weaving between lattice rows on either
side, and passes within 0.8 m of every room's centre.

The loops a route can drive: each block between two corridors, and the wall (or strip) between
corridor 0 and the hall: as many as there are wings.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from pppbot_sim.worldgen.sdf import WALL_T, Segment, door_wall

#: Drawn sizes are multiples of this (m).
GRAIN_M = 0.1
#: Side of the one cue box (m).
CUE_M = 0.4
#: The coverage route's lattice spacing is the wings' pitch over this: rows on the corridors and the rooms.
ROUTE_ROWS_PER_PITCH = 4
#: The route's clearance from walls and planning grid (m). On the 0.1 m grid a cell is free when its
#: centre is more than 0.39 m from every wall cell's: a 0.9 m door narrowed by a cell on each side still
#: leaves a free cell, and the route stays 0.3 m from walls (ppp_bot's chassis corners are 0.25 m from
#: base_link). The 0.1 m grid keeps the route's planning to a few seconds.
ROUTE_CLEARANCE_M = 0.34
ROUTE_RESOLUTION_M = 0.1
#: A closed part of a block (beside its row of rooms) is at least this long (m), or not there.
MIN_CLOSED_M = 1.0
#: The boxes overlap the walls they stand against by this much (m): no gap to map.
OVERLAP_M = 0.01


def _draw(rng: np.random.Generator, low: float, high: float) -> float:
    """A length drawn uniformly from [low, high] m, rounded to :data:`GRAIN_M`."""
    return round(round(float(rng.uniform(low, high)) / GRAIN_M) * GRAIN_M, 3)


def _r(value: float) -> float:
    return round(float(value), 3)


@dataclass(frozen=True)
class Plan:
    """A self-similar building (module docstring); lengths in m, clear between wall faces.

    Its fields are the layout's parameters: :meth:`from_parameters` gives the plan back.
    """

    wings: int
    corridor_m: float  # width of every corridor but the hall, cross corridors included
    corridor_length_m: float  # each wing's block along x, and the hall's plain stretch
    rooms_per_wing: int
    room_x_m: float  # a room's width along its corridor
    room_y_m: float  # a room's depth
    door_m: float
    door_at_m: float  # a door's centre from its room's west wall face
    rooms_from_m: float  # the row's west end (its first wall's west face) from the block's west face
    hall_m: float
    hall_gap_m: float  # from the hall's north face to corridor 0's south face (a wall or a closed strip)
    start_m: float  # the spawn from the block's west face (the hall's plain stretch begins there)
    route_spacing_m: float  # of the coverage route's lattice
    cue_room: int
    cue_east: int  # 1: the cue stands in the room's back corner by its east wall; 0: by its west wall

    @classmethod
    def from_parameters(cls, parameters: dict[str, float]) -> Plan:
        """The plan whose :meth:`parameters` these are (other keys are ignored)."""
        values: dict[str, Any] = {f.name: int(parameters[f.name]) if f.type == "int" else float(parameters[f.name])
                                  for f in fields(cls)}
        return cls(**values)

    def parameters(self) -> dict[str, float]:
        return {f.name: getattr(self, f.name) for f in fields(self)}

    # ------------------------------------------------------------------ places
    @property
    def west_m(self) -> float:
        """x of the blocks' (and the hall's plain stretch's) west face."""
        return -self.start_m

    @property
    def east_m(self) -> float:
        return self.west_m + self.corridor_length_m

    @property
    def pitch_m(self) -> float:
        """From one wing to the next along y: corridor, wall, room, wall."""
        return self.corridor_m + self.room_y_m + 2 * WALL_T

    @property
    def room_pitch_m(self) -> float:
        return self.room_x_m + WALL_T

    def corridor_y(self, wing: int) -> tuple[float, float]:
        """The clear y range (south face, north face) of ``wing``'s corridor."""
        south = self.hall_m / 2 + self.hall_gap_m + wing * self.pitch_m
        return _r(south), _r(south + self.corridor_m)

    def rooms(self) -> list[tuple[float, float]]:
        """Every room's centre (x, y), wing by wing from the south, west to east in a wing."""
        return [(_r(self.west_m + self.rooms_from_m + WALL_T + j * self.room_pitch_m + self.room_x_m / 2),
                 _r(self.corridor_y(k)[1] + WALL_T + self.room_y_m / 2))
                for k in range(self.wings) for j in range(self.rooms_per_wing)]

    @property
    def outer_m(self) -> tuple[float, float, float, float]:
        """The outer walls' centre lines: west x, south y, east x, north y."""
        return (_r(self.west_m - self.corridor_m - WALL_T / 2), _r(-self.hall_m / 2 - WALL_T / 2),
                _r(self.east_m + self.corridor_m + WALL_T / 2), _r(self.corridor_y(self.wings)[0] - WALL_T / 2))

    @property
    def longest_run_m(self) -> float:
        """The hall's and each corridor's clear length from the west outer wall to the east one."""
        west, _, east, _ = self.outer_m
        return _r(east - west - WALL_T)

    # ------------------------------------------------------------------- walls
    def walls(self) -> tuple[Segment, ...]:
        """Every wall's centre line: the outer rectangle, the hall's north wall, each wing's block."""
        west, south, east, north = self.outer_m
        x0, x1 = _r(self.west_m + WALL_T / 2), _r(self.east_m - WALL_T / 2)  # the blocks' end walls
        walls: list[Segment] = [(west, south, east, south), (east, south, east, north),
                                (east, north, west, north), (west, north, west, south)]
        hall, strip = _r(self.hall_m / 2 + WALL_T / 2), _r(self.corridor_y(0)[0] - WALL_T / 2)
        walls.append((x0, hall, x1, hall))  # the hall's north wall
        if strip > hall:  # corridor 0's south wall, and the ends of the strip they close
            walls += [(x0, strip, x1, strip), (x0, hall, x0, strip), (x1, hall, x1, strip)]
        doors = [(self.rooms_from_m + WALL_T / 2 + j * self.room_pitch_m + self.door_at_m, self.door_m)
                 for j in range(self.rooms_per_wing)]  # along the front wall, from its west end x0
        partitions = [_r(self.west_m + self.rooms_from_m + WALL_T / 2 + j * self.room_pitch_m)
                      for j in range(self.rooms_per_wing + 1)]
        partitions = [x for x in partitions if x0 + 0.01 < x < x1 - 0.01]  # not where an end wall stands
        for k in range(self.wings):
            front = _r(self.corridor_y(k)[1] + WALL_T / 2)
            back = _r(front + WALL_T + self.room_y_m)
            if k < self.wings - 1:
                walls += door_wall(x0, front, x1, front, doors)
                walls.append((x0, back, x1, back))
            else:  # the top wing's back wall is the outer one; its front wall closes the cross corridors
                walls += door_wall(west, front, east, front, [(at + x0 - west, width) for at, width in doors])
            walls += [(x0, front, x0, back), (x1, front, x1, back)]
            walls += [(x, front, x, back) for x in partitions]
        return tuple((_r(a), _r(b), _r(c), _r(d)) for a, b, c, d in walls)

    def cue(self) -> tuple[float, float, float, float]:
        """The cue box: centre x, y and size x, y (m), in its room's back corner, touching both walls."""
        x, y = self.rooms()[self.cue_room]
        side = 1 if self.cue_east else -1
        inset = self.room_x_m / 2 - CUE_M / 2 + OVERLAP_M
        return _r(x + side * inset), _r(y + self.room_y_m / 2 - CUE_M / 2 + OVERLAP_M), CUE_M, CUE_M


def draw(rng: np.random.Generator, small: bool) -> Plan:
    """A plan drawn from ``rng``: 2 wings of 3–4 rooms in blocks of 15–20 m, or 3 wings of 3 rooms in blocks
    of 15–17 m (each made a whole number of lattice spacings, a little longer); small: 2 wings of 2 rooms
    filling their blocks. The route's lattice is fitted to it (module docstring)."""
    wings = 2 if small else int(rng.integers(2, 4))
    corridor = _draw(rng, 1.4, 1.6 if small else 2.0)
    rooms = 2 if small else 3 if wings == 3 else int(rng.integers(3, 5))
    room_x = _draw(rng, 2.4, 2.6 if small else 3.4)
    room_y = _draw(rng, 2.4, 2.6) if small else _draw(rng, 2.6, 3.6)
    door = _draw(rng, 0.9, 1.1)
    door_at = _draw(rng, door / 2 + 0.4, room_x - door / 2 - 0.4)
    spacing = _r((corridor + room_y + 2 * WALL_T) / ROUTE_ROWS_PER_PITCH)
    # one lattice row in the hall: its clear band (0.34 m off each wall, a grid cell more) stops short of ±spacing
    hall = _draw(rng, max(2.0, corridor + 0.2), min(2.2 if small else 2.6, 2 * spacing + 0.2))
    # corridor 0's centre line onto the first lattice row past the hall's north wall
    gap = _r(math.ceil((hall / 2 + WALL_T + corridor / 2) / spacing) * spacing - hall / 2 - corridor / 2)
    row = _r(rooms * (room_x + WALL_T) + WALL_T)
    if small:  # the rooms fill the block
        length = row
    else:  # the cross corridors' centre lines onto lattice columns: the block reaches a whole number of spacings
        length = max(_draw(rng, 15.0, 20.0 if wings == 2 else 17.0), row + MIN_CLOSED_M)
        length = _r(math.ceil((length + corridor) / spacing) * spacing - corridor)
    # the west cross corridor's centre line onto a lattice column, the spawn within the block's first quarter
    columns = int(rng.integers(1, max(2, math.floor((length / 4 + corridor / 2) / spacing) + 1)))
    start = _r(columns * spacing - corridor / 2)
    spare = _r(length - row)  # the closed part of the block, on one side of the row or both
    rooms_from = _draw(rng, 0.0, spare)
    if rooms_from < MIN_CLOSED_M or spare - rooms_from < MIN_CLOSED_M:
        rooms_from = 0.0 if rooms_from < spare / 2 else spare
    return Plan(wings=wings, corridor_m=corridor, corridor_length_m=length, rooms_per_wing=rooms, room_x_m=room_x,
                room_y_m=room_y, door_m=door, door_at_m=door_at, rooms_from_m=rooms_from, hall_m=hall,
                hall_gap_m=gap, start_m=start, route_spacing_m=spacing,
                cue_room=int(rng.integers(wings * rooms)), cue_east=int(rng.integers(2)))
