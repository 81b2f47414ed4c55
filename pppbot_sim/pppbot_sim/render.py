"""Offscreen rendering of the simulator's cameras with MuJoCo's OpenGL renderer (no ROS).

:class:`SceneRenderer` owns an OpenGL context (EGL or OSMesa, software Mesa is enough), a
copy of the model and its own ``MjData``: it renders a camera from a :class:`RenderState`
(a snapshot of the simulation's positions at a time) and never touches the simulation's
data. It renders only what a sensor needs: no shadows, reflections, skybox, fog or haze, no
anti-aliasing, no sites or decorations; depth images in MuJoCo's segmentation mode (flat
colours, no lighting), whose depth buffer is the same. What that takes per frame:
``benchmarks/camera_speed.py`` (figures in docs/simulator.md, "Cameras").

OpenGL backends: ``MUJOCO_GL`` names it as for MuJoCo (``egl``, ``osmesa``, ``glfw``); unset,
EGL. A backend that does not work raises :class:`RenderUnavailable` with what to install.
"""
from __future__ import annotations

import copy
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from pppbot_common.errors import PppbotError

#: Debian packages that give each backend (software rendering, no GPU needed).
BACKEND_PACKAGES = {"egl": "libegl1 libegl-mesa0 libgl1-mesa-dri", "osmesa": "libosmesa6",
                    "glfw": "a display (X11) and libgl1-mesa-dri"}
#: Set by ``pppbot_sim/__init__.py`` (with the reason) when the environment's MUJOCO_GL stopped MuJoCo from loading.
REFUSED_MUJOCO_GL = "PPPBOT_REFUSED_MUJOCO_GL"


class RenderUnavailable(PppbotError, RuntimeError):
    """No working OpenGL backend; the message names the backend, the cause and what to install."""


def backend_name() -> str:
    """The OpenGL backend cameras use: ``MUJOCO_GL`` (lower case), ``egl`` when unset."""
    name = os.environ.get("MUJOCO_GL", "").strip().lower()
    return "egl" if name in ("", "1", "true", "on", "enable", "enabled") else name


def refused_backend() -> str | None:
    """Why cameras cannot render, when that is known without trying: ``MUJOCO_GL`` stopped MuJoCo
    from loading (see ``pppbot_sim/__init__.py``); None otherwise."""
    refused = os.environ.get(REFUSED_MUJOCO_GL)
    if not refused:
        return None
    return (f"{refused}; use MUJOCO_GL=egl (Debian: {BACKEND_PACKAGES['egl']}) or MUJOCO_GL=osmesa "
            f"(Debian: {BACKEND_PACKAGES['osmesa']})")


def create_gl_context(width: int, height: int, backend: str | None = None) -> Any:
    """An OpenGL context of the backend, made current in the calling thread.

    Raises:
        RenderUnavailable: the backend cannot be loaded or cannot make a context.
    """
    name = backend or backend_name()
    refused = refused_backend()
    if refused and backend is None:
        raise RenderUnavailable(refused)
    try:
        if name == "egl":
            from mujoco.egl import GLContext
        elif name == "osmesa":
            from mujoco.osmesa import GLContext
        elif name in ("glfw", "glx"):
            from mujoco.glfw import GLContext
        else:
            raise RenderUnavailable(f"MUJOCO_GL={name!r}: cameras render with egl, osmesa or glfw")
        context = GLContext(width, height)
        context.make_current()
    except RenderUnavailable:
        raise
    except Exception as exc:  # a missing library or driver surfaces as many exception types
        packages = BACKEND_PACKAGES.get(name, "")
        raise RenderUnavailable(f"MUJOCO_GL={name}: no OpenGL context ({type(exc).__name__}: {exc})"
                                + (f"; on Debian install {packages}" if packages else "")) from exc
    return context


@dataclass(frozen=True)
class RenderState:
    """The simulation's positions at ``stamp_s``: all a frame is rendered from."""

    stamp_s: float
    qpos: np.ndarray
    mocap_pos: np.ndarray
    mocap_quat: np.ndarray

    @classmethod
    def of(cls, data: mujoco.MjData) -> RenderState:
        """A snapshot of ``data``'s positions (copies)."""
        return cls(float(data.time), data.qpos.copy(), data.mocap_pos.copy(), data.mocap_quat.copy())


@dataclass(frozen=True)
class CameraView:
    """A camera of the model as the renderer draws it (lengths in m)."""

    camera_id: int
    width: int
    height: int
    near_m: float  # the render's near plane
    far_m: float


