"""What the live view draws, as plain arrays: scans as points, grids as images, covariance as an
ellipse, the odometry trail, poses as arrows. No rerun and no ROS here: ``ros/convert.py``
turns messages into these and these into rerun archetypes.
"""
from __future__ import annotations

import hashlib
import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from PIL import Image
from transforms3d.quaternions import quat2mat

#: a grid cell no one has seen (nav_msgs/OccupancyGrid's -1), as rerun's RViz colormaps expect it
UNKNOWN_CELL = 255


def scan_points(ranges: Sequence[float] | np.ndarray, angle_min: float, angle_increment: float,
                range_min: float, range_max: float) -> np.ndarray:
    """The (N, 3) points in the lidar's frame of the beams that hit something within
    ``[range_min, range_max]``; inf, NaN and out-of-range beams are left out (RViz's LaserScan
    display does the same)."""
    r = np.asarray(ranges, dtype=np.float32)
    angles = angle_min + angle_increment * np.arange(r.size, dtype=np.float64)
    valid = np.isfinite(r) & (r >= range_min) & (r <= range_max)
    points = np.zeros((int(valid.sum()), 3), dtype=np.float32)
    points[:, 0] = r[valid] * np.cos(angles[valid])
    points[:, 1] = r[valid] * np.sin(angles[valid])
    return points


def place_points(points: np.ndarray, pose: Sequence[float], height_m: float = 0.0) -> np.ndarray:
    """Planar points ((N, 3), z ignored) of a sensor at ``pose`` (x, y, yaw) in another frame, in
    that frame, ``height_m`` up."""
    x, y, yaw = (float(v) for v in pose)
    c, s = math.cos(yaw), math.sin(yaw)
    local = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    placed = np.empty((len(local), 3), dtype=np.float32)
    placed[:, 0] = x + c * local[:, 0] - s * local[:, 1]
    placed[:, 1] = y + s * local[:, 0] + c * local[:, 1]
    placed[:, 2] = height_m
    return placed


def grid_cells(data: Sequence[int] | np.ndarray, width: int, height: int) -> np.ndarray:
    """An occupancy grid's cells as a (height, width) uint8 image, row 0 at the grid's origin:
    0-100 as they are, unknown (-1) as :data:`UNKNOWN_CELL`.

    Raises:
        ValueError: ``data`` does not hold ``width * height`` cells.
    """
    cells = np.asarray(data, dtype=np.int8)
    if width <= 0 or height <= 0 or cells.size != width * height:
        raise ValueError(f"an occupancy grid of {width}x{height} cells needs {width * height} values, "
                         f"got {cells.size}")
    return cells.reshape(height, width).view(np.uint8)


def grid_image(cells: np.ndarray) -> np.ndarray:
    """Grid cells (:func:`grid_cells`, row 0 at the grid's origin) as the image rerun's ``GridMap``
    shows: it draws an image as a picture, its first row at the top, and puts the picture's
    lower-left corner at the map's origin. So the image's first row is the grid's last (the
    edge farthest along the grid's +y), and its last row the grid's row 0."""
    return np.ascontiguousarray(cells[::-1])


@dataclass(frozen=True)
class GridKey:
    """What makes two grids the same picture: geometry and cells."""

    width: int
    height: int
    resolution: float
    origin: tuple[float, ...]
    frame: str
    digest: bytes


class ChangeFilter:
    """Passes a grid only when it differs from the last one passed under the same name, so a
    map published again unchanged (a latched republish, slam_toolbox's periodic map) is not
    logged again."""

    def __init__(self) -> None:
        self._last: dict[str, GridKey] = {}

    def changed(self, name: str, cells: np.ndarray, resolution: float, origin: Sequence[float],
                frame: str = "") -> bool:
        """True when ``cells`` (placed by ``resolution``, ``origin`` and ``frame``) differ from
        the last grid passed as ``name``."""
        key = GridKey(cells.shape[1], cells.shape[0], float(resolution), tuple(float(v) for v in origin), frame,
                      hashlib.blake2b(np.ascontiguousarray(cells).data, digest_size=16).digest())
        if self._last.get(name) == key:
            return False
        self._last[name] = key
        return True


