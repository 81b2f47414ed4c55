"""Nav2 map files: written as map_saver writes them, read as map_server reads them."""
from __future__ import annotations

import numpy as np
import pytest
import yaml
from PIL import Image

from pppbot_common.maps import (
    FREE,
    OCCUPIED,
    UNKNOWN,
    MapFileError,
    MapMode,
    OccupancyGrid,
    load_map,
    read_map_metadata,
    save_map,
)


def sample_grid() -> OccupancyGrid:
    data = np.full((4, 6), FREE, dtype=np.int8)
    data[0, :] = OCCUPIED  # bottom row
    data[3, 5] = UNKNOWN  # top-right cell
    return OccupancyGrid(data, 0.05, (-1.0, -2.0, 0.0))


def test_round_trip_trinary(tmp_path):
    grid = sample_grid()
    yaml_path = save_map(grid, tmp_path / "m")
    loaded, meta = load_map(yaml_path)
    assert np.array_equal(loaded.data, grid.data)
    assert (loaded.resolution, loaded.origin) == (0.05, (-1.0, -2.0, 0.0))
    # Nav2's map_saver records fixed trinary thresholds, so 205 (p = 0.196) reads back unknown.
    assert (meta.mode, meta.occupied_thresh, meta.free_thresh, meta.negate) == (MapMode.TRINARY, 0.65, 0.196, False)


def test_given_thresholds_classify_cells_before_saving(tmp_path):
    grid = OccupancyGrid(np.array([[10, 30, 70, -1]], dtype=np.int8), 1.0)
    save_map(grid, tmp_path / "m", occupied_thresh=0.6, free_thresh=0.2)
    loaded, _ = load_map(tmp_path / "m.yaml")
    assert loaded.data.tolist() == [[FREE, UNKNOWN, OCCUPIED, UNKNOWN]]


def test_pixels_follow_map_saver_conventions(tmp_path):
    save_map(sample_grid(), tmp_path / "m")
    pixels = np.asarray(Image.open(tmp_path / "m.pgm"))
    assert pixels.shape == (4, 6)
    assert (pixels[-1, :] == 0).all()  # occupied bottom row is the image's last row
    assert pixels[0, 5] == 205  # unknown, top right
    assert pixels[1, 1] == 254  # free


def test_reads_a_map_made_by_hand_as_nav2_would(tmp_path):
    """A map_saver-style file written without pppbot: PGM with 0/205/254 and its YAML."""
    pixels = np.array([[254, 205, 0], [254, 254, 100], [0, 0, 0]], dtype=np.uint8)
    Image.fromarray(pixels).save(tmp_path / "hand.pgm")
    (tmp_path / "hand.yaml").write_text(
        "image: hand.pgm\nmode: trinary\nresolution: 0.1\norigin: [1.0, 2.0, 0.0]\n"
        "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.25\n")
    grid, _ = load_map(tmp_path / "hand.yaml")
    # p = (255 - v) / 255: 254 → 0.004 free, 205 → 0.196 free (< 0.25: Nav2 reads it so too),
    # 100 → 0.61 unknown, 0 → occupied
    assert grid.data.tolist() == [[OCCUPIED] * 3, [FREE, FREE, UNKNOWN], [FREE, FREE, OCCUPIED]]


#: The keys Nav2 requires besides image, resolution and origin.
NAV2_KEYS = "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.25\n"


def test_scale_and_raw_modes(tmp_path):
    pixels = np.array([[0, 100, 101, 128, 255]], dtype=np.uint8)
    Image.fromarray(pixels).save(tmp_path / "s.png")
    for mode in ("scale", "Raw"):  # Nav2 reads the mode in any case
        (tmp_path / f"{mode}.yaml").write_text(
            f"image: s.png\nmode: {mode}\nresolution: 1.0\norigin: [0, 0, 0]\n" + NAV2_KEYS)
        grid, _ = load_map(tmp_path / f"{mode}.yaml")
        if mode == "scale":
            # p = (255 - v) / 255; p(100) = 0.608: 100 * (0.608 - 0.25) / 0.4 = 89.46 → 89;
            # p(101) = 0.604 → 88; p(128) = 0.498 → 62
            assert grid.data[0].tolist() == [OCCUPIED, 89, 88, 62, FREE]
        else:
            # raw: a value 0-100 is the cell itself, anything above is unknown (Nav2's map_io)
            assert grid.data[0].tolist() == [0, 100, UNKNOWN, UNKNOWN, UNKNOWN]


