"""Ground-truth maps: walls where they are, free space inside, Nav2 files that read back."""
from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

from pppbot_common.maps import FREE, OCCUPIED, load_map
from pppbot_sim.ground_truth import Bounds, ground_truth_map
from pppbot_sim.simulation import load_world
from pppbot_sim.worlds import find_world, model_paths

DATA = Path(__file__).parent / "data"
PPPBOT = str(Path(__file__).resolve().parents[2] / "pppbot")


def compiled(world: str | Path):
    path = find_world(str(world))
    spec, _ = load_world(path, model_paths(path))
    return spec.compile()


def occupied_at(grid, x, y) -> bool:
    row, col = grid.cell_of(x, y)
    return bool(grid.data[row, col] == OCCUPIED)


def test_box_room_walls_and_free_inside():
    grid = ground_truth_map(compiled(DATA / "box_room.sdf"), resolution=0.05, height=0.2)
    # walls span 2.0..2.2 m from the centre on every side
    for x, y in ((2.1, 0.0), (-2.1, 1.0), (0.5, 2.1), (-1.5, -2.1)):
        assert occupied_at(grid, x, y), (x, y)
    xs, ys = grid.cell_centers()
    inside = (np.abs(xs) < 1.9) & (np.abs(ys) < 1.9)
    assert (grid.data[inside] == FREE).all()
    wall_band = ((np.abs(xs) > 2.05) & (np.abs(xs) < 2.15) & (np.abs(ys) < 1.9))
    assert (grid.data[wall_band] == OCCUPIED).all()
    assert grid.origin[0] == pytest.approx(-3.2) and grid.resolution == 0.05


def test_height_decides_what_is_cut():
    model = compiled(DATA / "features.sdf")
    bounds = Bounds(-6, -6, 6, 6)
    low = ground_truth_map(model, 0.05, 0.1, bounds)
    high = ground_truth_map(model, 0.05, 0.9, bounds)
    # the ball (radius 0.3 centred at z 0.3) exists at 0.1 m, not at 0.9 m
    assert occupied_at(low, -3.0, 2.0) and not occupied_at(high, -3.0, 2.0)
    # The cylinder (r 0.25, 0..1 m) is a disc at both heights. Cells are occupied when the
    # disc covers their centre or its edge crosses them: between the disc's area and the
    # area of the disc grown by half a cell diagonal, in cells.
    row, col = low.cell_of(-3.0, 0.0)
    disc = int((low.data[row - 8:row + 9, col - 8:col + 9] == OCCUPIED).sum())
    r, c = 0.25, 0.05
    assert np.pi * r**2 / c**2 <= disc <= np.pi * (r + c * np.sqrt(0.5)) ** 2 / c**2


def test_the_cone_mesh_is_cut_as_its_triangles():
    model = compiled(DATA / "features.sdf")
    at_base = ground_truth_map(model, 0.02, 0.015, Bounds(3, -1, 5, 1))  # the 0.4 m square base
    near_top = ground_truth_map(model, 0.02, 0.6, Bounds(3, -1, 5, 1))  # a thin slice of the cone
    assert (at_base.data == OCCUPIED).sum() > 3 * (near_top.data == OCCUPIED).sum() > 0


def test_tool_writes_a_nav2_map_that_reads_back(tmp_path):
    out = tmp_path / "maze_gt"
    result = subprocess.run([PPPBOT, "run", "pppbot_sim", "ground_truth_map", "world:=maze",
                             f"output:={out}", "resolution:=0.1"], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert f"saved {out}.yaml" in result.stdout
    grid, meta = load_map(f"{out}.yaml")
    expected = ground_truth_map(compiled("maze"), 0.1, 0.2)
    assert meta.resolution == 0.1 and np.array_equal(grid.data, expected.data)
    assert grid.origin == pytest.approx(expected.origin)


def test_tool_rejects_bad_arguments():
    result = subprocess.run([PPPBOT, "run", "pppbot_sim", "ground_truth_map", "resolution:=fine"],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 1
    assert "resolution:=fine: must be a number" in result.stderr
