"""A map file's image, read in blocks of rows so that loading takes memory proportional to the image.

The image's grey levels come out a block of rows at a time (top row first, as stored): 8-bit
(``uint8``) or 16-bit (``uint16``) levels, and the alpha channel when the image has one. An
8-bit binary PGM (``P5``, maxval 255: what map_saver writes) is read straight from the file;
every other image (PNG, BMP, other PGMs) is decoded once by Pillow and cut into blocks. A
netpbm header (PGM, PPM, PBM) is checked first, so a malformed one is named with what is wrong.

Images of up to :data:`MAX_MAP_PIXELS` pixels are read: above Pillow's decompression-bomb
limit (about 179 million pixels), which guards against images from the web, not against maps
(a 20000 × 20000 map is a 1 km square at 5 cm).
"""
from __future__ import annotations

import threading
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

import numpy as np
from PIL import Image, UnidentifiedImageError

from pppbot_common.errors import MapFileError

#: The most pixels a map image may have: 2^30 (32768 × 32768), 1 GiB of cells.
MAX_MAP_PIXELS = 2**30
#: Bytes of grey levels per block of rows (the size of a block's temporaries).
BLOCK_BYTES = 8 * 2**20
#: How far into a netpbm file its header may reach (comments included).
MAX_HEADER_BYTES = 64 * 1024
_NETPBM_KINDS = {b"P1": "PBM", b"P2": "PGM", b"P3": "PPM", b"P4": "PBM", b"P5": "PGM", b"P6": "PPM"}
_WHITESPACE = b" \t\n\r\v\f"
#: Pillow's decompression-bomb limit is a module global; it is raised only while a map image opens.
_PIL_LIMIT = threading.Lock()


@dataclass(frozen=True)
class NetpbmHeader:
    """A netpbm header: ``kind`` (``P5`` …), the size in pixels, ``maxval`` (1 for a bitmap) and
    ``raster_offset``, where the pixels start (bytes into the file)."""

    kind: bytes
    width: int
    height: int
    maxval: int
    raster_offset: int


def read_netpbm_header(path: Path, head: bytes) -> NetpbmHeader:
    """The header at the start (``head``) of the netpbm file ``path``.

    Raises:
        MapFileError: naming the file, the header field and what is allowed.
    """
    kind = head[:2]
    name = _NETPBM_KINDS[kind]
    fields = ("width", "height") if kind in (b"P1", b"P4") else ("width", "height", "maxval")
    layout = f"'{kind.decode()} <width> <height>{'' if len(fields) == 2 else ' <maxval>'}'"
    values: list[int] = []
    pos = 2
    for field in fields:
        while pos < len(head) and (head[pos] in _WHITESPACE or head[pos] == ord("#")):
            if head[pos] == ord("#"):
                end = head.find(b"\n", pos)
                pos = len(head) if end < 0 else end
            pos += 1
        start = pos
        while pos < len(head) and head[pos] not in _WHITESPACE and head[pos] != ord("#"):
            pos += 1
        token = head[start:pos]
        if not token:
            raise MapFileError(f"{path}: malformed {name} header: {field} is missing (the header is {layout})")
        if not token.isdigit():
            shown = token[:20].decode("ascii", "replace")
            raise MapFileError(f"{path}: malformed {name} header: {field} {shown!r} is not a whole number "
                               f"(the header is {layout})")
        values.append(int(token))
    if pos >= len(head) or head[pos] not in _WHITESPACE:
        raise MapFileError(f"{path}: malformed {name} header: no white space after the {fields[-1]} "
                           f"(the header is {layout} and one white space before the pixels)")
    width, height = values[0], values[1]
    maxval = values[2] if len(values) == 3 else 1
    if width < 1 or height < 1:
        raise MapFileError(f"{path}: malformed {name} header: size {width} × {height}; width and height "
                           "must be at least 1")
    if not 1 <= maxval <= 65535:
        raise MapFileError(f"{path}: malformed {name} header: maxval {maxval} is not allowed (1 to 65535)")
    return NetpbmHeader(kind, width, height, maxval, pos + 1)


def check_size(path: Path, width: int, height: int) -> None:
    """Raises: MapFileError when ``width`` × ``height`` is above :data:`MAX_MAP_PIXELS`."""
    if width * height > MAX_MAP_PIXELS:
        raise MapFileError(f"{path}: the image is {width} × {height} = {width * height} pixels; map images "
                           f"may have at most {MAX_MAP_PIXELS} (2^30, e.g. 32768 × 32768)")


