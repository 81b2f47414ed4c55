"""The pose graph with its scans, in a file (``.posegraph``), to continue mapping later.

slam_toolbox's ``serialize_map`` / ``deserialize_map`` in a format of pppbot's own:
a NumPy ``.npz`` archive (a zip of ``.npy`` arrays, read with ``allow_pickle=False``,
so a file cannot run code) holding

* ``format`` ("pppbot-posegraph") and ``version`` (1);
* per keyframe: ``stamps`` (K,), ``odom_poses`` (K, 3), ``poses`` (K, 3) in the map,
  ``sessions`` (K,) — which odometry session it came from; ``drawn`` (K,) — in the map
  (false for one placed while the mapper was lost; a file without it has every keyframe drawn);
* the scans, in the sensor frame: ``ray_counts`` (K,), ``directions`` (ΣN, 2),
  ``ranges`` (ΣN,), ``range_limits`` (K, 2) — beam counts may differ;
* ``sensor_offset`` (3,), the lidar in the base frame;
* the edges: ``edge_nodes`` (E, 2), ``edge_relative`` (E, 3), ``edge_covariance``
  (E, 3, 3), ``edge_loop`` (E,); and ``loop_closures`` (L, 3): older node, newer node,
  response.

No ROS here.
"""
from __future__ import annotations

import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from pppbot_slam.errors import PoseGraphFileError
from pppbot_slam.mapper import Keyframe, LoopClosure, Mapper, MapperSettings
from pppbot_slam.occupancy import OccupancyError, ScanRays
from pppbot_slam.pose_graph import PoseGraph, PoseGraphError

FORMAT = "pppbot-posegraph"
VERSION = 1
SUFFIX = ".posegraph"


def posegraph_path(name: str | Path) -> Path:
    """``name`` with the ``.posegraph`` suffix (added when missing)."""
    path = Path(name).expanduser()
    return path if path.suffix == SUFFIX else path.with_name(path.name + SUFFIX)


def save_posegraph(mapper: Mapper, name: str | Path) -> Path:
    """Write the mapper's keyframes, scans and graph; returns the file written.

    The file is written next to its final name and renamed into place, so an
    existing file is never left half-written.

    Raises:
        PoseGraphFileError: nothing to save, or the file cannot be written.
    """
    path = posegraph_path(name)
    if not mapper.keyframes:
        raise PoseGraphFileError(f"{path}: nothing to save, the pose graph is empty")
    keyframes, graph = mapper.keyframes, mapper.graph
    edges = graph.edges
    arrays: dict[str, Any] = dict(
        format=np.array(FORMAT), version=np.array(VERSION),
        stamps=np.array([k.stamp_s for k in keyframes]),
        odom_poses=np.array([k.odom_pose for k in keyframes]).reshape(-1, 3),
        poses=np.array(graph.poses).reshape(-1, 3),
        sessions=np.array([k.session for k in keyframes], dtype=np.int64),
        drawn=np.array([k.drawn for k in keyframes], dtype=bool),
        ray_counts=np.array([len(k.rays.ranges_m) for k in keyframes], dtype=np.int64),
        directions=np.vstack([k.rays.directions for k in keyframes]).reshape(-1, 2),
        ranges=np.concatenate([k.rays.ranges_m for k in keyframes]),
        range_limits=np.array([(k.rays.range_min_m, k.rays.range_max_m) for k in keyframes]),
        sensor_offset=np.asarray(mapper.sensor_offset, dtype=float),
        edge_nodes=np.array([(e.source, e.target) for e in edges], dtype=np.int64).reshape(-1, 2),
        edge_relative=np.array([e.relative for e in edges]).reshape(-1, 3),
        edge_covariance=np.array([e.covariance for e in edges]).reshape(-1, 3, 3),
        edge_loop=np.array([e.loop for e in edges], dtype=bool),
        loop_closures=np.array([(c.source, c.target, c.response) for c in mapper.loop_closures]).reshape(-1, 3),
    )
    partial = path.with_name(path.name + ".partial")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(partial, "wb") as stream:
            np.savez_compressed(stream, **arrays)
        partial.replace(path)
    except OSError as exc:
        partial.unlink(missing_ok=True)
        raise PoseGraphFileError(f"{path}: cannot write the pose graph ({exc.strerror or exc})") from exc
    return path


