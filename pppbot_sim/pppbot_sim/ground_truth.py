"""Ground-truth occupancy of a world: what a planar lidar at a given height can hit.

Every world geom (not the robot's) is cut by the horizontal plane at ``height``;
the cross-sections are rasterized into cells of ``resolution``: a cell is occupied
when the section covers its centre or its boundary passes through it, free
otherwise. The grid is in the world frame. Meshes are cut as their triangles are
(not as MuJoCo's convex collision hulls), which is what a lidar sees.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np
import trimesh
from PIL import Image, ImageDraw
from shapely.geometry import Polygon

from pppbot_common.maps import FREE, OCCUPIED, OccupancyGrid
from pppbot_sim.mj_build import ROBOT_GROUP


@dataclass(frozen=True)
class Bounds:
    x_min: float
    y_min: float
    x_max: float
    y_max: float


def _geom_mesh(model: mujoco.MjModel, data: mujoco.MjData, gid: int) -> trimesh.Trimesh | None:
    kind = model.geom_type[gid]
    size = model.geom_size[gid]
    G = mujoco.mjtGeom
    if kind == G.mjGEOM_BOX:
        mesh = trimesh.creation.box(extents=2 * size)
    elif kind == G.mjGEOM_SPHERE:
        mesh = trimesh.creation.icosphere(subdivisions=3, radius=size[0])
    elif kind == G.mjGEOM_ELLIPSOID:
        mesh = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
        mesh.apply_scale(size)
    elif kind == G.mjGEOM_CYLINDER:
        mesh = trimesh.creation.cylinder(radius=size[0], height=2 * size[1], sections=64)
    elif kind == G.mjGEOM_CAPSULE:
        mesh = trimesh.creation.capsule(height=2 * size[1], radius=size[0], count=[32, 32])
    elif kind == G.mjGEOM_MESH:
        mid = model.geom_dataid[gid]
        v0, nv = model.mesh_vertadr[mid], model.mesh_vertnum[mid]
        f0, nf = model.mesh_faceadr[mid], model.mesh_facenum[mid]
        mesh = trimesh.Trimesh(model.mesh_vert[v0:v0 + nv].copy(), model.mesh_face[f0:f0 + nf].copy(), process=False)
    else:  # planes, height fields: no cross-section at lidar height
        return None
    transform = np.eye(4)
    transform[:3, :3] = data.geom_xmat[gid].reshape(3, 3)
    transform[:3, 3] = data.geom_xpos[gid]
    mesh.apply_transform(transform)
    return mesh


def cross_sections(model: mujoco.MjModel, data: mujoco.MjData, height: float) -> list[Polygon]:
    """Polygons (world x, y) where non-robot geoms meet the plane z = ``height``."""
    polygons: list[Polygon] = []
    for gid in range(model.ngeom):
        if model.geom_group[gid] == ROBOT_GROUP:
            continue
        mesh = _geom_mesh(model, data, gid)
        if mesh is None or not (mesh.bounds[0][2] <= height <= mesh.bounds[1][2]):
            continue
        section = mesh.section(plane_origin=[0.0, 0.0, height], plane_normal=[0.0, 0.0, 1.0])
        if section is None:
            continue
        planar, _ = section.to_2D(to_2D=np.eye(4), check=False)
        polygons.extend(planar.polygons_full)
    return polygons


def ground_truth_map(model: mujoco.MjModel, resolution: float = 0.05, height: float = 0.2,
                     bounds: Bounds | None = None, margin: float = 1.0) -> OccupancyGrid:
    """Occupancy of the world at ``height`` (m) in cells of ``resolution`` (m).

    ``bounds`` default to the sections' extent plus ``margin``.

    Raises:
        ValueError: non-positive resolution, or nothing to map and no bounds.
    """
    if not (math.isfinite(resolution) and resolution > 0):
        raise ValueError(f"resolution must be a positive number of metres, not {resolution}")
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    polygons = cross_sections(model, data, height)
    if bounds is None:
        if not polygons:
            raise ValueError(f"nothing in the world crosses height {height} m; give bounds to map empty space")
        xs = [v for p in polygons for v in (p.bounds[0], p.bounds[2])]
        ys = [v for p in polygons for v in (p.bounds[1], p.bounds[3])]
        bounds = Bounds(min(xs) - margin, min(ys) - margin, max(xs) + margin, max(ys) + margin)
    x0 = math.floor(bounds.x_min / resolution) * resolution
    y0 = math.floor(bounds.y_min / resolution) * resolution
    width = int(math.ceil((bounds.x_max - x0) / resolution))
    height_cells = int(math.ceil((bounds.y_max - y0) / resolution))
    image = Image.new("L", (width, height_cells), 0)
    draw = ImageDraw.Draw(image)

    def to_cells(coords: np.ndarray) -> list[tuple[float, float]]:
        # Pixel (i, j) covers [i, i+1) × [j, j+1); PIL fills by pixel centres.
        return [((x - x0) / resolution - 0.5, (y - y0) / resolution - 0.5) for x, y in coords]

    for polygon in polygons:
        draw.polygon(to_cells(np.asarray(polygon.exterior.coords)), fill=1, outline=1)
        for hole in polygon.interiors:
            draw.polygon(to_cells(np.asarray(hole.coords)), fill=0, outline=1)
    occupied = np.asarray(image, dtype=bool)  # row j = y index (row 0 at y0): no flip
    data_cells = np.where(occupied, OCCUPIED, FREE).astype(np.int8)
    return OccupancyGrid(data_cells, resolution, (x0, y0, 0.0), frame_id="world")