@dataclass(frozen=True)
class Block:
    """Rows ``top`` to ``top + len(grey)`` of an image (row 0 at the top): ``grey`` levels
    (``rows x width``, uint8 or uint16) and ``alpha`` (0-255, the same shape) when the image has it."""

    top: int
    grey: np.ndarray
    alpha: np.ndarray | None = None


class MapImage:
    """An open map image: its size and its rows, block by block (:meth:`blocks`)."""

    def __init__(self, path: Path, width: int, height: int) -> None:
        self.path, self.width, self.height = path, width, height

    def rows_per_block(self, bytes_per_pixel: int = 1) -> int:
        return max(1, BLOCK_BYTES // (self.width * bytes_per_pixel))

    def blocks(self) -> Iterator[Block]:
        raise NotImplementedError


class _RawPgm(MapImage):
    """An 8-bit binary PGM, read from the file a block at a time."""

    def __init__(self, path: Path, file: BinaryIO, header: NetpbmHeader) -> None:
        super().__init__(path, header.width, header.height)
        self.file, self.offset = file, header.raster_offset
        size = path.stat().st_size
        need = header.width * header.height
        if size - self.offset < need:
            raise MapFileError(f"{path}: the PGM is cut short: its {header.width} × {header.height} pixels "
                               f"need {need} bytes after the header, the file has {size - self.offset}")

    def blocks(self) -> Iterator[Block]:
        self.file.seek(self.offset)
        rows = self.rows_per_block()
        for top in range(0, self.height, rows):
            count = min(rows, self.height - top)
            data = self.file.read(count * self.width)
            grey = np.frombuffer(data, dtype=np.uint8).reshape(count, self.width)
            yield Block(top, grey)


class _PillowImage(MapImage):
    """Any image Pillow reads, decoded once, its grey levels taken a block at a time."""

    def __init__(self, path: Path, image: Image.Image) -> None:
        super().__init__(path, image.width, image.height)
        self.image = image
        self.sixteen_bit = image.mode == "I" or image.mode.startswith("I;16")
        # a palette with a transparent entry: its alpha, as an RGBA conversion gives it
        self.palette_alpha = image.mode == "P" and "transparency" in image.info

    def blocks(self) -> Iterator[Block]:
        self.image.load()
        rows = self.rows_per_block(4)
        for top in range(0, self.height, rows):
            part = self.image.crop((0, top, self.width, min(top + rows, self.height)))
            if self.palette_alpha:
                part = part.convert("RGBA")
            alpha = np.asarray(part.getchannel("A")) if "A" in part.getbands() else None
            if self.sixteen_bit:  # 16-bit grey on its own scale (as GraphicsMagick reads it)
                grey = np.clip(np.asarray(part), 0, 65535).astype(np.uint16)
            else:
                grey = np.asarray(part.convert("L"))  # colour as luma (GraphicsMagick's intensity)
            yield Block(top, grey, alpha)


@contextmanager
def open_map_image(path: Path) -> Iterator[MapImage]:
    """The image file ``path``, open for reading in blocks.

    Raises:
        MapFileError: the file is missing, unreadable, not an image, malformed, or has more than
            :data:`MAX_MAP_PIXELS` pixels; the message names the file and what is wrong.
    """
    try:
        with path.open("rb") as file:
            head = file.read(MAX_HEADER_BYTES)
            if head[:2] in _NETPBM_KINDS:
                header = read_netpbm_header(path, head)
                check_size(path, header.width, header.height)
                if header.kind == b"P5" and header.maxval == 255:
                    yield _RawPgm(path, file, header)
                    return
            file.seek(0)
            with _open_with_pillow(path, file) as image:
                check_size(path, image.width, image.height)
                yield _PillowImage(path, image)
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError) as exc:
        if isinstance(exc, MapFileError):
            raise
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else exc
        raise MapFileError(f"{path}: not a readable image ({reason})") from exc


@contextmanager
def _open_with_pillow(path: Path, file: BinaryIO) -> Iterator[Image.Image]:
    """Pillow's ``Image.open`` with the decompression-bomb limit at :data:`MAX_MAP_PIXELS`."""
    with _PIL_LIMIT, warnings.catch_warnings():
        warnings.simplefilter("ignore", Image.DecompressionBombWarning)  # above the cap is refused below
        saved = Image.MAX_IMAGE_PIXELS
        Image.MAX_IMAGE_PIXELS = MAX_MAP_PIXELS
        try:
            image = Image.open(file)
        except Image.DecompressionBombError:
            raise MapFileError(f"{path}: the image has more than {2 * MAX_MAP_PIXELS} pixels; map images may "
                               f"have at most {MAX_MAP_PIXELS} (2^30, e.g. 32768 × 32768)") from None
        finally:
            Image.MAX_IMAGE_PIXELS = saved
    with image:
        yield image
