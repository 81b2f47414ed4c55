"""The ``self_similar`` family: seeded, loadable by the simulator, covered by its route, and alike.

Everything is measured on what the simulator loads, not on the generator's own geometry: the
world file ``write_world`` wrote goes through the simulator's loader into MuJoCo, and its
ground-truth grid (at the lidar's height) gives the loops, the route's clearance and the
patches of grid around the rooms and the corridors that must match their twins'. The plan
(:class:`~pppbot_sim.worldgen.self_similar.Plan`, from the layout's parameters) only says
where to look.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from pppbot_eval.generated_worlds import write_world
from pppbot_eval.map_quality import occupied_cells
from pppbot_eval.routes import load_routes, routes_file
from pppbot_eval.scenarios import world_truth
from pppbot_sim.worldgen.families import SPAWN_CLEARANCE_M, Family, generate
from pppbot_sim.worldgen.sdf import WALL_T
from pppbot_sim.worldgen.self_similar import Plan

TRUTH_RESOLUTION_M = 0.025
#: ppp_bot's chassis corners are 0.25 m from base_link; the route keeps this much more (as the shipped routes).
MIN_CLEARANCE_M = 0.25 + 0.02
#: The route passes this close to every room's centre, and along most of every corridor (between the cross corridors).
ROOM_VISIT_M = 1.0
DRIVEN_FRACTION = 0.85
WORLDS = [(seed, True) for seed in range(5)] + [(seed, False) for seed in (100, 101)]


def sampled(points: np.ndarray, step_m: float = 0.02) -> np.ndarray:
    pieces = [np.linspace(a, b, max(2, int(np.ceil(np.linalg.norm(b - a) / step_m)) + 1))
              for a, b in zip(points[:-1], points[1:], strict=True)]
    return np.vstack(pieces)


@pytest.fixture(scope="module", params=WORLDS, ids=lambda w: f"seed{w[0]}{'_small' if w[1] else ''}")
def world(request, tmp_path_factory):
    """A written world: (layout, its plan, the coverage route sampled every 0.02 m, the ground-truth grid)."""
    seed, small = request.param
    layout = generate(Family.SELF_SIMILAR, seed, small=small)
    world_file, summary = write_world(layout, tmp_path_factory.mktemp(layout.name))
    (route,) = load_routes(routes_file(world_file))
    assert summary["route_length_m"] == round(route.length_m, 1)
    grid = world_truth(world_file, resolution_m=TRUTH_RESOLUTION_M)
    return layout, Plan.from_parameters(layout.parameters), route, sampled(np.vstack([[0.0, 0.0], route.points])), grid


def _patch(grid, x: float, y: float, size_x_m: float, size_y_m: float) -> np.ndarray:
    """The occupied cells of the grid's window whose lower left corner is at (x, y) m."""
    row, col = (int(v) for v in grid.cell_of(x, y))
    rows, cols = round(size_y_m / grid.resolution), round(size_x_m / grid.resolution)
    return np.asarray(occupied_cells(grid)[row:row + rows, col:col + cols])


def _alike(a: np.ndarray, b: np.ndarray) -> bool:
    """The same but for a cell at an edge: every occupied cell of each has one of the other's within a cell."""
    near = np.ones((3, 3), dtype=bool)
    return bool((a <= ndimage.binary_dilation(b, near)).all() and (b <= ndimage.binary_dilation(a, near)).all())


def test_a_seed_gives_the_same_world_and_other_seeds_other_worlds():
    for small in (False, True):
        assert generate(Family.SELF_SIMILAR, 3, small=small).sdf("x") == \
            generate(Family.SELF_SIMILAR, 3, small=small).sdf("x")
        texts = {generate(Family.SELF_SIMILAR, seed, small=small).sdf("x") for seed in range(5)}
        assert len(texts) == 5


def test_the_parameters_give_the_plan_back_and_the_seeds_vary_it():
    plans = []
    for seed in range(20):
        layout = generate(Family.SELF_SIMILAR, seed)
        plan = Plan.from_parameters(layout.parameters)
        assert plan.walls() == layout.walls
        assert layout.corridor_width_m == (plan.corridor_m, plan.hall_m)
        assert 1.4 <= plan.corridor_m < plan.hall_m  # ppp_bot passes; the hall is the widest
        assert plan.corridor_length_m >= 15.0  # the hall's plain stretch
        assert layout.longest_run_m is not None and layout.longest_run_m > plan.corridor_length_m
        assert len(layout.boxes) == 1  # the one cue
        plans.append(plan)
    assert {p.wings for p in plans} == {2, 3}
    assert {p.rooms_per_wing for p in plans} == {3, 4}
    assert len({(p.corridor_m, p.room_x_m, p.room_y_m, p.door_at_m) for p in plans}) >= 18


