"""ROS messages as rerun archetypes: what RViz's displays show, in rerun's terms.

Every visual is logged with the ``rr.CoordinateFrame`` of its message's ``header.frame_id``, and
``/tf`` edges as ``rr.Transform3D`` with parent and child frames, so the viewer places each in
the view's frame (``map``) through the TF tree as RViz does.
"""
from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr

from pppbot_common.se2 import yaw_from_quaternion
from pppbot_description.kinematics import rpy_quaternion
from pppbot_viz.visuals import (
    covariance_ellipse,
    grid_cells,
    grid_image,
    heading_arrows,
    place_points,
    scan_points,
    transform_points,
    view_image,
)

# RViz's default colours, as RGBA bytes
SCAN_COLOR = (255, 0, 0, 255)          # LaserScan: flat red
PLAN_COLOR = (25, 255, 0, 255)         # Nav2's global plan: green
LOCAL_PLAN_COLOR = (0, 12, 255, 255)   # local plan: blue
PARTICLE_COLOR = (0, 180, 0, 255)      # ParticleCloud
POSE_COLOR = (255, 25, 0, 255)         # PoseWithCovariance arrow
COVARIANCE_COLOR = (204, 51, 204, 90)  # covariance ellipse
GOAL_COLOR = (255, 0, 255, 255)        # 2D Goal Pose
TRAIL_COLOR = (255, 200, 0, 255)       # odometry trail
FOOTPRINT_COLOR = (25, 255, 0, 255)    # Polygon (Nav2's footprint display)


def stamp_seconds(stamp: Any) -> float:
    return float(stamp.sec) + 1e-9 * float(stamp.nanosec)


def frame_of(header: Any) -> rr.CoordinateFrame:
    """The TF frame a message's data is in (``map`` when the header names none)."""
    return rr.CoordinateFrame(header.frame_id.lstrip("/") or "map")


def quaternion_xyzw(q: Any) -> list[float]:
    values = [float(q.x), float(q.y), float(q.z), float(q.w)]
    norm = math.sqrt(sum(v * v for v in values))
    return [v / norm for v in values] if norm > 0.0 and math.isfinite(norm) else [0.0, 0.0, 0.0, 1.0]


def quaternion(q: Any) -> rr.Quaternion:
    """A message's orientation, normalized (identity when it is zero or not finite)."""
    return rr.Quaternion(xyzw=quaternion_xyzw(q))


def transform(msg: Any) -> rr.Transform3D:
    """A geometry_msgs/TransformStamped as a TF edge (parent → child)."""
    t = msg.transform
    return rr.Transform3D(translation=[t.translation.x, t.translation.y, t.translation.z],
                          quaternion=quaternion(t.rotation),
                          parent_frame=msg.header.frame_id.lstrip("/"), child_frame=msg.child_frame_id.lstrip("/"))


def scan(msg: Any, radius_m: float = 0.03, pose: tuple[float, float, float] | None = None, frame: str = "",
         height_m: float = 0.0) -> list[Any]:
    """sensor_msgs/LaserScan: the beams that hit, as points in the lidar's frame; or, with ``pose``
    (the lidar's x, y, yaw in ``frame`` at the scan's stamp), in ``frame``, ``height_m`` up."""
    points = scan_points(msg.ranges, msg.angle_min, msg.angle_increment, msg.range_min, msg.range_max)
    if pose is None:
        return [frame_of(msg.header), rr.Points3D(points, radii=radius_m, colors=SCAN_COLOR)]
    return [rr.CoordinateFrame(frame), rr.Points3D(place_points(points, pose, height_m), radii=radius_m,
                                                   colors=SCAN_COLOR)]


