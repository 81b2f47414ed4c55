"""Cameras from Gazebo sensor tags: what each publishes, and the image math (no GL, no ROS).

A ``<sensor type="camera">`` gives a colour image and its camera info; a ``type="depth"``
(Gazebo's ``depth_camera``) a ``32FC1`` depth image in metres along the optical axis, its
camera info and a point cloud. Topics, frames, intrinsics, noise and the point layout
follow Gazebo Fortress (gz-sensors 6) as ros_gz_bridge hands them to ROS:

* topics: the tag's ``<topic>`` (else Gazebo's default, the sensor's scoped name
  ``/world/W/model/M/link/L/sensor/S/image``, ``.../depth_image`` for a depth camera); the
  camera info beside it (``<topic>``'s parent + ``/camera_info``); points on ``<topic>/points``;
* intrinsics of a pinhole with square pixels: fx = fy = width / (2 tan(hfov / 2)),
  cx = width / 2, cy = height / 2 (what Gazebo publishes; the rendered image's optical
  axis passes through pixel (width - 1) / 2, half a pixel off); ``<distortion>`` k1 k2 p1
  p2 k3 as ``plumb_bob`` in the camera info only (Gazebo Fortress does not distort its
  images either);
* image noise as Gazebo's Gaussian noise pass: one sample per pixel from N(mean, stddev)
  (in [0, 1] units of full scale) added to every channel, then clamped;
* depth (REP-118): ``-inf`` nearer than the near clip, ``+inf`` where nothing is hit or the
  point's distance exceeds the far clip (Gazebo's rule: its depth shader compares the range,
  not the depth, with the far clip);
* points: x, y, z float32 and ``rgb`` (the depth as a grey level, as Gazebo's depth camera
  fills it) at offsets 0, 4, 8, 16, 24 bytes a point, organised ``height × width``.
"""
from __future__ import annotations

import enum
import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pppbot_description.urdf_model import Sensor
from pppbot_sim.errors import SpawnError


class CameraKind(enum.Enum):
    """What a camera tag renders."""

    COLOR = "camera"
    DEPTH = "depth"


#: Gazebo's sensor type names (``depth`` in SDF, ``depth_camera`` in gz-sim) → kind.
CAMERA_TYPES = {"camera": CameraKind.COLOR, "depth": CameraKind.DEPTH, "depth_camera": CameraKind.DEPTH}


@dataclass(frozen=True)
class PixelFormat:
    """An ``<image><format>``: its ROS encoding and bytes per pixel."""

    encoding: str
    bytes_per_pixel: int


#: SDF's names (sdformat's and the older Gazebo ones) → what ros_gz_bridge publishes.
PIXEL_FORMATS = {
    **dict.fromkeys(("R8G8B8", "RGB_INT8"), PixelFormat("rgb8", 3)),
    **dict.fromkeys(("B8G8R8", "BGR_INT8"), PixelFormat("bgr8", 3)),
    **dict.fromkeys(("L8", "L_INT8"), PixelFormat("mono8", 1)),
    **dict.fromkeys(("L16", "L_INT16"), PixelFormat("mono16", 2)),
    "RGBA_INT8": PixelFormat("rgba8", 4),
    "BGRA_INT8": PixelFormat("bgra8", 4),
    "RGB_INT16": PixelFormat("rgb16", 6),
    "BGR_INT16": PixelFormat("bgr16", 6),
    **{name: PixelFormat(name.lower(), 1) for name in ("BAYER_RGGB8", "BAYER_BGGR8", "BAYER_GBRG8", "BAYER_GRBG8")},
}
DEPTH_FORMAT = PixelFormat("32FC1", 4)
#: Without an ``<update_rate>`` (or 0: Gazebo's "as fast as it renders") a camera runs at this rate (Hz).
DEFAULT_RATE_HZ = 30.0
#: A depth camera renders from this near plane (m, or its near clip if nearer), so that what lies
#: nearer than the clip still hides what is behind it and reads -inf, as in Gazebo.
DEPTH_RENDER_NEAR_M = 0.01
MAX_IMAGE_SIDE = 8192
#: Point layout (bytes): x, y, z at 0, 4, 8, rgb at 16, 24 a point (Gazebo's word-aligned fields).
POINT_STEP = 24
POINT_FIELDS = (("x", 0), ("y", 4), ("z", 8), ("rgb", 16))


