"""Mazes on a grid of square cells: walls are unit edges between lattice points.

An edge is (x0, y0, x1, y1) on integer lattice points, horizontal (y0 == y1) or
vertical (x0 == x1); cell (i, j) spans [i, i+1] × [j, j+1]. A *perfect* maze (a
spanning tree of the cells, carved depth first) has exactly one path between any
two cells; removing inner walls after carving adds loops.
"""
from __future__ import annotations

import random

import numpy as np

Edge = tuple[int, int, int, int]
_STEPS = ((1, 0), (-1, 0), (0, 1), (0, -1))


def all_edges(nx: int, ny: int) -> set[Edge]:
    """Every cell wall of an ``nx`` × ``ny`` grid."""
    edges = {(i, j, i + 1, j) for i in range(nx) for j in range(ny + 1)}
    return edges | {(i, j, i, j + 1) for i in range(nx + 1) for j in range(ny)}


def between(ax: int, ay: int, bx: int, by: int) -> Edge:
    """The wall between neighbouring cells (ax, ay) and (bx, by)."""
    if ax != bx:
        x = max(ax, bx)
        return (x, ay, x, ay + 1)
    y = max(ay, by)
    return (ax, y, ax + 1, y)


def on_border(edge: Edge, nx: int, ny: int) -> bool:
    x0, y0, x1, y1 = edge
    return (y0 == y1 and y0 in (0, ny)) or (x0 == x1 and x0 in (0, nx))


def maze_edges(n: int, seed: int, extra_openings: int) -> set[Edge]:
    """pppbot's ``maze`` world: an ``n`` × ``n`` depth-first maze (Python's ``random``, so the
    shipped world is remade identically) with ``extra_openings`` inner walls removed."""
    rng = random.Random(seed)
    edges = all_edges(n, n)
    seen = {(0, 0)}
    stack = [(0, 0)]
    while stack:
        cx, cy = stack[-1]
        options = [(dx, dy) for dx, dy in _STEPS
                   if 0 <= cx + dx < n and 0 <= cy + dy < n and (cx + dx, cy + dy) not in seen]
        if not options:
            stack.pop()
            continue
        dx, dy = rng.choice(options)
        edges.discard(between(cx, cy, cx + dx, cy + dy))
        seen.add((cx + dx, cy + dy))
        stack.append((cx + dx, cy + dy))
    inner = sorted(e for e in edges if not on_border(e, n, n))
    for edge in rng.sample(inner, extra_openings):
        edges.discard(edge)
    return edges


def carve(nx: int, ny: int, rng: np.random.Generator, *, straightness: float = 0.0,
          start: tuple[int, int] = (0, 0)) -> set[Edge]:
    """A perfect ``nx`` × ``ny`` maze carved depth first from ``start``.

    Args:
        nx: cells across.
        ny: cells up.
        rng: the random generator the walk draws from.
        start: the cell the walk starts in.
        straightness: probability (0–1) of carving on in the direction just taken when
            that cell is free: 0 is the plain random walk, values near 1 make long
            straight corridors.

    Returns:
        The walls left standing (border included).
    """
    edges = all_edges(nx, ny)
    seen = {start}
    stack: list[tuple[int, int, tuple[int, int] | None]] = [(start[0], start[1], None)]
    while stack:
        cx, cy, heading = stack[-1]
        options = [(dx, dy) for dx, dy in _STEPS
                   if 0 <= cx + dx < nx and 0 <= cy + dy < ny and (cx + dx, cy + dy) not in seen]
        if not options:
            stack.pop()
            continue
        if heading in options and rng.random() < straightness:
            dx, dy = heading
        else:
            dx, dy = options[int(rng.integers(len(options)))]
        edges.discard(between(cx, cy, cx + dx, cy + dy))
        seen.add((cx + dx, cy + dy))
        stack.append((cx + dx, cy + dy, (dx, dy)))
    return edges


def open_loops(edges: set[Edge], nx: int, ny: int, count: int, rng: np.random.Generator) -> set[Edge]:
    """``edges`` with up to ``count`` inner walls removed at random, each one a new loop.

    A wall is removed only where both its ends stay attached to other walls: then each
    removal cuts the walls into one more piece, a piece a robot can drive around (a
    removal that left a lattice point bare would open a 2 × 2-cell room instead).
    """
    left = set(edges)
    degree: dict[tuple[int, int], int] = {}
    for x0, y0, x1, y1 in left:
        for end in ((x0, y0), (x1, y1)):
            degree[end] = degree.get(end, 0) + 1
    inner = sorted(e for e in edges if not on_border(e, nx, ny))
    opened = 0
    for i in rng.permutation(len(inner)):
        if opened == count:
            break
        x0, y0, x1, y1 = inner[int(i)]
        if degree[(x0, y0)] >= 2 and degree[(x1, y1)] >= 2:
            left.discard(inner[int(i)])
            degree[(x0, y0)] -= 1
            degree[(x1, y1)] -= 1
            opened += 1
    return left


def merge_collinear(edges: set[Edge]) -> list[Edge]:
    """Unit grid edges → maximal horizontal and vertical runs."""
    runs = []
    horizontal = sorted((y0, x0) for x0, y0, x1, y1 in edges if y0 == y1)
    vertical = sorted((x0, y0) for x0, y0, x1, y1 in edges if x0 == x1)
    for items, horizontal_run in ((horizontal, True), (vertical, False)):
        i = 0
        while i < len(items):
            line, start = items[i]
            end = start + 1
            while i + 1 < len(items) and items[i + 1] == (line, end):
                i += 1
                end += 1
            runs.append((start, line, end, line) if horizontal_run else (line, start, line, end))
            i += 1
    return runs


def longest_corridor_cells(edges: set[Edge], nx: int, ny: int) -> int:
    """The most cells in a straight line with no wall across between them (a straight run)."""
    best = 1
    for j in range(ny):  # along x
        run = 1
        for i in range(1, nx):
            run = run + 1 if between(i - 1, j, i, j) not in edges else 1
            best = max(best, run)
    for i in range(nx):
        run = 1
        for j in range(1, ny):
            run = run + 1 if between(i, j - 1, i, j) not in edges else 1
            best = max(best, run)
    return best
