"""``pppbot map_saver`` over DDS: a latched map from the test's node in, Nav2 map files out."""
from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
import rclpy

from pppbot_bringup import cli
from pppbot_common.ros.qos import DEFAULT

pytestmark = pytest.mark.ros

NAV2_KEYS = ["image", "mode", "resolution", "origin", "negate", "occupied_thresh", "free_thresh"]


def map_saver(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    """The verb as ./pppbot runs it (pppbot_bringup.cli), in a process of its own."""
    return subprocess.run([sys.executable, "-m", "pppbot_bringup.cli", "map_saver", *args],
                          capture_output=True, text=True, timeout=60, env=env)


def test_saves_the_latched_map_as_trinary_pgm(publish_map, read_saved, tmp_path: Path):
    publish_map()
    result = map_saver("-f", str(tmp_path / "maze"))
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith(f"saved {tmp_path / 'maze.yaml'} and maze.pgm: 7 x 5 cells of 0.1 m")
    saved = read_saved(tmp_path / "maze.yaml")
    assert list(saved.meta) == NAV2_KEYS
    assert saved.meta == {"image": "maze.pgm", "mode": "trinary", "resolution": 0.1, "origin": [-1.5, 2.0, 0.0],
                          "negate": 0, "occupied_thresh": 0.65, "free_thresh": 0.196}
    assert (saved.image_format, saved.image_mode, saved.pixels.shape) == ("PPM", "L", (5, 7))
    assert (saved.pixels[-1, :] == 0).all()  # the occupied bottom row is the image's last row
    # free 254, occupied 0, unknown 205; cells between the thresholds (25 < c < 65) and outside 0-100 unknown
    assert saved.grey(1, 0) == 254 and saved.grey(1, 2) == 254  # 0 and 20 are free
    assert saved.grey(1, 1) == 205 and saved.grey(2, 3) == 205  # 30 and 50 are unknown
    assert saved.grey(3, 3) == 0  # 70 is occupied
    assert saved.grey(3, 4) == 205 and saved.grey(4, 6) == 205  # 101 and -1
    assert saved.pixels[0, 6] == 205  # -1 is the top-right cell


def test_occ_free_and_png(publish_map, read_saved, tmp_path: Path):
    publish_map()
    result = map_saver("-f", str(tmp_path / "m"), "--occ", "0.45", "--free", "0.35", "--fmt", "png")
    assert result.returncode == 0, result.stderr
    assert "trinary png (cells >= 45 occupied, <= 35 free)" in result.stdout
    saved = read_saved(tmp_path / "m.yaml")
    assert (saved.meta["image"], saved.image_format, saved.image_mode) == ("m.png", "PNG", "L")
    assert not (tmp_path / "m.pgm").exists()
    assert [saved.grey(1, 1), saved.grey(1, 2), saved.grey(2, 3), saved.grey(3, 3)] == [254, 254, 0, 0]
    # The thresholds classify before saving; the file records those that read 0/254/205 back (Nav2 #5278).
    assert (saved.meta["occupied_thresh"], saved.meta["free_thresh"]) == (0.65, 0.196)


def test_scale_mode_is_png_with_transparent_unknown_cells(publish_map, read_saved, tmp_path: Path):
    publish_map()
    result = map_saver("-f", str(tmp_path / "s"), "--mode", "scale", "--occ", "0.8", "--free", "0.1")
    assert result.returncode == 0, result.stderr
    saved = read_saved(tmp_path / "s.yaml")
    assert (saved.meta["image"], saved.meta["mode"]) == ("s.png", "scale")
    assert (saved.meta["occupied_thresh"], saved.meta["free_thresh"]) == (0.8, 0.1)  # recorded as given
    assert saved.image_mode == "LA"
    # grey falls linearly with occupancy: 255 free ... 0 occupied; unknown cells are transparent
    greys = {cell: saved.grey(*cell) for cell in [(1, 0), (1, 2), (1, 1), (2, 3), (3, 3), (0, 0)]}
    assert greys == {(1, 0): 255, (1, 2): 204, (1, 1): 178, (2, 3): 127, (3, 3): 76, (0, 0): 0}
    assert [saved.alpha(3, 4), saved.alpha(4, 6), saved.alpha(2, 3)] == [0, 0, 255]


def test_raw_mode_in_bmp_keeps_cell_values(publish_map, read_saved, tmp_path: Path):
    publish_map()
    result = map_saver("-f", str(tmp_path / "r"), "--mode", "raw", "--fmt", "BMP")
    assert result.returncode == 0, result.stderr
    saved = read_saved(tmp_path / "r.yaml")
    assert (saved.meta["image"], saved.meta["mode"], saved.image_format) == ("r.bmp", "raw", "BMP")
    assert [saved.grey(*c) for c in [(1, 1), (2, 3), (3, 3), (0, 4), (3, 4), (4, 6)]] == [30, 50, 70, 100, 255, 255]


def test_default_file_is_map_in_the_checkouts_maps_folder(publish_map, read_saved, tmp_path: Path):
    (tmp_path / "config").mkdir()  # a stand-in checkout, so the test never writes the real maps/
    publish_map(topic="/other_map")
    result = map_saver("-t", "other_map", env={**os.environ, "PPPBOT_ROOT": str(tmp_path)})
    assert result.returncode == 0, result.stderr
    saved = read_saved(tmp_path / "maps" / "map.yaml")
    assert saved.meta["image"] == "map.pgm" and saved.grey(3, 3) == 0


def test_no_map_in_time_exits_1_naming_the_topic(tmp_path: Path):
    start = time.monotonic()
    result = map_saver("-f", str(tmp_path / "out" / "m"), "-t", "/nobody_publishes_this", "--timeout", "1")
    assert result.returncode == 1
    assert time.monotonic() - start < 30
    assert result.stderr.splitlines() == [
        "pppbot map_saver: no map on /nobody_publishes_this within 1 s (it has no publisher); nothing saved"]
    assert result.stdout == "" and not (tmp_path / "out").exists()


def test_a_volatile_publisher_needs_volatile_durability(ros_node, publish_map, spawn, read_saved, tmp_path: Path):
    published = publish_map(topic="/volatile_map", qos=DEFAULT)
    # Long enough for discovery on a busy machine (the verdict needs the publisher's QoS): a
    # busy run once saw "it has no publisher" after 2 s.
    result = map_saver("-f", str(tmp_path / "v"), "-t", "/volatile_map", "--timeout", "10")
    assert result.returncode == 1
    assert "its publishers do not latch: --qos-durability volatile waits for their next map" in result.stderr
    assert not (tmp_path / "v.yaml").exists()
    saver = spawn([sys.executable, "-m", "pppbot_bringup.cli", "map_saver", "-f", str(tmp_path / "v"),
                   "-t", "/volatile_map", "--qos-durability", "volatile", "--timeout", "20"], name="map_saver")
    while saver.running():  # a volatile subscriber hears only what is published after it matched
        published.again()
        rclpy.spin_once(ros_node, timeout_sec=0.2)
    assert saver.wait(5) == 0, saver.output
    assert read_saved(tmp_path / "v.yaml").grey(3, 3) == 0


@pytest.mark.parametrize("args, message", [
    (["--occ", "0.2", "--free", "0.3"], "thresholds need 0 <= free (0.3) < occupied (0.2) <= 1; nothing saved"),
    (["--occ", "0.5", "--free", "0.5"], "thresholds need 0 <= free (0.5) < occupied (0.5) <= 1; nothing saved"),
    (["--occ", "1.5"], "thresholds need 0 <= free (0.25) < occupied (1.5) <= 1; nothing saved"),
    (["--free", "-0.1"], "thresholds need 0 <= free (-0.1) < occupied (0.65) <= 1; nothing saved"),
    (["--fmt", "jpg"], "image format 'jpg' is not supported (pgm, png, bmp); nothing saved"),
    (["--mode", "binary"], "map mode 'binary' is not one of trinary, scale, raw; nothing saved"),
    (["--timeout", "0"], "--timeout must be a positive number of seconds, not 0.0"),
    (["-t", "bad topic"], "-t 'bad topic': Invalid topic name: topic name must not contain characters"),
])
def test_bad_arguments_exit_2_with_one_line_and_write_nothing(capsys, tmp_path: Path, args, message):
    code = cli.main(["map_saver", "-f", str(tmp_path / "out" / "m"), *args])
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    (line,) = err.splitlines()
    assert line.startswith(f"pppbot map_saver: {message}")
    assert not (tmp_path / "out").exists()