@dataclass(frozen=True)
class CameraSpec:
    """A camera tag as the simulator runs it (lengths in m, angles in rad)."""

    name: str
    link: str
    kind: CameraKind
    frame_id: str
    topic: str  # the image (colour) or depth image
    info_topic: str
    points_topic: str  # depth cameras; "" otherwise
    rate_hz: float
    width: int
    height: int
    hfov_rad: float
    near_m: float
    far_m: float
    pixel_format: PixelFormat
    noise_mean: float = 0.0
    noise_stddev: float = 0.0  # colour: fraction of full scale; depth: metres
    distortion: tuple[float, float, float, float, float] = (0.0,) * 5  # k1 k2 p1 p2 k3
    pose: tuple[float, float, float, float, float, float] = (0.0,) * 6

    # ------------------------------------------------------------ intrinsics
    @property
    def focal_px(self) -> float:
        """fx = fy (pixels)."""
        return self.width / (2.0 * math.tan(self.hfov_rad / 2.0))

    @property
    def fovy_deg(self) -> float:
        """The vertical field of view MuJoCo's camera takes (degrees)."""
        return math.degrees(2.0 * math.atan(math.tan(self.hfov_rad / 2.0) * self.height / self.width))

    def k_matrix(self) -> list[float]:
        """CameraInfo's K, row-major: Gazebo's principal point (width / 2, height / 2)."""
        f = self.focal_px
        return [f, 0.0, self.width / 2.0, 0.0, f, self.height / 2.0, 0.0, 0.0, 1.0]

    def p_matrix(self) -> list[float]:
        k = self.k_matrix()
        return [*k[0:3], 0.0, *k[3:6], 0.0, *k[6:9], 0.0]

    @property
    def render_near_m(self) -> float:
        return min(self.near_m, DEPTH_RENDER_NEAR_M) if self.kind is CameraKind.DEPTH else self.near_m

    # --------------------------------------------------------------- parsing
    @classmethod
    def from_tag(cls, tag: Sensor, *, robot_links: frozenset[str] | set[str], default_topic_prefix: str,
                 pose: tuple[float, float, float, float, float, float]) -> tuple[CameraSpec, list[str]]:
        """The tag's camera and what of it is not simulated (one line each).

        Args:
            tag: a sensor tag whose type is in :data:`CAMERA_TYPES`.
            robot_links: the robot's link names (the optical frame ``<link>_optical`` is used
                when the tag names no frame and the robot has that link).
            default_topic_prefix: Gazebo's scoped name of the sensor
                (``/world/W/model/M/link/L/sensor/S``) for a tag without ``<topic>``.
            pose: the tag's ``<pose>`` in its link's frame.

        Raises:
            SpawnError: values a camera cannot have (named with the tag).
        """
        kind = CAMERA_TYPES[tag.type]
        where = f"{tag.type} '{tag.name}' on link '{tag.link}'"
        f = tag.find_float
        rate = tag.update_rate_hz or DEFAULT_RATE_HZ
        width, height = f("camera/image/width", 320), f("camera/image/height", 240)
        clip = "camera/depth_camera/clip" if kind is CameraKind.DEPTH and tag.element.find(
            "camera/depth_camera/clip") is not None else "camera/clip"
        near, far = f(f"{clip}/near", 0.1), f(f"{clip}/far", 100.0 if kind is CameraKind.COLOR else 10.0)
        hfov = f("camera/horizontal_fov", 1.047)
        format_name = tag.find_text("camera/image/format", "R8G8B8") or "R8G8B8"
        problems = []
        if not (rate > 0 and math.isfinite(rate)):
            problems.append(f"update_rate {rate} must be > 0")
        if not (width == int(width) and height == int(height) and 1 <= width <= MAX_IMAGE_SIDE
                and 1 <= height <= MAX_IMAGE_SIDE):
            problems.append(f"image {width:g} x {height:g} must be whole numbers of pixels in [1, {MAX_IMAGE_SIDE}]")
        if not 0.01 <= hfov < math.pi:
            problems.append(f"horizontal_fov {hfov} must be in [0.01, pi) rad (a pinhole camera)")
        if not 0 < near < far or not math.isfinite(far):
            problems.append(f"clip {near}..{far} must satisfy 0 < near < far")
        pixel_format = DEPTH_FORMAT if kind is CameraKind.DEPTH else PIXEL_FORMATS.get(format_name)
        if pixel_format is None:
            problems.append(f"image format '{format_name}' is not one of {', '.join(PIXEL_FORMATS)}")
        noise_mean, noise_stddev, notes = _noise(tag, where)
        if noise_stddev < 0:
            problems.append(f"noise stddev {noise_stddev} must be >= 0")
        if problems:
            raise SpawnError(f"{where}: {'; '.join(problems)}")
        assert pixel_format is not None
        topic = tag.find_text("topic") or (
            f"{default_topic_prefix}/{'image' if kind is CameraKind.COLOR else 'depth_image'}")
        frame = (tag.find_text("gz_frame_id") or tag.find_text("ignition_frame_id") or tag.find_text("frame_id")
                 or tag.find_text("plugin/frame_name") or tag.find_text("plugin/frameName")
                 or (f"{tag.link}_optical" if f"{tag.link}_optical" in robot_links else tag.link))
        d = "camera/distortion"
        distortion = (f(f"{d}/k1", 0.0), f(f"{d}/k2", 0.0), f(f"{d}/p1", 0.0), f(f"{d}/p2", 0.0), f(f"{d}/k3", 0.0))
        for element in ("lens", "depth_camera/output"):
            if tag.element.find(f"camera/{element}") is not None:
                notes.append(f"{where}: <{element}> is not simulated (a pinhole from <horizontal_fov>)")
        spec = cls(name=tag.name, link=tag.link, kind=kind, frame_id=frame, topic=topic,
                   info_topic=info_topic_of(topic), points_topic=f"{topic}/points" if kind is CameraKind.DEPTH else "",
                   rate_hz=rate, width=int(width), height=int(height), hfov_rad=hfov, near_m=near, far_m=far,
                   pixel_format=pixel_format, noise_mean=noise_mean, noise_stddev=noise_stddev,
                   distortion=distortion, pose=pose)
        return spec, notes