@pytest.mark.parametrize("suffix, header", [("png", None), ("pgm", b"P5\n4 1\n65535\n")])
def test_16_bit_images_are_scaled_not_clipped(tmp_path, suffix, header):
    """A 16-bit grey level is read on its own scale (GraphicsMagick's, as Nav2 reads it):
    half grey is unknown in trinary mode, not free as 8-bit clipping would make it."""
    levels = np.array([[0, 12850, 32768, 65535]], dtype=np.uint16)  # p = 1.0, 0.8, 0.5, 0.0
    if header is None:
        Image.fromarray(levels).save(tmp_path / f"m.{suffix}")
    else:
        (tmp_path / f"m.{suffix}").write_bytes(header + levels.astype(">u2").tobytes())
    (tmp_path / "m.yaml").write_text(f"image: m.{suffix}\nresolution: 1.0\norigin: [0, 0, 0]\n" + NAV2_KEYS)
    grid, _ = load_map(tmp_path / "m.yaml")
    assert grid.data[0].tolist() == [OCCUPIED, OCCUPIED, UNKNOWN, FREE]


BASE = "image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n"


@pytest.mark.parametrize("text, message", [
    ("image: m.pgm\nresolution: 0.05\n" + NAV2_KEYS, "missing key(s) origin"),
    (BASE, "missing key(s) negate, occupied_thresh, free_thresh"),
    (BASE + "negate: 0\noccupied_thresh: 0.65\n", "missing key(s) free_thresh"),
    ("image: m.pgm\nresolution: -1\norigin: [0, 0, 0]\n" + NAV2_KEYS, "'resolution' must be positive"),
    ("image: m.pgm\nresolution: 0.05\norigin: [0, 0]\n" + NAV2_KEYS, "'origin' must be [x, y, yaw]"),
    (BASE + NAV2_KEYS + "mode: fancy\n", "'mode' is 'fancy'; allowed: trinary, scale, raw"),
    (BASE + "negate: 2\noccupied_thresh: 0.65\nfree_thresh: 0.25\n", "'negate' must be 0 or 1, not 2"),
    (BASE + "negate: 0\noccupied_thresh: high\nfree_thresh: 0.25\n", "'occupied_thresh' must be a finite number"),
    (BASE + "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.9\n", "thresholds need"),
    ("- just\n- a list\n", "a map file is a YAML mapping"),
    ("image: [unclosed\n", "not valid YAML"),
])
def test_bad_map_yaml_is_named(tmp_path, text, message):
    (tmp_path / "m.yaml").write_text(text)
    with pytest.raises(MapFileError) as info:
        read_map_metadata(tmp_path / "m.yaml")
    assert message in str(info.value) and "m.yaml" in str(info.value)


def test_missing_and_unreadable_images(tmp_path):
    (tmp_path / "m.yaml").write_text("image: gone.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n" + NAV2_KEYS)
    with pytest.raises(MapFileError, match="image 'gone.pgm' not found"):
        load_map(tmp_path / "m.yaml")
    (tmp_path / "gone.pgm").write_text("not an image")
    with pytest.raises(MapFileError, match="not a readable image"):
        load_map(tmp_path / "m.yaml")
    with pytest.raises(MapFileError, match="cannot read the file"):
        load_map(tmp_path / "nothing.yaml")


def test_refuses_to_overwrite_when_asked(tmp_path):
    save_map(sample_grid(), tmp_path / "m")
    with pytest.raises(MapFileError, match="exists; refusing to overwrite"):
        save_map(sample_grid(), tmp_path / "m", overwrite=False)


# ---------------------------------------------------------------- saving as Nav2's map_saver
def cells_to_pixels(tmp_path, cells, **kwargs):
    """Save one row of cells; return the image's pixels as an independent reader (PIL) sees them."""
    grid = OccupancyGrid(np.array([cells], dtype=np.int8), 0.1)
    yaml_path = save_map(grid, tmp_path / "m", **kwargs)
    image_name = yaml.safe_load(yaml_path.read_text())["image"]
    with Image.open(tmp_path / image_name) as image:
        return image.mode, np.asarray(image)


def test_trinary_thresholds_are_rounded_to_whole_cells_as_nav2_does(tmp_path):
    # Nav2 compares cells with rint(100·threshold): free 0.256 → cells <= 26, occupied 0.594 → cells >= 59.
    _, pixels = cells_to_pixels(tmp_path, [26, 27, 58, 59], free_thresh=0.256, occupied_thresh=0.594)
    assert pixels[0].tolist() == [254, 205, 205, 0]