def grid(msg: Any, colormap: rr.components.Colormap, opacity: float = 1.0, lift_m: float = 0.0,
         cells: np.ndarray | None = None) -> list[Any]:
    """nav_msgs/OccupancyGrid in RViz's "map" or "costmap" colours, at its origin in its frame,
    ``lift_m`` above it (costmaps just above the map). ``cells``: :func:`grid_cells_of` the
    message, when the caller has them already."""
    info = msg.info
    cells = grid_cells_of(msg) if cells is None else cells
    origin = info.origin
    return [frame_of(msg.header), rr.GridMap(
        data=grid_image(cells).tobytes(), format=rr.components.ImageFormat(width=info.width, height=info.height,
                                                               color_model="L", channel_datatype="U8"),
        cell_size=float(info.resolution),
        translation=[origin.position.x, origin.position.y, origin.position.z + lift_m],
        quaternion=quaternion(origin.orientation), colormap=colormap, opacity=opacity)]


def grid_cells_of(msg: Any) -> np.ndarray:
    return grid_cells(msg.data, msg.info.width, msg.info.height)


def path(msg: Any, color: tuple[int, int, int, int], radius_m: float = 0.02) -> list[Any]:
    """nav_msgs/Path as a line in its frame (no line for an empty path: it clears the last)."""
    points = np.array([[p.pose.position.x, p.pose.position.y, p.pose.position.z] for p in msg.poses],
                      dtype=np.float32).reshape(-1, 3)
    return [frame_of(msg.header), rr.LineStrips3D([points] if len(points) > 1 else [], radii=radius_m,
                                                   colors=color)]


def polygon(msg: Any, color: tuple[int, int, int, int], radius_m: float = 0.01, lift_m: float = 0.03) -> list[Any]:
    """geometry_msgs/PolygonStamped (a costmap's footprint) as a closed line in its frame, ``lift_m``
    up (above the costmaps)."""
    points = np.array([[p.x, p.y, p.z + lift_m] for p in msg.polygon.points], dtype=np.float32).reshape(-1, 3)
    closed = np.vstack([points, points[:1]]) if len(points) > 2 else points
    return [frame_of(msg.header), rr.LineStrips3D([closed] if len(closed) > 1 else [], radii=radius_m, colors=color)]


def particles(msg: Any, arrow_m: float = 0.15) -> list[Any]:
    """nav2_msgs/ParticleCloud as heading arrows."""
    poses = np.array([[p.pose.position.x, p.pose.position.y, yaw_from_quaternion(
        p.pose.orientation.x, p.pose.orientation.y, p.pose.orientation.z, p.pose.orientation.w)]
        for p in msg.particles], dtype=np.float64).reshape(-1, 3)
    origins, vectors = heading_arrows(poses, arrow_m)
    return [frame_of(msg.header), rr.Arrows3D(origins=origins, vectors=vectors, radii=0.005, colors=PARTICLE_COLOR)]


def pose_with_covariance(msg: Any, sigmas: float = 2.0, arrow_m: float = 0.4) -> list[Any]:
    """geometry_msgs/PoseWithCovarianceStamped: an arrow and the position's ``sigmas``-sigma
    ellipse (flat, in the plane of the pose)."""
    pose = msg.pose.pose
    cov = np.asarray(msg.pose.covariance, dtype=np.float64).reshape(6, 6)[:2, :2]
    (major, minor), angle = covariance_ellipse(cov, sigmas)
    center = [pose.position.x, pose.position.y, pose.position.z]
    yaw = yaw_from_quaternion(pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w)
    origins, vectors = heading_arrows(np.array([[pose.position.x, pose.position.y, yaw]]), arrow_m)
    origins[:, 2] = pose.position.z
    return [frame_of(msg.header),
            rr.Ellipsoids3D(centers=[center], half_sizes=[[max(major, 1e-3), max(minor, 1e-3), 1e-3]],
                            rotation_axis_angles=[rr.RotationAxisAngle(axis=[0, 0, 1], radians=angle)],
                            colors=COVARIANCE_COLOR, fill_mode=rr.components.FillMode.Solid),
            rr.Arrows3D(origins=origins, vectors=vectors, radii=0.02, colors=POSE_COLOR)]