def _noise(tag: Sensor, where: str) -> tuple[float, float, list[str]]:
    """(mean, stddev, notes) of the tag's ``<camera><noise>``; only Gaussian noise is simulated."""
    kind = (tag.find_text("camera/noise/type", "none") or "none").lower()
    if kind == "none":
        return 0.0, 0.0, []
    if kind != "gaussian":
        return 0.0, 0.0, [f"{where}: noise type '{kind}' is not simulated (only gaussian)"]
    return tag.find_float("camera/noise/mean", 0.0), tag.find_float("camera/noise/stddev", 0.0), []


def info_topic_of(topic: str) -> str:
    """Gazebo's camera info topic: the image topic's parent + ``/camera_info`` (``camera/image_raw`` →
    ``camera/camera_info``, ``/camera`` → ``/camera_info``)."""
    parent = topic.rstrip("/").rpartition("/")[0]
    if not parent:
        return "/camera_info" if topic.startswith("/") else "camera_info"
    return f"{parent}/camera_info"


def scoped_sensor_name(world: str, model: str, link: str, sensor: str) -> str:
    """Gazebo's scoped name of a sensor, the prefix of its default topics."""
    return f"/world/{world}/model/{model}/link/{link}/sensor/{sensor}"


# ---------------------------------------------------------------------------- images
def apply_image_noise(rgb: np.ndarray, mean: float, stddev: float, rng: np.random.Generator) -> np.ndarray:
    """Gazebo's Gaussian image noise: one sample per pixel of N(``mean``, ``stddev``) (fractions of
    full scale) added to each channel of ``rgb`` (height x width x 3, uint8), rounded and clamped."""
    if stddev <= 0 and mean == 0:
        return rgb
    height, width = rgb.shape[:2]
    noise = rng.standard_normal((height, width, 1), dtype=np.float32)
    noise *= np.float32(255.0 * stddev)
    noise += np.float32(255.0 * mean)
    out = rgb.astype(np.float32)
    out += noise
    np.rint(out, out=out)
    np.clip(out, 0.0, 255.0, out=out)
    return out.astype(np.uint8)


