"""Camera frames rendered in a thread of their own, so rendering never holds up physics (no ROS).

The simulation takes a :class:`~pppbot_sim.render.RenderState` (a copy of its positions) when a
camera is due and hands it to :meth:`CameraWorker.submit`; the worker renders it with its own
OpenGL context and its own copy of the model, turns it into what the camera publishes
(:func:`produce`) and gives the :class:`CameraFrame` to ``deliver``. The physics loop never
waits for it. A camera whose previous frame is still waiting when the next is due keeps only
the newer one (the older is skipped); skips are reported per camera, at most once a minute. In
lockstep (``every_frame``) nothing is skipped: the physics loop waits for the renderer instead,
so every frame the camera's rate asks for in sim time is rendered, however busy the machine.

What is reproducible: a frame is rendered from the state at its stamp and its noise comes from a
generator seeded by (seed, camera, frame number), so a frame stamped t is the same in every
run with the same seed (on the same OpenGL implementation), however busy the machine; which
frames are skipped is not (none are with ``every_frame``). The thread runs at a lower CPU
priority (``nice``) than the physics loop, and so do the renderer's own threads (Mesa's
llvmpipe starts them from this one).

The OpenGL context is made when the first frame is asked for (it takes about 130 MB and 0.2 s
with Mesa's software renderer); if it cannot be made, ``failed`` says why and the worker stops.
"""
from __future__ import annotations

import os
import statistics
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from pppbot_sim.cameras import (
    CameraKind,
    CameraSpec,
    apply_image_noise,
    depth_from_zbuffer,
    depth_gray,
    encode,
    finalize_depth,
    optical_points,
    point_cloud_data,
    ray_lengths,
)
from pppbot_sim.render import CameraView, RenderState, RenderUnavailable, SceneRenderer

#: frames skipped are said at most this often (seconds), with the count since the last time
WARN_PERIOD_S = 60.0
#: The worker's niceness above the physics loop's (Linux; elsewhere the same priority).
RENDER_NICE = 10
#: The optical frame (x right, y down, z forward) in a sensor's frame (x forward, y left, z up).
OPTICAL_IN_SENSOR = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


@dataclass(frozen=True)
class CameraBinding:
    """A camera and where it lives in the compiled model."""

    spec: CameraSpec
    view: CameraView
    sensor_site: int  # the sensor's pose (x forward, z up)
    frame_site: int  # the header frame's link, -1 when the frame is not one of the robot's links


@dataclass(frozen=True)
class FrameRequest:
    index: int  # the camera's
    state: RenderState
    points: bool = True  # a depth camera's point cloud is wanted


@dataclass(frozen=True)
class CameraFrame:
    """What a camera publishes for one instant."""

    index: int
    stamp_s: float
    image: np.ndarray | None = None  # colour: height x width x channels in the spec's encoding
    depth: np.ndarray | None = None  # depth: height x width float32, metres (REP-118)
    points: np.ndarray | None = None  # depth: PointCloud2 data, uint8 (cameras.POINT_FIELDS)
    dense: bool = True
    elapsed_ms: float = 0.0


def frame_rng(seed: int, index: int, stamp_s: float, rate_hz: float) -> np.random.Generator:
    """The noise generator of camera ``index``'s frame at ``stamp_s``: its own for every frame."""
    return np.random.default_rng((seed, 4, index, int(round(stamp_s * rate_hz))))


def points_in_frame(points: np.ndarray, rotation: np.ndarray, translation: np.ndarray) -> np.ndarray:
    """Optical-frame points (h x w x 3) in a frame where the optical frame has ``rotation`` and
    ``translation``; non-finite points stay as they are."""
    if np.allclose(rotation, np.eye(3), atol=1e-9) and np.allclose(translation, 0.0, atol=1e-9):
        return points
    flat = points.reshape(-1, 3)
    finite = np.isfinite(flat).all(axis=1)
    out = flat.copy()
    out[finite] = flat[finite] @ rotation.T.astype(np.float32) + translation.astype(np.float32)
    return out.reshape(points.shape)