def covariance_ellipse(xy_covariance: np.ndarray, sigmas: float = 2.0) -> tuple[tuple[float, float], float]:
    """The ellipse of a 2x2 position covariance: (half axes in m, angle of the first axis in rad).
    ``sigmas`` standard deviations out (2: about 86 % of a planar Gaussian's mass). A covariance
    that is not positive semidefinite (NaN, negative variance) gives zero axes."""
    cov = np.asarray(xy_covariance, dtype=np.float64).reshape(2, 2)
    if not np.all(np.isfinite(cov)):
        return (0.0, 0.0), 0.0
    values, vectors = np.linalg.eigh(0.5 * (cov + cov.T))
    values = np.clip(values, 0.0, None)
    order = np.argsort(values)[::-1]
    values, vectors = values[order], vectors[:, order]
    angle = math.atan2(vectors[1, 0], vectors[0, 0])
    return (sigmas * math.sqrt(values[0]), sigmas * math.sqrt(values[1])), angle


def heading_arrows(xy_yaw: np.ndarray, length: float) -> tuple[np.ndarray, np.ndarray]:
    """Arrows for planar poses ((N, 3) x, y, yaw): (origins, vectors), both (N, 3) with z = 0."""
    poses = np.asarray(xy_yaw, dtype=np.float64).reshape(-1, 3)
    origins = np.zeros((len(poses), 3), dtype=np.float32)
    origins[:, :2] = poses[:, :2]
    vectors = np.zeros_like(origins)
    vectors[:, 0] = length * np.cos(poses[:, 2])
    vectors[:, 1] = length * np.sin(poses[:, 2])
    return origins, vectors


class Trail:
    """The path a robot drove: positions at least ``spacing_m`` apart, the newest ``max_points``
    of them (as RViz's Odometry display keeps its newest arrows).

    The points are held in segments of ``segment_points`` that reuse ``slots`` numbers in
    turn: a new position changes only the newest segment, so a viewer is sent that one
    (a few kilobytes), never the whole drive; and once every slot is used the newest segment
    takes the oldest one's slot, so memory stays bounded however long the run. Each segment
    starts at the previous one's last point: together they draw one line.
    """

    def __init__(self, spacing_m: float = 0.05, max_points: int = 4000, segment_points: int = 200) -> None:
        if spacing_m <= 0.0 or max_points < 2 or segment_points < 2:
            raise ValueError(f"a trail needs spacing_m > 0, max_points >= 2 and segment_points >= 2, got "
                             f"{spacing_m}, {max_points}, {segment_points}")
        self.spacing_m = spacing_m
        self.segment_points = min(segment_points, max_points)
        self.slots = max(1, math.ceil(max_points / self.segment_points))
        self._segments: deque[list[tuple[float, float, float]]] = deque()
        self._newest_slot = -1

    def add(self, x: float, y: float, z: float = 0.0) -> bool:
        """Add a position; true when it was far enough from the last one to be kept."""
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
            return False
        point = (x, y, z)
        if self._segments:
            newest = self._segments[-1]
            if math.dist(newest[-1], point) < self.spacing_m:
                return False
            if len(newest) < self.segment_points:
                newest.append(point)
                return True
        self._segments.append([self._segments[-1][-1], point] if self._segments else [point])
        self._newest_slot = (self._newest_slot + 1) % self.slots
        if len(self._segments) > self.slots:
            self._segments.popleft()
        return True

    def newest(self) -> tuple[int, np.ndarray]:
        """The slot of the segment the last kept position went to, and that segment's points."""
        if not self._segments:
            return 0, np.zeros((0, 3), dtype=np.float32)
        return self._newest_slot, np.asarray(self._segments[-1], dtype=np.float32).reshape(-1, 3)

    def points(self) -> np.ndarray:
        """The whole trail, oldest first (each segment's shared first point once)."""
        if not self._segments:
            return np.zeros((0, 3), dtype=np.float32)
        joined = [*self._segments[0], *(p for segment in list(self._segments)[1:] for p in segment[1:])]
        return np.asarray(joined, dtype=np.float32).reshape(-1, 3)

    def __len__(self) -> int:
        return len(self.points())