_BAYER = {"bayer_rggb8": "RGGB", "bayer_bggr8": "BGGR", "bayer_gbrg8": "GBRG", "bayer_grbg8": "GRBG"}
_LUMA = np.array([0.299, 0.587, 0.114], dtype=np.float32)  # ITU-R BT.601


def _with_alpha(rgb: np.ndarray) -> np.ndarray:
    return np.concatenate([rgb, np.full(rgb.shape[:2] + (1,), 255, dtype=np.uint8)], axis=2)


def _bayer(rgb: np.ndarray, pattern: str) -> np.ndarray:
    """One channel a pixel, as a Bayer sensor's 2 x 2 ``pattern`` (such as RGGB) samples them."""
    out = np.empty(rgb.shape[:2], dtype=np.uint8)
    for i, letter in enumerate(pattern):
        row, col = divmod(i, 2)
        out[row::2, col::2] = rgb[row::2, col::2, "RGB".index(letter)]
    return out[:, :, None]


_ENCODERS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "rgb8": lambda rgb: rgb,
    "bgr8": lambda rgb: rgb[:, :, ::-1],
    "rgba8": _with_alpha,
    "bgra8": lambda rgb: _with_alpha(rgb[:, :, ::-1]),
    "mono8": lambda rgb: np.rint(rgb.astype(np.float32) @ _LUMA).astype(np.uint8)[:, :, None],
    "mono16": lambda rgb: np.rint((rgb.astype(np.float32) @ _LUMA) * 257.0).astype(np.uint16)[:, :, None],
    "rgb16": lambda rgb: rgb.astype(np.uint16) * np.uint16(257),
    "bgr16": lambda rgb: rgb[:, :, ::-1].astype(np.uint16) * np.uint16(257),
    **{encoding: functools.partial(_bayer, pattern=pattern) for encoding, pattern in _BAYER.items()},
}


def encode(rgb: np.ndarray, pixel_format: PixelFormat) -> np.ndarray:
    """``rgb`` (height x width x 3, uint8) in ``pixel_format``: height x width x channels of
    uint8 or uint16 (mono from ITU-R BT.601 luma; 16-bit values scaled by 257)."""
    return np.asarray(_ENCODERS[pixel_format.encoding](rgb))


# ----------------------------------------------------------------------------- depth
def depth_from_zbuffer(zbuffer: np.ndarray, near_m: float, far_m: float) -> np.ndarray:
    """Metric depth along the optical axis (float64) from MuJoCo's reversed-Z depth buffer
    (``mjDEPTH_ZEROFAR``: 1 at the near plane, 0 at the far plane and where nothing was drawn),
    inverting OpenGL's perspective projection with the planes in float32 as OpenGL had them;
    ``+inf`` where nothing was drawn."""
    znear, zfar = np.float32(near_m), np.float32(far_m)
    c = np.float32(-0.5) * (-(zfar + znear) / (zfar - znear)) - np.float32(0.5)
    d = np.float32(-0.5) * (-(np.float32(2) * zfar * znear) / (zfar - znear))
    z = zbuffer.astype(np.float64)
    with np.errstate(divide="ignore"):
        depth = np.float64(d) / (z + np.float64(c))
    depth[z <= 0.0] = np.inf
    return depth