def produce(renderer: SceneRenderer, binding: CameraBinding, index: int, request: FrameRequest,
            seed: int) -> CameraFrame:
    """Render and post-process one frame of ``binding``'s camera at ``request.state``."""
    spec, view = binding.spec, binding.view
    start = time.perf_counter()
    renderer.set_state(request.state)
    rng = frame_rng(seed, index, request.state.stamp_s, spec.rate_hz)
    stamp = request.state.stamp_s
    if spec.kind is CameraKind.COLOR:
        rgb = apply_image_noise(renderer.color(view), spec.noise_mean, spec.noise_stddev, rng)
        image = encode(rgb, spec.pixel_format)
        return CameraFrame(index, stamp, image=image, elapsed_ms=1000.0 * (time.perf_counter() - start))
    metric = depth_from_zbuffer(renderer.zbuffer(view), view.near_m, view.far_m)
    depth = finalize_depth(metric, ray_lengths(spec.width, spec.height, spec.hfov_rad), spec.near_m, spec.far_m,
                           noise_mean=spec.noise_mean, noise_stddev=spec.noise_stddev, rng=rng)
    points, dense = None, True
    if request.points:
        cloud = optical_points(depth, spec.hfov_rad)
        if binding.frame_site >= 0:
            sensor_pos, sensor_rot = renderer.site_pose(binding.sensor_site)
            frame_pos, frame_rot = renderer.site_pose(binding.frame_site)
            rotation = frame_rot.T @ sensor_rot @ OPTICAL_IN_SENSOR
            cloud = points_in_frame(cloud, rotation, frame_rot.T @ (sensor_pos - frame_pos))
        points, dense = point_cloud_data(cloud, depth_gray(depth))
    return CameraFrame(index, stamp, depth=depth, points=points, dense=dense,
                       elapsed_ms=1000.0 * (time.perf_counter() - start))