def camera_option() -> mujoco.MjvOption:
    """What a camera sees: every geom group (the robot's too), no sites, tendons or decorations."""
    option = mujoco.MjvOption()
    option.geomgroup[:] = 1
    option.sitegroup[:] = 0
    for flag in (mujoco.mjtVisFlag.mjVIS_TENDON, mujoco.mjtVisFlag.mjVIS_RANGEFINDER,
                 mujoco.mjtVisFlag.mjVIS_PERTOBJ, mujoco.mjtVisFlag.mjVIS_FLEXEDGE):
        option.flags[flag] = 0
    return option


#: Scene flags off for every camera image (what costs time and a sensor does not need).
_OFF = (mujoco.mjtRndFlag.mjRND_SHADOW, mujoco.mjtRndFlag.mjRND_REFLECTION, mujoco.mjtRndFlag.mjRND_SKYBOX,
        mujoco.mjtRndFlag.mjRND_FOG, mujoco.mjtRndFlag.mjRND_HAZE)


class SceneRenderer:
    """Renders cameras of ``model`` offscreen; create, use and close it in one thread.

    Raises:
        RenderUnavailable: (from the constructor) no OpenGL backend.
    """

    def __init__(self, model: mujoco.MjModel, views: Sequence[CameraView], backend: str | None = None,
                 make_context: Callable[[int, int, str | None], Any] = create_gl_context) -> None:
        width = max((v.width for v in views), default=1)
        height = max((v.height for v in views), default=1)
        self.model = copy.deepcopy(model)  # near/far planes change per camera: a copy of our own
        self.model.vis.global_.offwidth = max(width, 1)
        self.model.vis.global_.offheight = max(height, 1)
        self.model.vis.quality.offsamples = 0
        self.data = mujoco.MjData(self.model)
        self._gl = make_context(width, height, backend)
        self._context = mujoco.MjrContext(self.model, mujoco.mjtFontScale.mjFONTSCALE_50)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._context)
        self._context.readDepthMap = mujoco.mjtDepthMap.mjDEPTH_ZEROFAR
        self._scene = mujoco.MjvScene(self.model, maxgeom=max(1000, 2 * self.model.ngeom))
        for flag in _OFF:
            self._scene.flags[flag] = 0
        self._option = camera_option()
        self._camera = mujoco.MjvCamera()
        self._camera.type = mujoco.mjtCamera.mjCAMERA_FIXED
        self._extent = float(self.model.stat.extent)

    def set_state(self, state: RenderState) -> None:
        """Positions of every body, geom, camera and light at ``state``."""
        self.data.qpos[:] = state.qpos
        self.data.mocap_pos[:] = state.mocap_pos
        self.data.mocap_quat[:] = state.mocap_quat
        self.data.time = state.stamp_s
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_comPos(self.model, self.data)
        mujoco.mj_camlight(self.model, self.data)

    def _draw(self, view: CameraView, depth_only: bool) -> mujoco.MjrRect:
        self.model.vis.map.znear = view.near_m / self._extent
        self.model.vis.map.zfar = view.far_m / self._extent
        self._camera.fixedcamid = view.camera_id
        mujoco.mjv_updateScene(self.model, self.data, self._option, None, self._camera,
                               mujoco.mjtCatBit.mjCAT_ALL, self._scene)
        self._scene.flags[mujoco.mjtRndFlag.mjRND_SEGMENT] = depth_only
        self._scene.flags[mujoco.mjtRndFlag.mjRND_IDCOLOR] = depth_only
        rect = mujoco.MjrRect(0, 0, view.width, view.height)
        mujoco.mjr_render(rect, self._scene, self._context)
        return rect

    def color(self, view: CameraView) -> np.ndarray:
        """The camera's image: height x width x 3 uint8, top row first."""
        rect = self._draw(view, depth_only=False)
        rgb = np.empty((view.height, view.width, 3), dtype=np.uint8)
        mujoco.mjr_readPixels(rgb, None, rect, self._context)
        return np.ascontiguousarray(rgb[::-1])

    def zbuffer(self, view: CameraView) -> np.ndarray:
        """The camera's depth buffer (height x width float32, top row first): 1 at the near plane,
        0 at the far plane and where nothing was drawn (see :func:`pppbot_sim.cameras.depth_from_zbuffer`)."""
        rect = self._draw(view, depth_only=True)
        depth = np.empty((view.height, view.width), dtype=np.float32)
        mujoco.mjr_readPixels(None, depth, rect, self._context)
        return np.ascontiguousarray(depth[::-1])

    def site_pose(self, site: int) -> tuple[np.ndarray, np.ndarray]:
        """(position, rotation matrix) of a site at the current state."""
        return self.data.site_xpos[site].copy(), self.data.site_xmat[site].reshape(3, 3).copy()

    def close(self) -> None:
        """Free the GL resources (in the thread that made them)."""
        if self._context is not None:
            self._context.free()
            self._context = None
        if self._gl is not None:
            self._gl.free()
            self._gl = None
