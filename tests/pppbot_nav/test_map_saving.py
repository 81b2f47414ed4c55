"""A save request made whole: Nav2's defaults for empty fields, and its checks (no ROS)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pppbot_common.maps import MapMode
from pppbot_nav.errors import MapSaverError
from pppbot_nav.map_saving import resolve_save_settings, shortest_float32, unset_if_zero

DEFAULT = Path("/maps/default")


def resolve(map_url="", image_format="", map_mode="", free=None, occupied=None, **kwargs):
    return resolve_save_settings(map_url, image_format, map_mode, free, occupied, DEFAULT, **kwargs)


def test_empty_request_takes_nav2s_defaults():
    s = resolve()
    assert (s.base_path, s.mode, s.image_format, s.occupied_thresh, s.free_thresh) == \
        (DEFAULT, MapMode.TRINARY, "pgm", 0.65, 0.25)
    assert (s.yaml_path, s.image_path) == (Path("/maps/default.yaml"), Path("/maps/default.pgm"))
    assert s.warnings() == []


def test_scale_defaults_to_png_and_other_modes_to_pgm():
    assert resolve(map_mode="scale").image_format == "png"
    assert resolve(map_mode="raw").image_format == "pgm"
    assert resolve(map_mode="Scale", image_format="BMP").image_format == "bmp"  # case-insensitive, as Nav2


def test_scale_without_transparency_is_warned_about():
    (warning,) = resolve(map_mode="scale", image_format="pgm").warnings()
    assert "unknown cells are written mid-grey" in warning and "use png" in warning


def test_the_callers_threshold_defaults_apply_when_not_given():
    s = resolve(free_default=0.1, occupied_default=0.9)
    assert (s.free_thresh, s.occupied_thresh) == (0.1, 0.9)
    s = resolve(free=0.3, occupied=0.5, free_default=0.1, occupied_default=0.9)
    assert (s.free_thresh, s.occupied_thresh) == (0.3, 0.5)


def test_a_given_zero_free_threshold_is_kept():
    assert resolve(free=0.0).free_thresh == 0.0  # only a service request's 0.0 means "default"


def test_service_zero_means_default_and_float32_noise_is_removed():
    assert unset_if_zero(0.0) is None
    assert float(np.float32(0.65)) != 0.65 and unset_if_zero(float(np.float32(0.65))) == 0.65
    assert shortest_float32(float(np.float32(0.196))) == 0.196


@pytest.mark.parametrize("url, expected", [
    ("maps/maze", Path("maps/maze")),
    ("maps/maze.yaml", Path("maps/maze")),
    ("file:///tmp/m", Path("/tmp/m")),
    ("~/m", Path.home() / "m"),
    ("maze.v2", Path("maze.v2")),
])
def test_map_url_names_the_files(url, expected):
    assert resolve(map_url=url).base_path == expected


@pytest.mark.parametrize("kwargs, message", [
    ({"map_mode": "fancy"}, "map mode 'fancy' is not one of trinary, scale, raw"),
    ({"image_format": "jpg"}, "image format 'jpg' is not supported (pgm, png, bmp)"),
    ({"free": 0.5, "occupied": 0.5}, "thresholds need 0 <= free (0.5) < occupied (0.5) <= 1"),
    ({"free": 0.3, "occupied": 0.2}, "thresholds need 0 <= free (0.3) < occupied (0.2) <= 1"),
    ({"occupied": 1.01}, "occupied (1.01)"),
    ({"free": -0.1}, "free (-0.1)"),
    ({"free": 0.7}, "free (0.7) < occupied (0.65)"),
])
def test_bad_requests_are_refused_naming_the_value(kwargs, message):
    with pytest.raises(MapSaverError) as info:
        resolve(**kwargs)
    assert message in str(info.value)


@pytest.mark.parametrize("mode, fmt, text", [
    ("", "", "trinary pgm (cells >= 65 occupied, <= 25 free)"),
    ("scale", "", "scale png (thresholds 0.65 / 0.25)"),
    ("raw", "bmp", "raw bmp (cell values)"),
])
def test_describe(mode, fmt, text):
    assert resolve(map_mode=mode, image_format=fmt).describe() == text
