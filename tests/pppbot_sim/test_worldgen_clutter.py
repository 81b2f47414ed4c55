"""The ``clutter`` family (BARN's kind of world): seeded, loadable by the simulator, passable with the
stated margin, and in the way.

Passability is checked independently of the generator's own grid: the world file
``write_world`` wrote goes through the simulator's loader into MuJoCo, and Nav2-like
``shortest_path`` plans on its ground-truth grid for a disc of 0.4 m (robot radius 0.3 m +
the 0.1 m margin). That grid marks every cell an obstacle's outline crosses, so it narrows a gap
by up to a cell on each side; at 0.025 m cells the 0.81 m and wider gaps the generator keeps
still let the disc through.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import ndimage
from shapely.geometry import LineString, Point

from pppbot_eval.generated_worlds import write_world
from pppbot_eval.routes import load_routes, routes_file
from pppbot_eval.scenarios import world_truth
from pppbot_eval.shortest_path import shortest_path
from pppbot_sim.worldgen import clutter
from pppbot_sim.worldgen.families import Family, generate

TRUTH_RESOLUTION_M = 0.025
#: ppp_bot's Nav2 robot radius (0.3 m) + the margin the generator promises (0.1 m)
PASSING_RADIUS_M = 0.4
SEEDS = range(10)


def test_a_seed_gives_the_same_world_and_other_seeds_other_worlds():
    for small in (False, True):
        assert generate(Family.CLUTTER, 3, small=small).sdf("x") == generate(Family.CLUTTER, 3, small=small).sdf("x")
        texts = {generate(Family.CLUTTER, seed, small=small).sdf("x") for seed in range(5)}
        assert len(texts) == 5


@pytest.mark.parametrize("small", [False, True])
@pytest.mark.parametrize("seed", SEEDS)
def test_the_written_world_is_passable_with_the_margin_and_its_first_route_crosses_to_the_goal(seed, small,
                                                                                                tmp_path):
    layout = generate(Family.CLUTTER, seed, small=small)
    assert layout.goal is not None and layout.path is not None
    gx, gy, yaw = layout.goal
    straight = math.hypot(gx, gy)
    assert (4.5 <= straight <= 6.5) if small else (9.0 <= straight <= 11.0)
    assert yaw == 0.0
    world_file, summary = write_world(layout, tmp_path)

    grid = world_truth(world_file, resolution_m=TRUTH_RESOLUTION_M)
    path = shortest_path(grid, (0.0, 0.0), (gx, gy), PASSING_RADIUS_M)  # raises NoPath when blocked
    assert path.length_m == pytest.approx(summary["path_length_m"], rel=0.03)  # the same shortest path

    (crossing, *others) = load_routes(routes_file(world_file))
    assert crossing.name == "crossing" and crossing.start == (0.0, 0.0, 0.0)
    assert tuple(crossing.points[-1]) == (gx, gy)
    assert crossing.length_m == pytest.approx(summary["path_length_m"], abs=0.01)
    assert [r.name for r in others] == ["coverage"]

    assert summary["goal"] == [gx, gy, 0.0]
    assert summary["narrowest_gap_m"] >= 2 * PASSING_RADIUS_M
    assert summary["path_length_m"] >= straight - 0.0005  # rounded to the millimetre
    assert summary["tortuosity"] == pytest.approx(summary["path_length_m"] / straight, abs=0.002)
    assert summary["mean_clearance_m"] > PASSING_RADIUS_M
    assert 0.0 < summary["density"] < 1.0


@pytest.mark.parametrize("seed", SEEDS)
def test_the_spawn_and_the_goal_are_clear_and_the_loops_are_the_obstacles_standing_free(seed, tmp_path):
    layout = generate(Family.CLUTTER, seed)
    assert layout.goal is not None
    for x, y in ((0.0, 0.0), layout.goal[:2]):
        assert min(o.distance(Point(x, y)) for o in layout.obstacles()) >= 0.45
    world_file = tmp_path / f"{layout.name}.sdf"
    world_file.write_text(layout.sdf("test"))
    occupied = world_truth(world_file, resolution_m=0.05).data > 50
    _, count = ndimage.label(occupied, structure=np.ones((3, 3)))
    assert layout.loops == count - 1 > 0  # every component but the walls (with what touches them)


def test_the_field_stands_in_the_way():
    blocked, tortuosity = [], []
    for seed in range(20):
        layout = generate(Family.CLUTTER, seed)
        assert layout.goal is not None
        swept = LineString([(0.0, 0.0), layout.goal[:2]]).buffer(clutter.ROBOT_RADIUS_M)
        blocked.append(any(swept.intersects(o) for o in layout.obstacles()))
        tortuosity.append(layout.parameters["tortuosity"])
        assert 0 < len(layout.boxes) <= 150
    assert np.mean(blocked) >= 0.8  # driving straight at the goal hits something in most worlds
    assert np.mean(tortuosity) > 1.02


def test_an_unpassable_fill_is_thinned_until_a_field_passes(monkeypatch):
    monkeypatch.setattr(clutter, "FILL_RANGE", (0.6, 0.6))  # a wall of obstacles: never passable as drawn
    layout = generate(Family.CLUTTER, 0, small=True)
    assert layout.parameters["fill"] == 0.6
    assert layout.parameters["tries"] > clutter.MAX_DRAWS
    assert layout.parameters["fill_used"] < 0.6
    assert layout.parameters["narrowest_gap_m"] >= 2 * PASSING_RADIUS_M


def test_the_automaton_fills_crowded_cells_and_empties_lonely_ones():
    field = np.zeros((6, 14), dtype=bool)  # rows along y: walls beyond rows 0 and 5
    field[2, 0:3] = field[3, 0] = field[3, 2] = True  # (3, 1) has 5 filled neighbours
    field[1:4, 6:9] = True  # a 3 × 3 block: its corners keep 3 filled neighbours, its centre 8
    field[2, 12] = True  # alone: it empties
    smoothed = clutter.smooth(field)
    assert smoothed[3, 1]
    assert smoothed[1:4, 6:9].all()
    assert not smoothed[2, 12]
    assert not smoothed[2, 5] and not smoothed[2, 9]  # 3 filled neighbours each: not enough to fill
    assert smoothed[0, 7]  # the wall's 3 and the block's 3
    assert not smoothed[5, 7]  # the wall's 3 alone


def test_field_boxes_cover_exactly_the_filled_cells():
    field = np.random.default_rng(4).random((30, 46)) < 0.3
    boxes = clutter.field_boxes(field, clutter.FIELD_X0_M, -clutter.CORRIDOR_M / 2)
    centres = [(clutter.FIELD_X0_M + (c + 0.5) * clutter.CELL_M, -clutter.CORRIDOR_M / 2 + (r + 0.5) * clutter.CELL_M)
               for r in range(30) for c in range(46)]
    inside = np.array([[abs(x - bx) < sx / 2 and abs(y - by) < sy / 2 for bx, by, sx, sy in boxes]
                       for x, y in centres])
    assert (inside.sum(axis=1) == field.ravel()).all()  # each filled cell in one box, each empty one in none
    assert len(boxes) < field.sum()  # runs are merged


def test_the_world_sets_keep_the_mixed_sets_and_hold_clutter_apart(load_benchmark):
    sets = load_benchmark("worldgen").SETS
    for name in ("tune", "held_out"):
        assert len(sets[name]) == 21 and Family.CLUTTER not in {s.family for s in sets[name]}
    assert [(s.family, s.seed, s.small) for s in sets["clutter_held_out"]] == \
        [(Family.CLUTTER, seed, False) for seed in range(100, 200)]
    assert [s.seed for s in sets["clutter_tune"]] == list(range(10))
