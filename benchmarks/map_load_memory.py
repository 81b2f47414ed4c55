"""Peak memory of loading a big Nav2 map file (``pppbot_common.maps.load_map``), as a multiple of
the image's size.

Writes a ``--size`` × ``--size`` 8-bit PGM map (free, walls every 100 pixels and an unknown
band: all three cell values) and its YAML into a temporary directory, loads it in a child
Python process, and reads the child's peak RSS (``VmHWM``) after the load and, for the
baseline, after the same imports without the load. The last line is one JSON object:
``image_bytes``, ``baseline_rss_bytes``, ``peak_rss_bytes``, ``load_peak_over_image`` (peak
minus baseline, over the image's bytes; the target is at most 4) and ``load_s``.

    ./pppbot env python benchmarks/map_load_memory.py [--size 13000] [--mode trinary] [--format pgm]
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

#: What the child runs: import what a load imports, optionally load, report its peak RSS. That is
#: VmHWM, the peak of the child's own memory: on Linux ``ru_maxrss`` survives exec, so a child's
#: would include the parent's peak (which writing the map raised) whenever that was higher.
_CHILD = """
import json, re, sys, time
from pathlib import Path
from pppbot_common.maps import load_map
start = time.perf_counter()
if sys.argv[1] == "load":
    grid, _ = load_map(sys.argv[2])
    cells = int(grid.data.size)
else:
    cells = 0
hwm_kib = int(re.search(r"VmHWM:\\s+(\\d+) kB", Path("/proc/self/status").read_text()).group(1))
print(json.dumps({"peak_kib": hwm_kib,
                  "cells": cells, "seconds": time.perf_counter() - start}))
"""

#: Rows written per step, so that writing the map does not take the memory measured.
_WRITE_ROWS = 1024


def write_map(directory: Path, size: int, mode: str, image_format: str) -> Path:
    """A ``size`` × ``size`` map image (``pgm`` or ``png``) and its YAML in ``directory``; the YAML's path."""
    image = directory / "big.pgm"
    with image.open("wb") as out:
        out.write(f"P5\n{size} {size}\n255\n".encode("ascii"))
        cols = np.arange(size)
        for top in range(0, size, _WRITE_ROWS):
            rows = np.arange(top, min(top + _WRITE_ROWS, size))[:, None]
            block = np.full((rows.shape[0], size), 254, dtype=np.uint8)
            block[(rows % 100 == 0) | (cols[None, :] % 100 == 0)] = 0
            block[(rows[:, 0] // 1000) % 7 == 3] = 205
            out.write(block.tobytes())
    if image_format == "png":
        Image.MAX_IMAGE_PIXELS = None  # this script's own image
        with Image.open(image) as pgm:
            pgm.save(directory / "big.png")
        image.unlink()
    yaml_path = directory / "big.yaml"
    yaml_path.write_text(f"image: big.{image_format}\nmode: {mode}\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\n"
                         "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n")
    return yaml_path


def child(*args: str) -> dict[str, float]:
    done = subprocess.run([sys.executable, "-c", _CHILD, *args], capture_output=True, text=True, check=False)
    if done.returncode != 0:
        sys.exit(f"the child failed ({done.returncode}): {done.stderr.strip()}")
    result: dict[str, float] = json.loads(done.stdout.strip().splitlines()[-1])
    return result


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", type=int, default=13000, help="map width and height (pixels)")
    parser.add_argument("--mode", default="trinary", choices=("trinary", "scale", "raw"))
    parser.add_argument("--format", default="pgm", choices=("pgm", "png"),
                        help="pgm: read straight from the file; png: decoded by Pillow")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="map_load_memory_") as tmp:
        yaml_path = write_map(Path(tmp), args.size, args.mode, args.format)
        baseline = child("baseline")
        loaded = child("load", str(yaml_path))
    image_bytes = args.size * args.size
    if loaded["cells"] != image_bytes:
        sys.exit(f"loaded {loaded['cells']} cells, not {image_bytes}")
    baseline_b = int(baseline["peak_kib"]) * 1024
    peak_b = int(loaded["peak_kib"]) * 1024
    print(f"{args.size} × {args.size} {args.mode} {args.format} map: image {image_bytes / 2**20:.0f} MiB, baseline "
          f"{baseline_b / 2**20:.0f} MiB, peak {peak_b / 2**20:.0f} MiB, load {loaded['seconds']:.1f} s")
    print(json.dumps({"size_px": args.size, "mode": args.mode, "format": args.format, "image_bytes": image_bytes,
                      "baseline_rss_bytes": baseline_b, "peak_rss_bytes": peak_b,
                      "load_peak_over_image": round((peak_b - baseline_b) / image_bytes, 2),
                      "load_s": round(loaded["seconds"], 2)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