def ray_lengths(width: int, height: int, hfov_rad: float) -> np.ndarray:
    """Per pixel (height x width): the distance to a point at depth 1 seen through the pixel's centre."""
    f = width / (2.0 * math.tan(hfov_rad / 2.0))
    u = (np.arange(width) - (width - 1) / 2.0) / f
    v = (np.arange(height) - (height - 1) / 2.0) / f
    return np.sqrt(1.0 + u[None, :] ** 2 + v[:, None] ** 2)


def finalize_depth(depth_m: np.ndarray, rays: np.ndarray, near_m: float, far_m: float, *,
                   noise_mean: float = 0.0, noise_stddev: float = 0.0,
                   rng: np.random.Generator | None = None) -> np.ndarray:
    """A 32FC1 depth image (REP-118) from metric depth (``+inf`` where nothing was hit):
    Gaussian noise (m) on the depths, ``+inf`` where the range (depth x ray length) reaches
    ``far_m``, ``-inf`` where the depth is nearer than ``near_m`` (Gazebo's depth camera rules)."""
    depth = np.asarray(depth_m, dtype=np.float64)
    if (noise_stddev > 0 or noise_mean != 0) and rng is not None:
        depth = depth + (noise_mean + noise_stddev * rng.standard_normal(depth.shape))
    out = depth.astype(np.float32)
    out[depth * rays > far_m - 1e-6] = np.inf
    out[depth < near_m] = -np.inf
    return out


def optical_points(depth: np.ndarray, hfov_rad: float) -> np.ndarray:
    """Points (height x width x 3, float32) in the optical frame (x right, y down, z forward) from a
    depth image; a pixel's ray passes through its centre. Non-finite depths give points whose three
    coordinates are that depth (+inf or -inf), as Gazebo's."""
    height, width = depth.shape
    f = width / (2.0 * math.tan(hfov_rad / 2.0))
    u = ((np.arange(width, dtype=np.float32) - np.float32((width - 1) / 2.0)) / np.float32(f))
    v = ((np.arange(height, dtype=np.float32) - np.float32((height - 1) / 2.0)) / np.float32(f))
    finite = np.isfinite(depth)
    x = np.where(finite, depth * u[None, :], depth)  # inf x 0 would be nan
    y = np.where(finite, depth * v[:, None], depth)
    return np.stack([x, y, depth.astype(np.float32, copy=False)], axis=-1)


def depth_gray(depth: np.ndarray) -> np.ndarray:
    """Gazebo's grey rendering of a depth image (uint8): 255 - 255 x depth / (largest finite depth),
    truncated; 0 where the depth is not finite."""
    finite = np.isfinite(depth)
    largest = float(np.max(depth, where=finite, initial=0.0))
    if largest <= 0:
        return np.zeros(depth.shape, dtype=np.uint8)
    with np.errstate(invalid="ignore"):
        values = np.float32(255.0) - depth * np.float32(255.0 / largest)
        np.trunc(values, out=values)
        np.clip(values, 0.0, 255.0, out=values)
    return np.where(finite, values, 0.0).astype(np.uint8)


def point_cloud_data(points: np.ndarray, gray: np.ndarray) -> tuple[np.ndarray, bool]:
    """PointCloud2 ``data`` in Gazebo's layout (:data:`POINT_FIELDS`, :data:`POINT_STEP` bytes a point,
    rows of the image in order; as uint8) and whether every point is finite (``is_dense``).

    Args:
        points: height x width x 3 float32, in the frame the cloud is published in.
        gray: height x width uint8, the colour of each point (r = g = b).
    """
    height, width = gray.shape
    packed = np.empty((height * width, POINT_STEP // 4), dtype=np.float32)
    packed[:, 0:3] = points.reshape(-1, 3)
    words = packed.view(np.uint32)
    words[:, 3] = 0
    words[:, 5] = 0
    g = gray.reshape(-1).astype(np.uint32)
    words[:, 4] = g * np.uint32(0x010101)
    # a point is finite or all of its coordinates are not (optical_points, points_in_frame)
    return packed.view(np.uint8).reshape(-1), bool(np.isfinite(points[..., 2]).all())