def test_cells_outside_0_to_100_are_unknown_in_every_mode(tmp_path):
    assert cells_to_pixels(tmp_path, [101, 127, -1, 100])[1][0].tolist() == [205, 205, 205, 0]
    assert cells_to_pixels(tmp_path, [101, -1, 7], mode=MapMode.RAW)[1][0].tolist() == [255, 255, 7]
    mode, pixels = cells_to_pixels(tmp_path, [101, -1, 0], mode=MapMode.SCALE, image_format="png")
    assert mode == "LA" and pixels[0, :, 1].tolist() == [0, 0, 255]


def test_scale_png_is_grey_by_occupancy_with_unknown_transparent(tmp_path):
    mode, pixels = cells_to_pixels(tmp_path, [0, 30, 50, 70, 100, -1], mode=MapMode.SCALE, image_format="png")
    assert mode == "LA"
    # floor(255·(100 - cell)/100), as Nav2's map_saver writes the grey; unknown: alpha 0
    assert pixels[0, :, 0].tolist() == [255, 178, 127, 76, 0, 127]
    assert pixels[0, :, 1].tolist() == [255, 255, 255, 255, 255, 0]
    loaded, meta = load_map(tmp_path / "m.yaml")
    assert (meta.mode, meta.occupied_thresh, meta.free_thresh) == (MapMode.SCALE, 0.65, 0.25)
    # read back with the scale rule: p = (255 - v)/255 between the thresholds, transparent → unknown
    # (178 → p 0.302 → 13, 127 → p 0.502 → 63)
    assert loaded.data[0].tolist() == [FREE, 13, 63, OCCUPIED, OCCUPIED, UNKNOWN]


def test_scale_without_png_has_no_transparency(tmp_path):
    mode, pixels = cells_to_pixels(tmp_path, [0, -1], mode=MapMode.SCALE, image_format="pgm")
    assert mode == "L" and pixels[0].tolist() == [255, 127]


@pytest.mark.parametrize("image_format", ["png", "bmp", "PGM"])
def test_trinary_in_each_image_format(tmp_path, image_format):
    yaml_path = save_map(sample_grid(), tmp_path / "m", image_format=image_format)
    meta = yaml.safe_load(yaml_path.read_text())
    assert meta["image"] == f"m.{image_format.lower()}"
    with Image.open(tmp_path / meta["image"]) as image:
        assert image.mode == "L"
        pixels = np.asarray(image)
    assert pixels[0, 5] == 205 and pixels[1, 1] == 254 and (pixels[-1, :] == 0).all()


def test_yaml_has_nav2s_keys_in_nav2s_order(tmp_path):
    yaml_path = save_map(OccupancyGrid(np.zeros((2, 3), np.int8), 0.05, (1.5, -2.25, 0.5)), tmp_path / "m",
                         mode=MapMode.RAW, occupied_thresh=0.7, free_thresh=0.2)
    meta = yaml.safe_load(yaml_path.read_text())
    assert list(meta) == ["image", "mode", "resolution", "origin", "negate", "occupied_thresh", "free_thresh"]
    assert meta == {"image": "m.pgm", "mode": "raw", "resolution": 0.05, "origin": [1.5, -2.25, 0.5],
                    "negate": 0, "occupied_thresh": 0.7, "free_thresh": 0.2}


def test_a_dotted_name_gets_the_extensions_appended(tmp_path):
    yaml_path = save_map(sample_grid(), tmp_path / "maze.v2")
    assert yaml_path == tmp_path / "maze.v2.yaml" and (tmp_path / "maze.v2.pgm").is_file()


@pytest.mark.parametrize("occupied, free", [(0.5, 0.5), (0.4, 0.6), (1.2, 0.25), (0.65, -0.1), (float("nan"), 0.2)])
def test_bad_thresholds_write_nothing(tmp_path, occupied, free):
    with pytest.raises(MapFileError, match=r"thresholds need 0 <= free .* < occupied .* <= 1"):
        save_map(sample_grid(), tmp_path / "out" / "m", occupied_thresh=occupied, free_thresh=free)
    assert not (tmp_path / "out").exists()


def test_unknown_image_format_writes_nothing(tmp_path):
    with pytest.raises(MapFileError, match="image format 'jpg' is not supported"):
        save_map(sample_grid(), tmp_path / "out" / "m", image_format="jpg")
    assert not (tmp_path / "out").exists()


def pgm_map(tmp_path, data: bytes):
    (tmp_path / "m.pgm").write_bytes(data)
    (tmp_path / "m.yaml").write_text("image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n" + NAV2_KEYS)
    return tmp_path / "m.yaml"


