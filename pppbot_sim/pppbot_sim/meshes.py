"""Mesh files (STL, OBJ, COLLADA .dae) as vertex and face arrays in metres, as Gazebo loads them.

Gazebo's loaders (gz-common's ColladaLoader, read for this) give:
- COLLADA: the vertices through the ``<visual_scene>`` node transforms, then scaled by the
  file's ``<asset><unit meter="…">`` (an inch file: 0.0254). ``<up_axis>`` is not applied:
  Gazebo reads every mesh as Z up (gazebo-classic issue 1305), and so does pppbot.
- STL and OBJ: the numbers as they are, in metres.
- A ``<mesh><scale>`` multiplies on top (:func:`load_mesh`).
Materials and textures play no part in physics or the lidar: they are not loaded, and a
missing texture prints nothing.

trimesh is imported on the first mesh read: with it (and the scipy modules it brings) a
simulator takes about 80 MB more, which a world of boxes and cylinders has no use for."""
from __future__ import annotations

import functools
import logging
import math
from pathlib import Path

import numpy as np

from pppbot_common.xml_files import XmlFileError, parse_xml
from pppbot_sim.errors import WorldError


def collada_meter(path: Path) -> float:
    """The metres per unit of a COLLADA file's ``<asset><unit meter>`` (1 without one).

    Raises:
        WorldError: the file is not XML, or ``meter`` is not a positive finite number.
    """
    try:
        root = parse_xml(path)
    except XmlFileError as exc:
        raise WorldError(f"{path}: not a COLLADA file ({exc})") from exc
    asset = next((child for child in root if isinstance(child.tag, str) and _local(child.tag) == "asset"), None)
    unit = next((child for child in asset if isinstance(child.tag, str) and _local(child.tag) == "unit"), None) \
        if asset is not None else None
    if unit is None or unit.get("meter") is None:
        return 1.0
    text = unit.get("meter", "")
    try:
        meter = float(text)
    except ValueError:
        meter = math.nan
    if not (math.isfinite(meter) and meter > 0.0):
        raise WorldError(f"{path}: <unit meter=\"{text}\"> must be a positive number of metres per unit")
    return meter


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


@functools.lru_cache(maxsize=64)
def _load(path: str) -> tuple[np.ndarray, np.ndarray]:
    import trimesh

    # trimesh logs a traceback for each texture it cannot find (at debug level, which a
    # node's logging may show): textures are of no use here.
    logging.getLogger("trimesh").setLevel(logging.ERROR)
    meter = collada_meter(Path(path)) if path.lower().endswith(".dae") else 1.0
    try:
        loaded = trimesh.load(path, force="mesh", process=False, skip_materials=True)
    except Exception as exc:  # trimesh raises many types for bad files
        raise WorldError(f"{path}: cannot read the mesh ({exc})") from exc
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise WorldError(f"{path}: the mesh has no triangles")
    if np.shape(loaded.vertices)[1:] != (3,) or not np.isfinite(loaded.vertices).all():
        raise WorldError(f"{path}: the mesh's vertices are not finite 3D points (x y z)")
    faces = np.asarray(loaded.faces)
    if faces.shape[1:] != (3,) or faces.min() < 0 or faces.max() >= len(loaded.vertices):
        raise WorldError(f"{path}: the mesh's faces name vertices it does not have ({len(loaded.vertices)} vertices)")
    return np.asarray(loaded.vertices, dtype=float) * meter, faces.astype(np.int32)


def load_mesh(path: Path, scale: tuple[float, float, float] = (1.0, 1.0, 1.0)) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices (n, 3) in m, faces (k, 3))`` of a mesh file as Gazebo sizes it (the module's
    docstring), then scaled per axis by ``scale`` (``<mesh><scale>``).

    Raises:
        WorldError: unreadable file, a bad COLLADA unit, or no triangles.
    """
    vertices, faces = _load(str(path))
    return vertices * np.asarray(scale, dtype=float), faces
