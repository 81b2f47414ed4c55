"""A map save request made whole, as Nav2's map_saver does before it writes (no ROS).

A request — the ``nav2_msgs/srv/SaveMap`` fields or ``pppbot map_saver``'s options —
names a file, an image format, a mode and two thresholds. Empty and zero mean
"the default", as in Nav2:

* file: the caller's default (``maps/map`` for the command line);
* mode: ``trinary``; image format: ``png`` in ``scale`` mode (it needs transparency
  for unknown cells), else ``pgm``; formats are case-insensitive;
* thresholds: the defaults 0.65 occupied, 0.25 free (or the node's
  ``*_thresh_default`` parameters); in a service request, where a float cannot be
  absent, 0.0 stands for "the default" (:func:`unset_if_zero`).

Then Nav2's checks: ``0 <= free < occupied <= 1``. Unlike Nav2, an unknown mode or
format is refused instead of replaced by a default, so a request never silently
saves something other than what it asked for. Writing is
:func:`pppbot_common.maps.save_map`.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pppbot_common.maps import ALPHA_FORMATS, IMAGE_FORMATS, MapFileError, MapMode, check_save_thresholds
from pppbot_nav.errors import MapSaverError

DEFAULT_OCCUPIED_THRESH = 0.65
DEFAULT_FREE_THRESH = 0.25
MAP_MODES = tuple(m.value for m in MapMode)


@dataclass(frozen=True)
class SaveSettings:
    """Everything a save needs, checked: files ``<base_path>.yaml`` and ``<base_path>.<image_format>``."""

    base_path: Path
    mode: MapMode
    image_format: str
    occupied_thresh: float
    free_thresh: float

    @property
    def yaml_path(self) -> Path:
        return self.base_path.parent / f"{self.base_path.name}.yaml"

    @property
    def image_path(self) -> Path:
        return self.base_path.parent / f"{self.base_path.name}.{self.image_format}"

    def warnings(self) -> list[str]:
        """What the user should know before relying on the files (Nav2 warns the same)."""
        if self.mode is MapMode.SCALE and self.image_format not in ALPHA_FORMATS:
            return [f"scale mode marks unknown cells by transparency, which {self.image_format} does not "
                    f"carry here: unknown cells are written mid-grey; use png to keep them unknown"]
        return []

    def describe(self) -> str:
        """E.g. ``trinary pgm (cells >= 65 occupied, <= 25 free)``."""
        if self.mode is MapMode.TRINARY:
            how = f"cells >= {round(100 * self.occupied_thresh)} occupied, <= {round(100 * self.free_thresh)} free"
        elif self.mode is MapMode.SCALE:
            how = f"thresholds {self.occupied_thresh:g} / {self.free_thresh:g}"
        else:
            how = "cell values"
        return f"{self.mode.value} {self.image_format} ({how})"


def shortest_float32(value: float) -> float:
    """The shortest decimal that is ``value`` as a float32 (0.6499999761581421 → 0.65).

    Service fields are float32; this keeps their rounding noise out of the YAML.
    """
    return float(str(np.float32(value)))


def unset_if_zero(value: float) -> float | None:
    """A service request's threshold: 0.0 means "not given" (Nav2's convention); float32
    noise removed."""
    return None if value == 0.0 else shortest_float32(value)


def resolve_save_settings(map_url: str, image_format: str, map_mode: str,
                          free_thresh: float | None, occupied_thresh: float | None, default_path: Path,
                          free_default: float = DEFAULT_FREE_THRESH,
                          occupied_default: float = DEFAULT_OCCUPIED_THRESH) -> SaveSettings:
    """Fill in Nav2's defaults and check a request.

    ``map_url`` is a file path (``~`` and a leading ``file://`` are understood; a
    trailing ``.yaml`` is dropped), ``default_path`` when empty; an empty mode or
    format and a threshold of ``None`` take the defaults.

    Raises:
        MapSaverError: an unknown mode or format, or thresholds outside ``0 <= free < occupied <= 1``.
    """
    mode_text = map_mode.strip().lower() or MapMode.TRINARY.value
    try:
        mode = MapMode(mode_text)
    except ValueError:
        raise MapSaverError(f"map mode '{map_mode}' is not one of {', '.join(MAP_MODES)}") from None
    fmt = image_format.strip().lower() or ("png" if mode is MapMode.SCALE else "pgm")
    if fmt not in IMAGE_FORMATS:
        raise MapSaverError(f"image format '{image_format}' is not supported ({', '.join(IMAGE_FORMATS)})")
    occupied = occupied_default if occupied_thresh is None else float(occupied_thresh)
    free = free_default if free_thresh is None else float(free_thresh)
    try:
        check_save_thresholds(occupied, free)
    except MapFileError as exc:
        raise MapSaverError(str(exc)) from exc
    return SaveSettings(file_base(map_url, default_path), mode, fmt, occupied, free)


def file_base(map_url: str, default_path: Path) -> Path:
    """The path the files are named from (no extension)."""
    text = map_url.strip()
    if text.startswith("file://"):
        text = text[len("file://"):]
    path = Path(os.path.expanduser(text)) if text else Path(default_path)
    return path.with_suffix("") if path.suffix == ".yaml" else path
