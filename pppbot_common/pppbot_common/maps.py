"""Occupancy grids and Nav2 map files (YAML + PGM/PNG), read and written as Nav2 does.

Cell values follow nav_msgs/OccupancyGrid: 0 free, 100 occupied, -1 unknown (and
1-99 in ``scale`` mode). Row 0 of ``data`` is the map's bottom row (lowest y),
as in the message; image row 0 is the top, so files are flipped on the way.

Nav2's rules (map_server / map_saver):

* loading: ``p = (255 - v) / 255`` (or ``v / 255`` when ``negate``);
  ``trinary``: p > occupied_thresh → 100, p < free_thresh → 0, else -1;
  ``scale``: the same ends, and between them ``round(100·(p - free)/(occ - free))``;
  ``raw``: the pixel value itself when it is 0-100, else -1 (``negate`` does not apply).
  ``v`` is the pixel's grey level on a 0-255 scale: 16-bit images (a PGM whose maxval
  is above 255, a 16-bit PNG) are scaled down, as Nav2's GraphicsMagick reads them.
  Nav2 requires ``negate``, ``occupied_thresh`` and ``free_thresh``; so does this
  reader (``mode`` may be left out: trinary).
* saving: cells outside 0-100 are unknown. ``trinary`` writes 0 for occupied
  (``cell >= rint(100·occupied_thresh)``), 254 for free (``cell <= rint(100·free_thresh)``,
  checked first) and 205 for the rest, and, as Nav2's map_saver does since it fixed
  this (navigation2 #5278), records the fixed thresholds 0.65 / 0.196 in the YAML
  so that 205 reads back as unknown (the thresholds given only classify the cells
  before saving); ``scale`` writes ``floor(255·(100 - cell)/100)`` and the given
  thresholds, unknown cells transparent (alpha 0) in a PNG — PGM and BMP carry no
  transparency here, so there they are mid-grey (127) and read back as a middling
  occupancy, which is why Nav2 warns against scale without PNG; ``raw`` writes
  the cell value, unknown 255.
"""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from PIL import Image

from pppbot_common.errors import MapFileError
from pppbot_common.map_images import open_map_image
from pppbot_common.param_files import load_yaml_file

FREE, OCCUPIED, UNKNOWN = 0, 100, -1
#: What a trinary map file records: 0 → p 1.0 occupied, 254 → p 0.004 free, 205 → p 0.196 unknown.
TRINARY_FILE_THRESHOLDS = (0.65, 0.196)
#: Image formats map files are written in (Nav2's map_saver: "bmp", "pgm", "png").
IMAGE_FORMATS = ("pgm", "png", "bmp")
#: Formats in which ``scale`` mode marks unknown cells transparent.
ALPHA_FORMATS = ("png",)
#: Grey of unknown cells in ``scale`` mode (under the transparency, or alone without it).
SCALE_UNKNOWN_GREY = 127


class MapMode(enum.Enum):
    TRINARY = "trinary"
    SCALE = "scale"
    RAW = "raw"