def pose(msg: Any, color: tuple[int, int, int, int] = GOAL_COLOR, arrow_m: float = 0.5) -> list[Any]:
    """geometry_msgs/PoseStamped as an arrow (a goal)."""
    p = msg.pose
    yaw = yaw_from_quaternion(p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w)
    origins, vectors = heading_arrows(np.array([[p.position.x, p.position.y, yaw]]), arrow_m)
    return [frame_of(msg.header), rr.Arrows3D(origins=origins, vectors=vectors, radii=0.03, colors=color)]


def trail(points: np.ndarray, frame: str) -> list[Any]:
    return [rr.CoordinateFrame(frame), rr.LineStrips3D([points] if len(points) > 1 else [], radii=0.015,
                                                        colors=TRAIL_COLOR)]


# visualization_msgs/Marker types drawn (the ones slam_toolbox's graph and Nav2 use)
_ARROW, _CUBE, _SPHERE, _LINE_STRIP, _LINE_LIST, _SPHERE_LIST, _POINTS = 0, 1, 2, 4, 5, 7, 8
_DELETE, _DELETEALL = 2, 3


def _rgba(color: Any) -> tuple[int, int, int, int]:
    return tuple(int(round(255 * min(max(float(v), 0.0), 1.0))) for v in (color.r, color.g, color.b, color.a))  # type: ignore[return-value]


def marker_path(marker: Any) -> str:
    return f"{marker.ns or 'markers'}/{marker.id}"


