"""``pppbot eval map``: a saved Nav2 map scored against the world's ground truth, through the CLI."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from pppbot_bringup.cli import main
from pppbot_common.maps import FREE, OCCUPIED, OccupancyGrid, load_map, save_map
from pppbot_sim.ground_truth import ground_truth_map
from pppbot_sim.simulation import load_world
from pppbot_sim.worlds import model_paths

BOX_ROOM = Path(__file__).resolve().parents[1] / "pppbot_sim" / "data" / "box_room.sdf"


def truth_grid() -> OccupancyGrid:
    spec, _ = load_world(BOX_ROOM, model_paths(BOX_ROOM))
    return ground_truth_map(spec.compile(), 0.05, 0.2)


def score(capsys: pytest.CaptureFixture[str], map_yaml: Path, out: Path, *extra: str) -> tuple[int, dict]:
    code = main(["eval", "map", "--world", str(BOX_ROOM), "--map", str(map_yaml), "--out", str(out), "--json",
                 *extra])
    lines = capsys.readouterr().out.strip().splitlines()
    return code, json.loads(lines[-1]) if lines else {}


def test_the_ground_truth_itself_scores_perfectly(capsys, tmp_path: Path):
    yaml_path = save_map(truth_grid(), tmp_path / "truth")
    code, report = score(capsys, yaml_path, tmp_path / "out")
    assert code == 0 and report["ok"] is True and report["scenario"] == "map"
    assert report["map_precision"] == report["map_recall"] == report["map_f1"] == 1.0
    assert report["map_free_coverage"] == 1.0 and report["map_mean_wall_distance_m"] == 0.0
    assert report == json.loads((tmp_path / "out" / "report.json").read_text())


def test_a_map_saved_in_the_spawn_frame_with_a_ghost_and_a_missing_wall(capsys, tmp_path: Path):
    truth = truth_grid()
    # Mapping started at the spawn pose (1, 0.5, 0): the map frame is there.
    grid = OccupancyGrid(truth.data.copy(), truth.resolution, (truth.origin[0] - 1.0, truth.origin[1] - 0.5, 0.0))
    rows, cols = grid.cell_of(np.array([0.0]), np.array([0.0]))  # the map frame's origin, in free space
    grid.data[rows[0] - 2:rows[0] + 3, cols[0] + 10] = OCCUPIED  # a 5-cell ghost wall 0.5 m ahead
    west_wall = truth.data[:, :int((-1.95 - truth.origin[0]) / truth.resolution)] == OCCUPIED
    grid.data[:, :west_wall.shape[1]][west_wall] = FREE  # the west wall was never seen
    yaml_path = save_map(grid, tmp_path / "slam_map")
    code, report = score(capsys, yaml_path, tmp_path / "out", "--map-pose", "1.0", "0.5", "0.0")
    assert code == 0
    loaded, _ = load_map(yaml_path)
    mapped = int((loaded.data == OCCUPIED).sum())
    assert report["map_occupied_cells"] == mapped
    assert report["map_precision"] == pytest.approx((mapped - 5) / mapped)
    assert 0.6 < report["map_recall"] < 0.9  # three of the four inner faces
    assert report["map_f1"] < 1.0
    with Image.open(tmp_path / "out" / "map.png") as png:
        assert png.width > 400
    # The same map placed at the wrong pose scores much worse.
    code, shifted = score(capsys, yaml_path, tmp_path / "out2")
    assert shifted["map_f1"] < 0.5 * report["map_f1"]


def test_bad_map_arguments_give_one_message(capsys, tmp_path: Path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the default report folder goes here
    assert main(["eval", "map", "--world", str(BOX_ROOM), "--map", str(tmp_path / "none.yaml")]) == 2
    assert "none.yaml" in capsys.readouterr().err
    assert not list(tmp_path.glob("eval_map_*"))  # no empty report folder left behind
    assert main(["eval", "drive", "--world", str(BOX_ROOM), "--map", "x.yaml"]) == 2
    assert "only the map, localization and navigation scenarios take it, not drive" in capsys.readouterr().err
    yaml_path = save_map(truth_grid(), tmp_path / "truth")
    assert main(["eval", "map", "--world", str(BOX_ROOM), "--map", str(yaml_path), "--map-pose", "2.1", "0", "0",
                 "--out", str(tmp_path / "o")]) == 2
    assert "reachable_from" in capsys.readouterr().err