@pytest.mark.parametrize("data, message", [
    (b"P5\n4x 3\n255\n" + bytes(12), "malformed PGM header: width '4x' is not a whole number"),
    (b"P5\n# a comment\n4 three\n255\n" + bytes(12), "malformed PGM header: height 'three' is not a whole number"),
    (b"P5\n4 3\n", "malformed PGM header: maxval is missing"),
    (b"P5\n4 3\n70000\n" + bytes(24), "maxval 70000 is not allowed (1 to 65535)"),
    (b"P5\n0 3\n255\n", "size 0 × 3; width and height must be at least 1"),
    (b"P5\n4 3\n255\n" + bytes(5),
     "the PGM is cut short: its 4 × 3 pixels need 12 bytes after the header, the file has 5"),
    (b"P2\n2 1\n255\n0 x\n", "not a readable image"),
])
def test_a_malformed_pgm_is_named_with_what_is_wrong(tmp_path, data, message):
    with pytest.raises(MapFileError) as info:
        load_map(pgm_map(tmp_path, data))
    assert str(info.value).startswith(f"{tmp_path / 'm.pgm'}: ")
    assert message in str(info.value)


def test_an_ascii_pgm_reads_as_the_binary_one(tmp_path):
    load_ascii = load_map(pgm_map(tmp_path, b"P2\n3 1\n255\n0 205 254\n"))[0]
    assert load_ascii.data.tolist() == [[OCCUPIED, FREE, FREE]]  # 205 → p 0.196 < 0.25: free


def test_a_big_map_loads_cell_for_cell(tmp_path):
    """6000 × 6000 read in blocks of rows: every block lands flipped in its place."""
    rng = np.random.default_rng(0)
    pixels = rng.choice(np.array([0, 205, 254], dtype=np.uint8), size=(6000, 6000))
    Image.fromarray(pixels).save(tmp_path / "big.pgm")
    (tmp_path / "big.yaml").write_text("image: big.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\n"
                                       "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
    grid, _ = load_map(tmp_path / "big.yaml")
    expected = np.select([pixels == 0, pixels == 254], [OCCUPIED, FREE], UNKNOWN).astype(np.int8)[::-1]
    assert grid.data.shape == (6000, 6000)
    assert np.array_equal(grid.data, expected)


def test_map_images_beyond_pillows_bomb_limit_load_up_to_the_cap(tmp_path, monkeypatch):
    from pppbot_common import map_images
    Image.fromarray(np.full((30, 40), 254, dtype=np.uint8)).save(tmp_path / "m.png")
    (tmp_path / "m.yaml").write_text("image: m.png\nresolution: 1.0\norigin: [0, 0, 0]\n" + NAV2_KEYS)
    monkeypatch.setattr(Image, "MAX_IMAGE_PIXELS", 100)  # Pillow would refuse it
    assert load_map(tmp_path / "m.yaml")[0].data.shape == (30, 40)
    assert Image.MAX_IMAGE_PIXELS == 100  # and its limit is left as it was
    monkeypatch.setattr(map_images, "MAX_MAP_PIXELS", 1000)
    with pytest.raises(MapFileError, match=r"m\.png: the image is 40 × 30 = 1200 pixels; map images may have "
                                           r"at most 1000"):
        load_map(tmp_path / "m.yaml")
    monkeypatch.setattr(map_images, "MAX_MAP_PIXELS", 500)  # twice over: Pillow's own refusal, named
    with pytest.raises(MapFileError, match=r"m\.png: the image has more than 1000 pixels; map images may have "
                                           r"at most 500"):
        load_map(tmp_path / "m.yaml")
    monkeypatch.setattr(map_images, "MAX_MAP_PIXELS", 100)
    pgm = pgm_map(tmp_path, b"P5\n20 10\n255\n" + bytes(200))
    with pytest.raises(MapFileError, match=r"m\.pgm: the image is 20 × 10 = 200 pixels"):
        load_map(pgm)


@pytest.mark.parametrize("mode", ["trinary", "scale", "raw"])
@pytest.mark.parametrize("negate", [0, 1])
def test_the_level_table_is_nav2s_rule_for_every_level(mode, negate):
    from pppbot_common.maps import MapMetadata, pixels_to_occupancy
    meta = MapMetadata("m.png", 1.0, (0.0, 0.0, 0.0), MapMode(mode), bool(negate), 0.65, 0.25)
    levels = np.arange(256, dtype=np.uint8)
    assert np.array_equal(pixels_to_occupancy(levels, meta), pixels_to_occupancy(levels.astype(np.float64), meta))
    wide = np.arange(0, 65536, 7, dtype=np.uint16)
    assert np.array_equal(pixels_to_occupancy(wide, meta), pixels_to_occupancy(wide * (255.0 / 65535.0), meta))