def markers(msg: Any) -> dict[str, list[Any] | None]:
    """visualization_msgs/MarkerArray: {entity path under the topic: archetypes}, ``None`` to
    clear (DELETE); a DELETEALL clears everything first (key ``""``). Types other than points,
    lines, spheres, cubes and arrows are skipped."""
    out: dict[str, list[Any] | None] = {}
    for m in msg.markers:
        if m.action == _DELETEALL:
            out.clear()
            out[""] = None
            continue
        key = marker_path(m)
        if m.action == _DELETE:
            out[key] = None
            continue
        position, orientation = m.pose.position, m.pose.orientation
        translation = [position.x, position.y, position.z]
        rotation = quaternion_xyzw(orientation)
        points = np.array([[p.x, p.y, p.z] for p in m.points], dtype=np.float64).reshape(-1, 3)
        points = transform_points(points, translation, rotation)
        color = _rgba(m.color)
        colors = [_rgba(c) for c in m.colors] if len(m.colors) == len(m.points) and len(m.colors) else color
        if m.type in (_SPHERE_LIST, _POINTS):
            visual: Any = rr.Points3D(points, radii=0.5 * float(m.scale.x), colors=colors)
        elif m.type == _LINE_LIST:
            visual = rr.LineStrips3D(list(points[: len(points) // 2 * 2].reshape(-1, 2, 3)),
                                     radii=0.5 * float(m.scale.x), colors=color)
        elif m.type == _LINE_STRIP:
            visual = rr.LineStrips3D([points], radii=0.5 * float(m.scale.x), colors=color)
        elif m.type == _SPHERE:
            visual = rr.Ellipsoids3D(centers=[translation], half_sizes=[[0.5 * m.scale.x, 0.5 * m.scale.y,
                                                                         0.5 * m.scale.z]],
                                     quaternions=[rotation], colors=color, fill_mode=rr.components.FillMode.Solid)
        elif m.type == _CUBE:
            visual = rr.Boxes3D(centers=[translation], sizes=[[m.scale.x, m.scale.y, m.scale.z]],
                                quaternions=[rotation], colors=color, fill_mode=rr.components.FillMode.Solid)
        elif m.type == _ARROW:
            start = transform_points(np.zeros((1, 3)), translation, rotation)
            tip = transform_points(np.array([[m.scale.x, 0.0, 0.0]]), translation, rotation)
            visual = rr.Arrows3D(origins=start, vectors=tip - start, radii=0.5 * float(m.scale.y), colors=color)
        else:
            continue
        out[key] = [frame_of(m.header), visual]
    return out


#: The slam node's reasons for leaving a loop match out (its ``rejected_<why>`` diagnostics), as said.
REJECTED_WHY = {"disagrees": "disagree with the map", "see_through": "see through walls",
                "inconsistent": "disagree with other matches", "residual": "the solve could not meet"}


def slam_health(msg: Any) -> str | None:
    """The SLAM node's health (its ``…: mapping`` status on /diagnostics, see docs/slam.md) as a
    Markdown text: loop closures accepted, rejected and why, undone, the largest correction;
    None when the message has no such status."""
    status = next((s for s in msg.status if s.name.endswith(": mapping")), None)
    if status is None:
        return None
    values = {v.key: v.value for v in status.values}

    def count(key: str) -> int:
        try:
            return int(values.get(key, "0"))
        except ValueError:
            return 0

    try:
        correction_m, correction_deg = (float(values.get("largest_correction_m", "0")),
                                        math.degrees(float(values.get("largest_correction_rad", "0"))))
    except ValueError:
        correction_m = correction_deg = math.nan
    why = ", ".join(f"{count('rejected_' + key)} {said}" for key, said in REJECTED_WHY.items()
                    if count("rejected_" + key))
    lines = [f"- **{status.message or 'ok'}**: {count('keyframes')} keyframes, {count('loop_closures')} loop "
             f"closures, largest correction {correction_m:.2f} m, {correction_deg:.1f}°",
             f"- rejected {count('rejected_closures')}" + (f": {why}" if why else ""),
             f"- undone {count('undone_closures')}"]
    return "\n".join(lines)


_IMAGE_ENCODINGS = {"rgb8": ("RGB", np.uint8), "rgba8": ("RGBA", np.uint8), "bgr8": ("BGR", np.uint8),
                    "bgra8": ("BGRA", np.uint8), "mono8": ("L", np.uint8), "8UC1": ("L", np.uint8),
                    "mono16": ("L", np.uint16), "16UC1": ("L", np.uint16), "32FC1": ("L", np.float32)}


def image(msg: Any) -> rr.Image:
    """sensor_msgs/Image in one of the common encodings (RGB/BGR(A) 8-bit, mono 8/16-bit, 32FC1),
    as the view sends it (:func:`~pppbot_viz.visuals.view_image`: 8-bit, at most 320 px wide).

    Raises:
        ValueError: another encoding, or data that does not fill ``height * step``.
    """
    if msg.encoding not in _IMAGE_ENCODINGS:
        raise ValueError(f"image encoding '{msg.encoding}' is not shown (one of {sorted(_IMAGE_ENCODINGS)})")
    color_model, dtype = _IMAGE_ENCODINGS[msg.encoding]
    channels = len(color_model)
    raw = np.frombuffer(bytes(msg.data), dtype=np.uint8)
    if msg.step < msg.width * channels * np.dtype(dtype).itemsize or raw.size < msg.height * msg.step:
        raise ValueError(f"a {msg.width}x{msg.height} {msg.encoding} image needs step >= "
                         f"{msg.width * channels * np.dtype(dtype).itemsize} and {msg.height * msg.step} bytes, "
                         f"got step {msg.step} and {raw.size} bytes")
    row_bytes = msg.width * channels * np.dtype(dtype).itemsize
    rows = raw[: msg.height * msg.step].reshape(msg.height, msg.step)[:, :row_bytes]
    pixels = np.ascontiguousarray(rows).view(np.dtype(dtype).newbyteorder(">" if msg.is_bigendian else "<"))
    shown = view_image(pixels.astype(dtype, copy=False).reshape(msg.height, msg.width, channels), color_model)
    # Sizes given, not a shape: rerun would read a one-row image's (1, W, C) as (W, C).
    return rr.Image(bytes=shown.tobytes(), width=shown.shape[1], height=shown.shape[0],
                    color_model="RGB" if shown.ndim == 3 else "L", datatype=np.uint8)


def compressed_image(msg: Any) -> rr.EncodedImage:
    """sensor_msgs/CompressedImage (JPEG or PNG)."""
    media = "image/png" if "png" in msg.format.lower() else "image/jpeg"
    return rr.EncodedImage(contents=bytes(msg.data), media_type=media)


@dataclass(frozen=True)
class LinkVisual:
    """One ``<visual>`` of a link: where it goes and what it is."""

    path: str
    archetypes: list[Any]


def robot_visuals(urdf_text: str, resolve_mesh: Any = None) -> tuple[list[LinkVisual], list[str]]:
    """The robot model of a URDF: every link's visuals in the link's frame, as RViz's RobotModel
    display draws them, and warnings for what could not be drawn (a mesh not found)."""
    from pppbot_description.urdf_model import parse_urdf
    model = parse_urdf(urdf_text)
    visuals: list[LinkVisual] = []
    warnings: list[str] = []
    for link in model.links.values():
        for index, shape in enumerate(link.visuals):
            quaternion = _rpy_quaternion(*shape.origin.rpy)
            center = list(shape.origin.xyz)
            color = tuple(int(round(255 * c)) for c in shape.rgba) if shape.rgba else (180, 180, 180, 255)
            g = shape.geometry
            archetype: Any
            if g.kind == "box":
                archetype = rr.Boxes3D(centers=[center], sizes=[list(g.size)], quaternions=[quaternion],
                                       colors=color, fill_mode=rr.components.FillMode.Solid)
            elif g.kind == "cylinder":
                radius, length = g.size[0], g.size[1]
                archetype = rr.Cylinders3D(centers=[center], radii=[radius], lengths=[length],
                                           quaternions=[quaternion], colors=color,
                                           fill_mode=rr.components.FillMode.Solid)
            elif g.kind == "sphere":
                archetype = rr.Ellipsoids3D(centers=[center], half_sizes=[[g.size[0]] * 3], colors=color,
                                            fill_mode=rr.components.FillMode.Solid)
            elif g.kind == "mesh":
                mesh = _mesh(g.filename, g.scale, center, quaternion, color, resolve_mesh)
                if mesh is None:
                    warnings.append(f"link '{link.name}': mesh '{g.filename}' not found; not drawn")
                    continue
                archetype = mesh
            else:
                continue
            visuals.append(LinkVisual(f"robot/{link.name}/visual_{index}",
                                      [rr.CoordinateFrame(link.name), archetype]))
    return visuals, warnings


def _rpy_quaternion(roll: float, pitch: float, yaw: float) -> list[float]:
    """A URDF origin's rpy as (x, y, z, w), the messages' and rerun's order."""
    w, x, y, z = rpy_quaternion(roll, pitch, yaw)
    return [float(x), float(y), float(z), float(w)]


def _mesh(filename: str, scale: Iterable[float], center: list[float], quaternion: list[float],
          color: tuple[int, ...], resolve_mesh: Any) -> rr.Mesh3D | None:
    import trimesh
    path = resolve_mesh(filename) if resolve_mesh is not None else Path(filename.removeprefix("file://"))
    if path is None or not Path(path).is_file():
        return None
    loaded: Any = trimesh.load(str(path), force="mesh")
    vertices = np.asarray(loaded.vertices, dtype=np.float64) * np.asarray(list(scale), dtype=np.float64)
    vertices = transform_points(vertices, center, quaternion)
    return rr.Mesh3D(vertex_positions=vertices, triangle_indices=np.asarray(loaded.faces, dtype=np.uint32),
                     albedo_factor=color)