class RateLimit:
    """``due(stamp_s)`` is true at most once per ``1 / max_hz`` seconds of message time (0: always).
    A stamp going backwards (a bag played again, a simulator restarted) starts over."""

    def __init__(self, max_hz: float) -> None:
        if not (max_hz >= 0.0 and math.isfinite(max_hz)):
            raise ValueError(f"max_hz must be a finite number >= 0, got {max_hz}")
        self.period_s = 0.0 if max_hz == 0.0 else 1.0 / max_hz
        self._last: float | None = None

    def due(self, stamp_s: float) -> bool:
        if self._last is not None and self._last <= stamp_s < self._last + self.period_s:
            return False
        self._last = stamp_s
        return True


def transform_points(points: np.ndarray, translation: Sequence[float], quaternion_xyzw: Sequence[float]) -> np.ndarray:
    """``points`` (N, 3) moved by a pose (a marker's pose in its frame)."""
    x, y, z, w = (float(v) for v in quaternion_xyzw)
    rotation = quat2mat((w, x, y, z) if any((x, y, z, w)) else (1.0, 0.0, 0.0, 0.0))  # normalizes
    return (np.asarray(points, dtype=np.float64).reshape(-1, 3) @ rotation.T + np.asarray(translation)).astype(
        np.float32)


def pose_from_clicks(first: Sequence[float], second: Sequence[float]) -> tuple[float, float, float]:
    """RViz's "2D Goal Pose" from two clicks: the position of the first, the heading towards the
    second (0 when both are the same point)."""
    dx, dy = float(second[0]) - float(first[0]), float(second[1]) - float(first[1])
    yaw = math.atan2(dy, dx) if (dx, dy) != (0.0, 0.0) else 0.0
    return float(first[0]), float(first[1]), yaw


#: the view sends camera images at most this wide (px; the camera panel is about as wide)
VIEW_IMAGE_WIDTH = 320


def view_image(pixels: np.ndarray, color_model: str, max_width: int = VIEW_IMAGE_WIDTH) -> np.ndarray:
    """A camera image as the view sends it: 8-bit RGB (or grey, for a one-channel image), scaled
    down (an area average) to at most ``max_width`` pixels wide. ``pixels``: height x width
    (x channels) in ``color_model`` ("RGB", "RGBA", "BGR", "BGRA" or "L"). A 16-bit or float
    image (depth) is shown grey, from black at 0 to white at its largest finite value, as
    RViz's Image display scales one; NaN and infinity are black.

    Sent raw, not as a JPEG: a viewer decodes an encoded image in the background and, without a
    GPU, marks every new frame as loading for about as long as it shows it. A 320 x 240 frame
    is a quarter of a 640 x 480 one, and the stream to the viewer is compressed (LZ4) anyway.

    Raises:
        ValueError: an unknown colour model, or pixels of another shape.
    """
    channels = {"RGB": 3, "RGBA": 4, "BGR": 3, "BGRA": 4, "L": 1}.get(color_model)
    if channels is None:
        raise ValueError(f"color model '{color_model}' is not one of RGB, RGBA, BGR, BGRA, L")
    shaped = pixels if pixels.ndim == 3 else pixels[..., np.newaxis]
    if shaped.ndim != 3 or shaped.shape[2] != channels:
        raise ValueError(f"a {color_model} image needs height x width x {channels} pixels, got {pixels.shape}")
    if color_model.startswith("BGR"):
        shaped = shaped[..., 2::-1]
    elif color_model == "RGBA":
        shaped = shaped[..., :3]
    if shaped.dtype != np.uint8:
        values = shaped.astype(np.float64)
        finite = np.isfinite(values)
        top = float(values[finite].max()) if finite.any() else 0.0
        scaled = np.where(finite, values, 0.0) * (255.0 / top if top > 0.0 else 0.0)
        shaped = np.clip(np.round(scaled), 0, 255).astype(np.uint8)
    image = np.ascontiguousarray(shaped if shaped.shape[2] == 3 else shaped[..., 0])
    height, width = image.shape[:2]
    if width > max_width:
        size = (max_width, max(1, round(height * max_width / width)))
        image = np.asarray(Image.fromarray(image).resize(size, Image.Resampling.BOX))
    return image