class CameraWorker:
    """Renders requested frames of ``bindings``' cameras in a thread of its own.

    Args:
        model: the compiled model (copied: the worker never reads the simulation's data).
        bindings: the cameras.
        seed: the simulation's seed (image noise).
        deliver: called in the worker's thread with each frame.
        log: called in the worker's thread with warnings (skipped frames, a failed delivery).
        backend: the OpenGL backend (None: ``MUJOCO_GL``, else EGL).
    """

    def __init__(self, model: mujoco.MjModel, bindings: Sequence[CameraBinding], seed: int,
                 deliver: Callable[[CameraFrame], None], log: Callable[[str], None], *,
                 backend: str | None = None, nice: int = RENDER_NICE, every_frame: bool = False,
                 make_renderer: Callable[..., SceneRenderer] = SceneRenderer) -> None:
        self.bindings = list(bindings)
        #: never skip a frame: :meth:`submit` waits for the camera's previous frame to be taken
        self.every_frame = every_frame
        self.seed = seed
        self.deliver = deliver
        self.log = log
        #: why the worker stopped (no OpenGL backend, a render error); None while it works
        self.failed: str | None = None
        self.frames = 0  # delivered
        self.skipped = [0] * len(self.bindings)  # since each camera's last warning
        self.asked = [0] * len(self.bindings)  # frames asked for, since each camera's last warning
        self._times_ms: list[deque[float]] = [deque(maxlen=20) for _ in self.bindings]
        self._warned = [time.monotonic()] * len(self.bindings)
        self._pending: dict[int, FrameRequest] = {}
        self._busy = False
        self._stopping = False
        self._cond = threading.Condition()
        self._ready = threading.Event()
        self._args = (model, backend, nice, make_renderer)
        self._thread = threading.Thread(target=self._run, name="camera-render", daemon=True)
        self._thread.start()

    # ------------------------------------------------------------ the caller's side
    def submit(self, request: FrameRequest) -> bool:
        """Render ``request`` when the thread is free; an older request of the same camera still
        waiting is skipped (with :attr:`every_frame`: waited for, until the thread takes it). False
        when the worker has stopped (see :attr:`failed`)."""
        with self._cond:
            while self.every_frame and request.index in self._pending and self.failed is None \
                    and not self._stopping:
                self._cond.wait()
            if self.failed is not None or self._stopping:
                return False
            self.asked[request.index] += 1
            if request.index in self._pending:
                self.skipped[request.index] += 1
            self._pending[request.index] = request
            self._cond.notify()
        return True

    def wait_ready(self, timeout_s: float) -> bool:
        """Whether the OpenGL context is up (False: not yet, or :attr:`failed`)."""
        return self._ready.wait(timeout_s) and self.failed is None

    def wait_idle(self, timeout_s: float) -> bool:
        """Until nothing waits and nothing renders (True), the worker stopped or ``timeout_s`` passed."""
        deadline = time.monotonic() + timeout_s
        with self._cond:
            while (self._pending or self._busy) and self.failed is None:
                remaining = deadline - time.monotonic()
                if remaining <= 0 or not self._cond.wait(remaining):
                    return False
            return self.failed is None

    def close(self, timeout_s: float = 5.0) -> None:
        """Stop the thread (a frame being rendered is finished first)."""
        with self._cond:
            self._stopping = True
            self._pending.clear()
            self._cond.notify_all()
        if self._thread is not threading.current_thread():
            self._thread.join(timeout_s)

    # ------------------------------------------------------------ the thread
    def _run(self) -> None:
        model, backend, nice, make_renderer = self._args
        _lower_priority(nice)
        try:
            renderer = make_renderer(model, [b.view for b in self.bindings], backend)
        except RenderUnavailable as exc:
            self._stop(str(exc))
            return
        except Exception as exc:  # MuJoCo's renderer could not start on this context
            self._stop(f"no renderer ({type(exc).__name__}: {exc})")
            return
        with self._cond:  # frames due while the context was made are not the renderer's doing
            self.skipped = [0] * len(self.bindings)
            self.asked = [0] * len(self.bindings)
            self._warned = [time.monotonic()] * len(self.bindings)
        self._ready.set()
        try:
            while True:
                with self._cond:
                    while not self._pending and not self._stopping:
                        self._cond.wait()
                    if self._stopping:
                        return
                    index = min(self._pending, key=lambda i: self._pending[i].state.stamp_s)
                    request = self._pending.pop(index)
                    self._busy = True
                    self._cond.notify_all()  # a submit waiting for this camera's turn (every_frame)
                try:
                    frame = produce(renderer, self.bindings[index], index, request, self.seed)
                    self.deliver(frame)
                    self.frames += 1
                    self._account(index, frame.elapsed_ms)
                finally:
                    with self._cond:
                        self._busy = False
                        self._cond.notify_all()
        except Exception as exc:  # an OpenGL error mid-run: the cameras stop, the simulation goes on
            self._stop(f"rendering failed ({type(exc).__name__}: {exc})")
        finally:
            renderer.close()

    def _account(self, index: int, elapsed_ms: float) -> None:
        self._times_ms[index].append(elapsed_ms)
        now = time.monotonic()
        if self.skipped[index] and now - self._warned[index] >= WARN_PERIOD_S:
            with self._cond:
                skipped, self.skipped[index] = self.skipped[index], 0
                asked, self.asked[index] = self.asked[index], 0
            self.log(f"camera '{self.bindings[index].spec.name}': skipped {skipped} of {asked} frame(s) in the last "
                     f"{now - self._warned[index]:.0f} s: the machine is too busy to render them in time (a frame "
                     f"takes {statistics.median(self._times_ms[index]):.0f} ms). Cameras render only while someone "
                     "subscribes: closing the live view's page, or cameras:=false, frees the CPU")
            self._warned[index] = now

    def _stop(self, reason: str) -> None:
        with self._cond:
            self.failed = reason
            self._pending.clear()
            self._cond.notify_all()
        self._ready.set()


def _lower_priority(nice: int) -> None:
    """This thread (and the threads it starts) ``nice`` steps below the process (Linux: niceness is
    per thread)."""
    if nice <= 0 or not hasattr(os, "setpriority"):
        return
    try:
        tid = threading.get_native_id()
        os.setpriority(os.PRIO_PROCESS, tid, min(19, os.getpriority(os.PRIO_PROCESS, tid) + nice))
    except OSError:
        pass
