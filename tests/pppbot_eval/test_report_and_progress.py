"""Report files (JSON, the map overlay's colours, PNGs) and the progress display."""
from __future__ import annotations

import io
import json
import math
from pathlib import Path

import numpy as np
from PIL import Image

from pppbot_common.maps import FREE, OCCUPIED, OccupancyGrid
from pppbot_eval.map_quality import compare_maps
from pppbot_eval.progress import Progress
from pppbot_eval.report import (
    FALSE_WALL,
    MAPPED_WALL,
    TRUE_WALL,
    json_safe,
    map_overlay_image,
    plot_map_overlay,
    write_json,
)


def box_room(size: int = 40) -> OccupancyGrid:
    data = np.full((size, size), FREE, dtype=np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = OCCUPIED
    return OccupancyGrid(data, 0.1, (0.0, 0.0, 0.0), "world")


def test_json_is_strict_and_the_last_line_matches_the_file(tmp_path: Path):
    report = {"ok": True, "ate_rms_m": np.float64(0.25), "rpe": math.nan, "n": np.int64(3), "xs": [math.inf, 1.0]}
    line = write_json(tmp_path / "report.json", report)
    assert "\n" not in line
    parsed = json.loads(line, parse_constant=lambda c: (_ for _ in ()).throw(ValueError(c)))
    assert parsed == {"ok": True, "ate_rms_m": 0.25, "rpe": None, "n": 3, "xs": [None, 1.0]}
    assert json.loads((tmp_path / "report.json").read_text()) == parsed
    assert json_safe({"a": (1, np.float32(2.5))}) == {"a": [1, 2.5]}


def test_map_overlay_shows_true_mapped_and_false_walls_in_their_colours(tmp_path: Path):
    truth = box_room()
    estimate = OccupancyGrid(truth.data.copy(), 0.1, (0.0, 0.0, 0.0))
    estimate.data[:, -1] = FREE  # the east wall was not mapped
    estimate.data[20, 20] = OCCUPIED  # a ghost wall in the middle of the room
    quality = compare_maps(estimate, truth, reachable_from=(2.0, 2.0))
    image = map_overlay_image(truth, quality.true_walls, quality.matched_walls, quality.false_walls)
    assert tuple(image[20, 20]) == FALSE_WALL
    assert tuple(image[20, 0]) == MAPPED_WALL  # west wall: mapped
    assert tuple(image[20, -1]) == TRUE_WALL  # east wall: true, not mapped
    assert tuple(image[10, 10]) == (1.0, 1.0, 1.0)
    plot_map_overlay(tmp_path / "map.png", truth, quality.true_walls, quality.matched_walls, quality.false_walls,
                     "test")
    with Image.open(tmp_path / "map.png") as png:
        pixels = np.asarray(png.convert("RGB")).reshape(-1, 3)
    colours = {tuple(p) for p in pixels.tolist()}
    for colour in (TRUE_WALL, MAPPED_WALL, FALSE_WALL):
        assert tuple(int(round(c * 255)) for c in colour) in colours


def test_progress_without_a_terminal_prints_a_line_every_ten_percent():
    stream = io.StringIO()
    progress = Progress(stream, "drive maze/coverage", terminal=False)
    for k in range(101):
        progress.update(k / 100, f"at {k}")
    lines = stream.getvalue().splitlines()
    assert lines[0] == "drive maze/coverage: 0% at 0" and lines[-1] == "drive maze/coverage: 100% at 100"
    assert len(lines) == 11 and "\r" not in stream.getvalue()


def test_progress_on_a_terminal_redraws_one_line_and_throttles():
    stream = io.StringIO()
    now = [0.0]
    progress = Progress(stream, "run", terminal=True, clock=lambda: now[0])
    progress.update(0.0)
    progress.update(0.5)  # within 0.2 s: not drawn
    now[0] = 1.0
    progress.update(0.5, "half")
    progress.update(1.0)  # the end is always drawn
    progress.finish()
    text = stream.getvalue()
    assert text.count("\r") == 3 and text.endswith("\n")
    assert "[" + "#" * 15 + "." * 15 + "]  50.0% half" in text


def test_other_output_ends_the_bar_line_first():
    stream = io.StringIO()
    progress = Progress(stream, "run", terminal=True, clock=lambda: 0.0)
    progress.update(0.3)
    progress.lines().write("[WARN] [simulator-1]: something\n")
    progress.update(1.0)
    lines = stream.getvalue().split("\n")
    assert lines[0].startswith("\rrun [") and lines[1] == "[WARN] [simulator-1]: something"