def test_the_spawn_is_clear_and_the_loops_are_the_blocks_standing_free(world):
    layout, plan, _, _, grid = world
    occupied = occupied_cells(grid)
    clearance = ndimage.distance_transform_edt(~occupied, sampling=grid.resolution)
    assert clearance[grid.cell_of(0.0, 0.0)] - grid.resolution >= SPAWN_CLEARANCE_M
    labels, count = ndimage.label(occupied, structure=np.ones((3, 3)))
    assert layout.loops == count - 1 == plan.wings  # the outer walls and every free-standing block


def test_the_route_keeps_ppp_bot_clear_of_the_walls(world):
    layout, _, route, points, grid = world
    assert route.start == (0.0, 0.0, 0.0)
    np.testing.assert_allclose(route.points[-1], (0.0, 0.0))  # back at the start
    clearance = ndimage.distance_transform_edt(~occupied_cells(grid), sampling=grid.resolution)
    rows, cols = grid.cell_of(points[:, 0], points[:, 1])
    # from a cell centre to the nearest wall cell's centre, less a whole cell (test_shipped_routes.py)
    nearest_wall_m = clearance[rows, cols] - grid.resolution
    assert nearest_wall_m.min() >= MIN_CLEARANCE_M, f"the route passes {nearest_wall_m.min():.3f} m from a wall"
    if layout.small:
        assert route.length_m <= 90.0


def test_the_route_enters_every_room_and_drives_along_every_corridor_and_the_hall(world):
    _, plan, route, points, _ = world
    for x, y in plan.rooms():
        assert np.hypot(points[:, 0] - x, points[:, 1] - y).min() <= ROOM_VISIT_M, f"room at ({x}, {y}) missed"
    bands = [plan.corridor_y(k) for k in range(plan.wings)] + [(-plan.hall_m / 2, plan.hall_m / 2)]
    stations = np.arange(plan.west_m, plan.east_m, 0.1)  # along the blocks, between the cross corridors
    for south, north in bands:
        inside = points[(points[:, 1] > south) & (points[:, 1] < north), 0]
        driven = np.mean([np.abs(inside - x).min(initial=np.inf) <= 0.05 for x in stations])
        assert driven >= DRIVEN_FRACTION, f"the corridor from y = {south} to {north} m is driven along {driven:.0%}"
    assert route.length_m >= (plan.wings + 1) * plan.corridor_length_m


def test_the_rooms_are_twins_but_for_the_cue(world):
    _, plan, _, _, grid = world
    margin = WALL_T  # each room with its walls
    size_x, size_y = plan.room_x_m + 2 * margin, plan.room_y_m + 2 * margin
    patches = [_patch(grid, x - size_x / 2, y - size_y / 2, size_x, size_y) for x, y in plan.rooms()]
    twins = [p for k, p in enumerate(patches) if k != plan.cue_room]
    assert len(twins) >= 3
    for patch in twins[1:]:
        assert _alike(patch, twins[0])
    assert not _alike(patches[plan.cue_room], twins[0])  # the comparison sees a 0.4 m box


def test_the_parallel_corridors_are_twins(world):
    _, plan, _, _, grid = world
    # each corridor with its walls, between the cross corridors
    patches = [_patch(grid, plan.west_m, plan.corridor_y(k)[0] - WALL_T, plan.corridor_length_m,
                      plan.corridor_m + 2 * WALL_T) for k in range(plan.wings)]
    for patch in patches[1:]:
        assert _alike(patch, patches[0])
    _, gaps = ndimage.label(~patches[0][-2, 1:-1])  # along the front wall
    assert gaps == plan.rooms_per_wing  # its doors (in the same places in every corridor)
    assert patches[0][1, 1:-1].all()  # the south wall: plain


def test_the_world_sets_hold_the_self_similar_worlds_apart(load_benchmark):
    sets = load_benchmark("worldgen").SETS
    for name in ("tune", "held_out"):
        assert len(sets[name]) == 21
        assert not {Family.CLUTTER, Family.SELF_SIMILAR} & {s.family for s in sets[name]}
    assert [(s.family, s.seed, s.small) for s in sets["self_similar_tune"]] == \
        [(Family.SELF_SIMILAR, seed, False) for seed in range(5)]
    assert [(s.family, s.seed, s.small) for s in sets["self_similar_held_out"]] == \
        [(Family.SELF_SIMILAR, seed, False) for seed in range(100, 105)]