@dataclass
class OccupancyGrid:
    """A 2D grid in a frame: ``data[row, col]``, row 0 at ``origin`` y (bottom)."""

    data: np.ndarray  # int8, shape (height, width)
    resolution: float  # m per cell
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)  # x, y, yaw of cell (0, 0)'s corner
    frame_id: str = "map"

    def __post_init__(self) -> None:
        self.data = np.asarray(self.data, dtype=np.int8)
        if self.data.ndim != 2:
            raise ValueError(f"occupancy data must be 2D, not shape {self.data.shape}")
        if not (math.isfinite(self.resolution) and self.resolution > 0):
            raise ValueError(f"resolution must be a positive number, not {self.resolution}")

    @property
    def height(self) -> int:
        return int(self.data.shape[0])

    @property
    def width(self) -> int:
        return int(self.data.shape[1])

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """The map's rectangle in its frame: x0, x1, y0, y1 (origin yaw 0; matplotlib's ``extent``)."""
        x0, y0 = float(self.origin[0]), float(self.origin[1])
        return x0, x0 + self.width * self.resolution, y0, y0 + self.height * self.resolution

    def cell_of(self, x: np.ndarray | float, y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """(row, col) indices of world points (origin yaw must be 0); may be out of range."""
        col = np.floor((np.asarray(x) - self.origin[0]) / self.resolution).astype(int)
        row = np.floor((np.asarray(y) - self.origin[1]) / self.resolution).astype(int)
        return row, col

    def cell_centers(self) -> tuple[np.ndarray, np.ndarray]:
        """x and y of every cell centre, each of shape (height, width)."""
        cols = self.origin[0] + (np.arange(self.width) + 0.5) * self.resolution
        rows = self.origin[1] + (np.arange(self.height) + 0.5) * self.resolution
        return np.meshgrid(cols, rows)


@dataclass
class MapMetadata:
    """The YAML side of a Nav2 map file."""

    image: str
    resolution: float
    origin: tuple[float, float, float]
    mode: MapMode = MapMode.TRINARY
    negate: bool = False
    occupied_thresh: float = 0.65
    free_thresh: float = 0.25
    extra: dict[str, Any] = field(default_factory=dict)


_REQUIRED = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh")


def _number(meta: dict[str, Any], key: str, path: Path) -> float:
    value = meta[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise MapFileError(f"{path}: '{key}' must be a finite number, not {value!r}")
    return float(value)


def read_map_metadata(path: str | Path) -> MapMetadata:
    """Parse a Nav2 map YAML file.

    Raises:
        MapFileError: missing file, bad YAML, a missing or invalid key.
    """
    path = Path(path)
    meta = load_yaml_file(path, MapFileError)
    if not isinstance(meta, dict):
        raise MapFileError(f"{path}: a map file is a YAML mapping with keys {', '.join(_REQUIRED)}")
    missing = [k for k in _REQUIRED if k not in meta]
    if missing:
        raise MapFileError(f"{path}: missing key(s) {', '.join(missing)}")
    if not isinstance(meta["image"], str) or not meta["image"]:
        raise MapFileError(f"{path}: 'image' must be a file name, not {meta['image']!r}")
    resolution = _number(meta, "resolution", path)
    if resolution <= 0:
        raise MapFileError(f"{path}: 'resolution' must be positive, not {resolution}")
    origin = meta["origin"]
    if (not isinstance(origin, (list, tuple)) or len(origin) != 3
            or not all(isinstance(v, (int, float)) and math.isfinite(v) for v in origin)):
        raise MapFileError(f"{path}: 'origin' must be [x, y, yaw], not {origin!r}")
    mode_text = meta.get("mode", "trinary")
    try:
        mode = MapMode(mode_text.lower() if isinstance(mode_text, str) else mode_text)  # Nav2 ignores case
    except ValueError:
        raise MapFileError(f"{path}: 'mode' is {mode_text!r}; allowed: trinary, scale, raw") from None
    negate = meta["negate"]
    if negate not in (0, 1, True, False):
        raise MapFileError(f"{path}: 'negate' must be 0 or 1, not {negate!r}")
    occupied = _number(meta, "occupied_thresh", path)
    free = _number(meta, "free_thresh", path)
    if not 0.0 <= free <= occupied <= 1.0:
        raise MapFileError(f"{path}: thresholds need 0 <= free_thresh ({free}) <= occupied_thresh ({occupied}) <= 1")
    extra = {k: v for k, v in meta.items()
             if k not in {*_REQUIRED, "mode", "negate", "occupied_thresh", "free_thresh"}}
    return MapMetadata(meta["image"], resolution, (float(origin[0]), float(origin[1]), float(origin[2])),
                       mode, bool(negate), occupied, free, extra)


def pixels_to_occupancy(pixels: np.ndarray, meta: MapMetadata, alpha: np.ndarray | None = None) -> np.ndarray:
    """Nav2's loading rule: grey levels (image orientation) → int8 cells (same orientation).

    ``pixels``: 8-bit levels (``uint8``, 0-255) or 16-bit ones (``uint16``, on the 0-65535 scale:
    ``v = level·255/65535``); any other dtype is taken as ``v`` itself. Integer levels go
    through a table of every level (:func:`occupancy_table`): no temporaries beyond the cells.
    ``alpha`` (0-255, same shape), when the image has it: in ``scale`` mode a pixel that is not
    fully opaque is unknown.
    """
    if pixels.dtype in (np.uint8, np.uint16):
        out = occupancy_table(meta, 256 if pixels.dtype == np.uint8 else 65536)[pixels]
    else:
        out = _occupancy_of_grey(np.asarray(pixels, dtype=np.float64), meta)
    if meta.mode is MapMode.SCALE and alpha is not None:
        out[alpha < 255] = UNKNOWN
    return out


def occupancy_table(meta: MapMetadata, levels: int = 256) -> np.ndarray:
    """The cell of every grey level ``0 .. levels - 1`` (int8, ``levels`` long): level ``i`` is
    ``v = i·255/(levels - 1)`` on the 0-255 scale."""
    return _occupancy_of_grey(np.arange(levels, dtype=np.float64) * (255.0 / (levels - 1)), meta)


def _occupancy_of_grey(values: np.ndarray, meta: MapMetadata) -> np.ndarray:
    """Nav2's rule on ``v`` (0-255 scale, float64)."""
    if meta.mode is MapMode.RAW:
        level = np.rint(values)
        return np.where((level >= FREE) & (level <= OCCUPIED), level, UNKNOWN).astype(np.int8)
    p = values / 255.0 if meta.negate else (255.0 - values) / 255.0
    out = np.full(values.shape, UNKNOWN, dtype=np.int8)
    out[p > meta.occupied_thresh] = OCCUPIED
    out[p < meta.free_thresh] = FREE
    if meta.mode is MapMode.SCALE:
        between = (p >= meta.free_thresh) & (p <= meta.occupied_thresh)
        span = max(meta.occupied_thresh - meta.free_thresh, 1e-9)
        out[between] = np.rint(100.0 * (p[between] - meta.free_thresh) / span).astype(np.int8)
    return out


def occupancy_to_pixels(data: np.ndarray, mode: MapMode = MapMode.TRINARY,
                        occupied_thresh: float = 0.65, free_thresh: float = 0.25) -> np.ndarray:
    """Nav2 map_saver's writing rule: int8 cells → uint8 greyscale pixels (see the module doc)."""
    cells = data.astype(np.int16)
    unknown = (cells < 0) | (cells > 100)
    if mode is MapMode.RAW:
        return np.where(unknown, 255, cells).astype(np.uint8)
    if mode is MapMode.SCALE:
        grey = (255 * (100 - cells)) // 100
        return np.where(unknown, SCALE_UNKNOWN_GREY, grey).astype(np.uint8)
    free = ~unknown & (cells <= int(np.rint(free_thresh * 100.0)))
    occupied = ~unknown & ~free & (cells >= int(np.rint(occupied_thresh * 100.0)))
    out = np.full(data.shape, 205, dtype=np.uint8)
    out[occupied] = 0
    out[free] = 254
    return out


def load_map(path: str | Path) -> tuple[OccupancyGrid, MapMetadata]:
    """Load a Nav2 map (YAML and its image).

    Raises:
        MapFileError: any problem with the YAML or the image, naming the file.
    """
    path = Path(path)
    meta = read_map_metadata(path)
    return load_map_image(path, meta), meta


def check_map_file(path: str | Path) -> MapMetadata:
    """Check a Nav2 map without loading its image: the YAML, and the image's header and size.

    Raises:
        MapFileError: as :func:`load_map` would, naming the file.
    """
    path = Path(path)
    meta = read_map_metadata(path)
    image_path = Path(meta.image) if Path(meta.image).is_absolute() else path.parent / meta.image
    if not image_path.is_file():
        raise MapFileError(f"{path}: image '{meta.image}' not found at {image_path}")
    with open_map_image(image_path):
        pass
    return meta


def load_map_image(path: str | Path, meta: MapMetadata) -> OccupancyGrid:
    """The grid of the map file ``path`` whose YAML says ``meta`` (its image, read by Nav2's rule).

    The image is read and converted a block of rows at a time
    (:mod:`pppbot_common.map_images`): the memory a load takes is the grid (a byte a cell) and,
    for images other than 8-bit binary PGM, Pillow's decoded image, plus a few MiB.
    ``benchmarks/map_load_memory.py`` measures it.

    Raises:
        MapFileError: the image is missing, unreadable, malformed (naming what in its header) or
            bigger than :data:`pppbot_common.map_images.MAX_MAP_PIXELS`, naming the file.
    """
    path = Path(path)
    image_path = Path(meta.image) if Path(meta.image).is_absolute() else path.parent / meta.image
    if not image_path.is_file():
        raise MapFileError(f"{path}: image '{meta.image}' not found at {image_path}")
    with open_map_image(image_path) as image:
        cells = np.empty((image.height, image.width), dtype=np.int8)
        for block in image.blocks():
            bottom = image.height - block.top  # image row 0 is the grid's top row
            cells[bottom - len(block.grey):bottom] = pixels_to_occupancy(block.grey, meta, block.alpha)[::-1]
    return OccupancyGrid(cells, meta.resolution, meta.origin)


def save_map(grid: OccupancyGrid, path: str | Path, mode: MapMode = MapMode.TRINARY,
             occupied_thresh: float = 0.65, free_thresh: float = 0.25, image_format: str = "pgm",
             overwrite: bool = True) -> Path:
    """Write ``<path>.yaml`` and ``<path>.<image_format>`` as Nav2's map_saver does.

    ``path`` may end in ``.yaml``; returns the YAML path. Nothing is written when an
    argument is bad.

    Raises:
        MapFileError: a bad format or thresholds (Nav2's rule: 0 <= free < occupied <= 1),
            or an existing file when not ``overwrite``.
    """
    path = Path(path)
    base = path.with_suffix("") if path.suffix == ".yaml" else path
    image_format = image_format.lower()
    if image_format not in IMAGE_FORMATS:
        raise MapFileError(f"image format '{image_format}' is not supported ({', '.join(IMAGE_FORMATS)})")
    check_save_thresholds(occupied_thresh, free_thresh)
    yaml_path = base.parent / f"{base.name}.yaml"
    image_path = base.parent / f"{base.name}.{image_format}"
    if not overwrite:
        for existing in (yaml_path, image_path):
            if existing.exists():
                raise MapFileError(f"{existing} exists; refusing to overwrite it")
    pixels = np.ascontiguousarray(occupancy_to_pixels(grid.data, mode, occupied_thresh, free_thresh)[::-1])
    if mode is MapMode.SCALE and image_format in ALPHA_FORMATS:
        cells = grid.data[::-1]
        alpha = np.where((cells < 0) | (cells > 100), 0, 255).astype(np.uint8)
        image = Image.fromarray(np.dstack([pixels, alpha]))  # mode LA: grey and alpha
    else:
        image = Image.fromarray(pixels)
    base.parent.mkdir(parents=True, exist_ok=True)
    image.save(image_path)
    if mode is MapMode.TRINARY:
        occupied_thresh, free_thresh = TRINARY_FILE_THRESHOLDS
    meta = {
        "image": image_path.name,
        "mode": mode.value,
        "resolution": float(grid.resolution),
        "origin": [float(v) for v in grid.origin],
        "negate": 0,
        "occupied_thresh": float(occupied_thresh),
        "free_thresh": float(free_thresh),
    }
    yaml_path.write_text(yaml.safe_dump(meta, sort_keys=False, default_flow_style=None))
    return yaml_path


def check_save_thresholds(occupied_thresh: float, free_thresh: float) -> None:
    """Nav2 map_saver's rule for thresholds: finite, ``0 <= free < occupied <= 1``.

    Raises:
        MapFileError: naming both values.
    """
    if not (math.isfinite(free_thresh) and math.isfinite(occupied_thresh)
            and 0.0 <= free_thresh < occupied_thresh <= 1.0):
        raise MapFileError(f"thresholds need 0 <= free ({free_thresh}) < occupied ({occupied_thresh}) <= 1")
