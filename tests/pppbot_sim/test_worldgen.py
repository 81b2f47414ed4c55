"""Generated worlds: seeded, loadable by the simulator, and what they were asked to be.

Each property is measured independently of the generator's own geometry: the SDF goes
through the simulator's loader into MuJoCo, and the ground-truth grid (ray-cast at the
lidar's height) gives the loops (obstacles standing free of the outer walls) and the
corridor widths (twice the distance to the nearest wall on a corridor's centre line).
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from pppbot_eval.routes import load_routes, routes_file
from pppbot_eval.scenarios import world_truth
from pppbot_sim.worldgen import mazes
from pppbot_sim.worldgen.families import Family, WorldGenError, generate
from pppbot_sim.worlds import find_world

RESOLUTION_M = 0.05


def _truth(layout, tmp_path):
    world_file = tmp_path / f"{layout.name}.sdf"
    world_file.write_text(layout.sdf("test"))
    return world_truth(world_file, resolution_m=RESOLUTION_M)


def _free_islands(grid) -> int:
    """Occupied components that do not touch the largest one (the outer walls), or all of them
    in a world without walls around it."""
    occupied = grid.data > 50
    labels, count = ndimage.label(occupied, structure=np.ones((3, 3)))
    sizes = np.bincount(labels.ravel())[1:]
    return count - 1 if sizes.max() > 200 else count


def _widths(grid):
    """``width(x, y)``: twice the distance from (x, y) to the nearest occupied cell (m)."""
    distance = ndimage.distance_transform_edt(grid.data <= 50) * grid.resolution
    return lambda x, y: 2 * float(distance[grid.cell_of(x, y)])


def test_a_family_and_seed_give_the_same_world_and_other_seeds_other_worlds():
    for family in Family:
        assert generate(family, 4).sdf("x") == generate(family, 4).sdf("x")
        assert generate(family, 4).sdf("x") != generate(family, 5).sdf("x")


def test_bad_family_or_seed_is_named():
    with pytest.raises(WorldGenError, match="unknown world family 'castle'; known: maze, looped_maze, office"):
        generate("castle", 0)
    with pytest.raises(WorldGenError, match="seed must be a non-negative integer, not -1"):
        generate(Family.MAZE, -1)


@pytest.mark.parametrize("family", list(Family))
@pytest.mark.parametrize("small", [True, False])
def test_every_family_loads_in_the_simulator_with_the_loops_it_says_and_a_free_spawn(family, small, tmp_path):
    layout = generate(family, 1, small=small)
    grid = _truth(layout, tmp_path)
    assert _free_islands(grid) == layout.loops
    assert _widths(grid)(0.0, 0.0) >= 2 * 0.45 - 2 * RESOLUTION_M  # the spawn is free around the robot


@pytest.mark.parametrize("family", [Family.CORRIDOR, Family.OFFICE, Family.SYMMETRIC])
def test_a_corridor_is_as_wide_as_the_family_made_it(family, tmp_path):
    for seed in (0, 1):
        layout = generate(family, seed)
        assert layout.corridor_width_m is not None
        (width, _) = layout.corridor_width_m
        width_at = _widths(_truth(layout, tmp_path))
        # along the corridor the robot starts in, where walls stand on both sides (not at a door)
        measured = min(width_at(x, 0.0) for x in np.arange(-3.0, 3.0, 0.1))
        assert measured == pytest.approx(width, abs=3 * RESOLUTION_M)


def test_maze_corridors_are_as_wide_as_asked_and_perfect_mazes_have_no_loops_looped_ones_some(tmp_path):
    widths = []
    for family, seed in ((Family.MAZE, 0), (Family.MAZE, 2), (Family.LOOPED_MAZE, 1)):
        layout = generate(family, seed)
        assert layout.corridor_width_m is not None
        grid = _truth(layout, tmp_path)
        pitch = layout.route.spacing_m
        nx, ny = int(layout.parameters["cells_x"]), int(layout.parameters["cells_y"])
        centres = [((i - nx // 2) * pitch, (j - ny // 2) * pitch) for i in range(nx) for j in range(ny)]
        width_at = _widths(grid)
        measured = min(width_at(x, y) for x, y in centres)  # a cell with walls on both sides
        assert measured == pytest.approx(layout.corridor_width_m[0], abs=3 * RESOLUTION_M)
        widths.append(layout.corridor_width_m[0])
        assert (_free_islands(grid) > 0) == (family is Family.LOOPED_MAZE)
    assert min(widths) < 1.1 and max(widths) > 1.5  # the seeds span the 0.9–2.0 m range


def test_mazes_reach_long_straight_runs_and_stay_within_25_m():
    runs = [generate(f, s).longest_run_m for f in (Family.MAZE, Family.LOOPED_MAZE) for s in range(6)]
    assert all(r is not None for r in runs)  # a maze always has a longest run
    runs_m = [float(r) for r in runs if r is not None]
    assert max(runs_m) >= 15.0
    assert all(r <= 25.0 for r in runs_m)


def test_carving_makes_a_spanning_tree_and_each_opened_wall_one_loop():
    rng = np.random.default_rng(0)
    nx, ny = 7, 5
    walls = mazes.carve(nx, ny, rng, straightness=0.5)
    assert len(mazes.all_edges(nx, ny)) - len(walls) == nx * ny - 1  # a tree: cells − 1 passages
    looped = mazes.open_loops(walls, nx, ny, 3, rng)
    assert len(walls) - len(looped) == 3
    assert all(not mazes.on_border(e, nx, ny) for e in walls - looped)


def test_straightness_makes_longer_runs():
    def mean_run(straightness: float) -> float:
        rng = np.random.default_rng(1)
        return float(np.mean([mazes.longest_corridor_cells(mazes.carve(15, 15, rng, straightness=straightness), 15, 15)
                              for _ in range(10)]))
    assert mean_run(0.9) > mean_run(0.0) + 3


def test_longest_corridor_counts_cells_with_no_wall_across():
    # a 4 × 1 strip with one wall across between cells 1 and 2: runs of 2
    walls = mazes.all_edges(4, 1) - {mazes.between(0, 0, 1, 0), mazes.between(2, 0, 3, 0)}
    assert mazes.longest_corridor_cells(walls, 4, 1) == 2
    assert mazes.longest_corridor_cells(walls - {mazes.between(1, 0, 2, 0)}, 4, 1) == 4


def test_the_cli_writes_a_world_and_route_the_evaluation_finds(tmp_path, load_benchmark):
    worldgen = load_benchmark("worldgen")
    assert worldgen.main(["--family", "corridor", "--seed", "0", "--small", "--out", str(tmp_path)]) == 0
    world_file = find_world(str(tmp_path / "corridor_small_000.sdf"))
    (route,) = load_routes(routes_file(world_file))
    layout = generate(Family.CORRIDOR, 0, small=True)
    assert layout.corridor_width_m is not None
    assert route.name == "coverage" and route.start == (0.0, 0.0, 0.0)
    assert np.allclose(route.points[-1], (0.0, 0.0))  # back at the start
    lap = 2 * (layout.parameters["length_x_m"] + layout.parameters["length_y_m"]) - 4 * layout.corridor_width_m[0]
    assert route.length_m > 0.8 * lap  # around the ring, not there and back along one side
    grid = world_truth(world_file, resolution_m=RESOLUTION_M)
    distance = ndimage.distance_transform_edt(grid.data <= 50) * RESOLUTION_M
    for x, y in route.points:
        assert distance[grid.cell_of(x, y)] >= layout.route.clearance_m - 2 * RESOLUTION_M
    assert worldgen.main(["--family", "castle", "--out", str(tmp_path)]) == 2


def test_every_set_world_is_named_once(load_benchmark):
    worldgen = load_benchmark("worldgen")
    names = [generate(s.family, s.seed, small=s.small).name for specs in worldgen.SETS.values() for s in specs]
    assert len(names) == len(set(names)) >= 44
    assert not {s.seed for s in worldgen.SETS["tune"]} & {s.seed for s in worldgen.SETS["held_out"]}
    assert len(worldgen.SETS["tune"]) == (len(Family) - 2) * 3  # clutter and self_similar have sets of their own