def load_posegraph(name: str | Path, settings: MapperSettings = MapperSettings()) -> Mapper:
    """A mapper holding the file's keyframes and graph, mapping on with ``settings``.

    Call :meth:`Mapper.start_session` before feeding it scans of a new run.

    Raises:
        PoseGraphFileError: missing or unreadable file, a missing or malformed field
            (named), or inconsistent sizes.
    """
    path = posegraph_path(name)
    if not path.is_file():
        raise PoseGraphFileError(f"{path}: no such pose-graph file")
    try:
        with np.load(path, allow_pickle=False) as archive:
            data = {key: archive[key] for key in archive.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise PoseGraphFileError(f"{path}: not a pose-graph file ({exc})") from exc
    return _mapper_from(path, data, settings)


def _field(path: Path, data: dict[str, np.ndarray], key: str, shape: tuple[int | None, ...],
           dtype: str = "f") -> np.ndarray:
    if key not in data:
        raise PoseGraphFileError(f"{path}: field '{key}' is missing")
    value = data[key]
    if value.ndim != len(shape) or any(s is not None and s != d for s, d in zip(shape, value.shape, strict=True)):
        wanted = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ")"
        raise PoseGraphFileError(f"{path}: field '{key}' has shape {value.shape}, expected {wanted}")
    if value.dtype.kind not in ("iu" if dtype == "i" else "b" if dtype == "b" else "fiu"):
        raise PoseGraphFileError(f"{path}: field '{key}' has type {value.dtype}, expected "
                                 f"{ {'i': 'integers', 'b': 'booleans', 'f': 'numbers'}[dtype]}")
    return value


def _mapper_from(path: Path, data: dict[str, np.ndarray], settings: MapperSettings) -> Mapper:
    if "format" not in data or str(data["format"]) != FORMAT:
        raise PoseGraphFileError(f"{path}: not a pppbot pose graph (field 'format' should be '{FORMAT}')")
    version = int(_field(path, data, "version", (), "i"))
    if version != VERSION:
        raise PoseGraphFileError(f"{path}: pose-graph version {version} is not supported (this pppbot reads "
                                 f"version {VERSION})")
    stamps = _field(path, data, "stamps", (None,))
    count = len(stamps)
    odom = _field(path, data, "odom_poses", (count, 3))
    poses = _field(path, data, "poses", (count, 3))
    sessions = _field(path, data, "sessions", (count,), "i")
    drawn = _field(path, data, "drawn", (count,), "b") if "drawn" in data else np.ones(count, dtype=bool)
    ray_counts = _field(path, data, "ray_counts", (count,), "i")
    directions = _field(path, data, "directions", (None, 2))
    ranges = _field(path, data, "ranges", (len(directions),))
    limits = _field(path, data, "range_limits", (count, 2))
    offset = _field(path, data, "sensor_offset", (3,))
    edge_nodes = _field(path, data, "edge_nodes", (None, 2), "i")
    edge_relative = _field(path, data, "edge_relative", (len(edge_nodes), 3))
    edge_covariance = _field(path, data, "edge_covariance", (len(edge_nodes), 3, 3))
    edge_loop = _field(path, data, "edge_loop", (len(edge_nodes),), "b")
    closures = _field(path, data, "loop_closures", (None, 3))
    if count == 0:
        raise PoseGraphFileError(f"{path}: the pose graph has no keyframes")
    if (ray_counts < 0).any() or int(ray_counts.sum()) != len(ranges):
        raise PoseGraphFileError(f"{path}: field 'ray_counts' sums to {int(ray_counts.sum())}, but there are "
                                 f"{len(ranges)} ranges")
    if not (np.isfinite(odom).all() and np.isfinite(poses).all() and np.isfinite(stamps).all()
            and np.isfinite(offset).all()):
        raise PoseGraphFileError(f"{path}: stamps, poses and the sensor offset must be finite numbers")
    mapper = Mapper(settings, sensor_offset=offset.astype(float))
    graph = PoseGraph()
    try:
        for pose in poses:
            graph.add_node(pose)
        for (source, target), relative, covariance, loop in zip(edge_nodes, edge_relative, edge_covariance,
                                                                 edge_loop, strict=True):
            graph.add_edge(int(source), int(target), relative, covariance, loop=bool(loop))
    except PoseGraphError as exc:
        raise PoseGraphFileError(f"{path}: {exc}") from exc
    mapper.graph = graph
    ends = np.cumsum(ray_counts)
    for index in range(count):
        begin, end = int(ends[index] - ray_counts[index]), int(ends[index])
        try:
            rays = ScanRays(directions[begin:end], ranges[begin:end], float(limits[index, 0]), float(limits[index, 1]))
        except OccupancyError as exc:
            raise PoseGraphFileError(f"{path}: the scan of keyframe {index} is malformed: {exc}") from exc
        points, normals = mapper.hit_points(rays)
        mapper.keyframes.append(Keyframe(index, float(stamps[index]), odom[index].astype(float), rays, points,
                                         normals, int(sessions[index]), bool(drawn[index])))
    for source, target, response in closures:
        if not (0 <= source < count and 0 <= target < count):
            raise PoseGraphFileError(f"{path}: loop closure ({source:g}, {target:g}) names a node the graph lacks")
        mapper.loop_closures.append(LoopClosure(int(source), int(target), float(response)))
    mapper.session = int(sessions.max())
    return mapper
