"""Mesh files (STL, OBJ, COLLADA .dae) as vertex and face arrays, via trimesh.

trimesh is imported on the first mesh read: with it (and the scipy modules it brings) a
simulator takes about 80 MB more, which a world of boxes and cylinders has no use for."""
from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from pppbot_sim.errors import WorldError


@functools.lru_cache(maxsize=64)
def _load(path: str) -> tuple[np.ndarray, np.ndarray]:
    import trimesh

    try:
        loaded = trimesh.load(path, force="mesh", process=False)
    except Exception as exc:  # trimesh raises many types for bad files
        raise WorldError(f"{path}: cannot read the mesh ({exc})") from exc
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise WorldError(f"{path}: the mesh has no triangles")
    return np.asarray(loaded.vertices, dtype=float), np.asarray(loaded.faces, dtype=np.int32)


def load_mesh(path: Path, scale: tuple[float, float, float] = (1.0, 1.0, 1.0)) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices (n, 3) in m, faces (k, 3))`` of a mesh file, scaled per axis.

    COLLADA units (``<unit meter>``) are applied by the reader.

    Raises:
        WorldError: unreadable file or no triangles.
    """
    vertices, faces = _load(str(path))
    return vertices * np.asarray(scale, dtype=float), faces
