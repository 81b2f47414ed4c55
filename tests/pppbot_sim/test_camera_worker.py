"""The camera thread without OpenGL (a stand-in renderer): frames rendered from the state they were
asked with, skipped when the renderer is behind (and said so), and a missing backend stops the cameras
and nothing else."""
from __future__ import annotations

import re
import threading
from collections.abc import Sequence
from typing import Any

import numpy as np
import pytest

from pppbot_common.ros.wait import wait_until
from pppbot_sim.camera_worker import CameraBinding, CameraFrame, CameraWorker, FrameRequest
from pppbot_sim.cameras import CameraKind, CameraSpec, PixelFormat
from pppbot_sim.render import CameraView, RenderState, RenderUnavailable

SPEC = CameraSpec(name="cam", link="camera_link", kind=CameraKind.COLOR, frame_id="camera_link_optical",
                  topic="camera/image_raw", info_topic="camera/camera_info", points_topic="", rate_hz=10.0, width=8,
                  height=6, hfov_rad=1.0, near_m=0.05, far_m=8.0, pixel_format=PixelFormat("rgb8", 3))
BINDING = CameraBinding(SPEC, CameraView(0, 8, 6, 0.05, 8.0), sensor_site=0, frame_site=-1)


class StandInRenderer:
    """Renders the state's first position as the image's grey level; ``gate`` holds each frame
    (``entered`` is set once a frame waits there)."""

    def __init__(self, model: Any, views: Sequence[CameraView], backend: str | None,
                 gate: threading.Semaphore | None = None) -> None:
        self.gate = gate
        self.entered = threading.Event()
        self.qpos = np.zeros(1)
        self.closed = False

    def set_state(self, state: RenderState) -> None:
        self.qpos = state.qpos

    def color(self, view: CameraView) -> np.ndarray:
        if self.gate is not None:
            self.entered.set()
            assert self.gate.acquire(timeout=10)
        return np.full((view.height, view.width, 3), int(self.qpos[0]), dtype=np.uint8)

    def close(self) -> None:
        self.closed = True


def state(t: float, value: float) -> RenderState:
    return RenderState(t, np.array([value]), np.zeros((0, 3)), np.zeros((0, 4)))


class Collected:
    def __init__(self) -> None:
        self.frames: list[CameraFrame] = []
        self.logged: list[str] = []


@pytest.fixture
def collected() -> Collected:
    return Collected()


def worker(collected: Collected, **kwargs: Any) -> CameraWorker:
    return CameraWorker(None, [BINDING], seed=0, deliver=collected.frames.append, log=collected.logged.append,
                        **kwargs)


def test_each_frame_shows_the_state_it_was_asked_with(collected: Collected) -> None:
    w = worker(collected, make_renderer=StandInRenderer)
    try:
        for i in range(3):
            assert w.submit(FrameRequest(0, state(0.1 * i, 10.0 * i)))
            assert w.wait_idle(10)
    finally:
        w.close()
    assert [f.stamp_s for f in collected.frames] == [0.0, 0.1, 0.2]
    assert [int(np.asarray(f.image)[0, 0, 0]) for f in collected.frames] == [0, 10, 20]
    assert collected.logged == []


def test_a_renderer_behind_skips_frames_and_says_so(collected: Collected, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("pppbot_sim.camera_worker.WARN_PERIOD_S", 0.0)
    gate = threading.Semaphore(0)
    renderer = StandInRenderer(None, [], None, gate)
    w = worker(collected, make_renderer=lambda *args: renderer)
    try:
        w.submit(FrameRequest(0, state(0.0, 1.0)))
        assert renderer.entered.wait(10)  # the first frame is being rendered; three more come meanwhile
        for i in range(1, 4):
            w.submit(FrameRequest(0, state(0.1 * i, 1.0 + i)))
        gate.release(2)
        assert w.wait_idle(10)
    finally:
        w.close()
    assert [f.stamp_s for f in collected.frames] == pytest.approx([0.0, 0.3])  # the newest waiting one, not 0.1 and 0.2
    assert len(collected.logged) == 1
    # 4 asked (3 when the first came before the renderer was up, which resets the counts)
    assert re.match(r"camera 'cam': skipped 2 of [34] frame\(s\) in the last ", collected.logged[0])
    assert "cameras:=false" in collected.logged[0]  # and what to do about it


def test_in_lockstep_a_renderer_behind_holds_the_caller_and_every_frame_comes(collected: Collected) -> None:
    """every_frame (lockstep): a frame asked for while the camera's previous one still waits makes the
    caller (the physics loop) wait its turn; no frame is skipped, however slow the renderer."""
    gate = threading.Semaphore(0)
    renderer = StandInRenderer(None, [], None, gate)
    w = worker(collected, make_renderer=lambda *args: renderer, every_frame=True)
    submitted: list[int] = []

    def physics() -> None:
        for i in range(4):
            w.submit(FrameRequest(0, state(0.1 * i, 1.0 + i)))
            submitted.append(i)

    loop = threading.Thread(target=physics)
    try:
        loop.start()
        assert renderer.entered.wait(10)  # frame 0 renders (held at the gate) while the loop asks for more
        # (without every_frame the loop would ask for all four now and frames 1 and 2 be skipped)
        assert wait_until(lambda: len(submitted) >= 2, 10, "frame 1 asked for")
        gate.release(4)
        loop.join(10)
        assert w.wait_idle(10)
    finally:
        gate.release(4)
        w.close()
    assert submitted == [0, 1, 2, 3]
    assert [f.stamp_s for f in collected.frames] == pytest.approx([0.0, 0.1, 0.2, 0.3])
    assert collected.logged == []


def test_no_backend_stops_the_cameras_with_the_reason(collected: Collected) -> None:
    def unavailable(*args: Any) -> StandInRenderer:
        raise RenderUnavailable("MUJOCO_GL=osmesa: no OpenGL context (no libOSMesa)")

    w = worker(collected, make_renderer=unavailable)
    assert not w.wait_ready(10)
    assert w.failed == "MUJOCO_GL=osmesa: no OpenGL context (no libOSMesa)"
    assert not w.submit(FrameRequest(0, state(0.0, 1.0)))
    w.close()
    assert collected.frames == []


def test_a_render_error_stops_the_cameras(collected: Collected) -> None:
    made: list[StandInRenderer] = []

    class Failing(StandInRenderer):
        def color(self, view: CameraView) -> np.ndarray:
            raise RuntimeError("GL_OUT_OF_MEMORY")

    def make(*args: Any) -> StandInRenderer:
        made.append(Failing(*args))
        return made[-1]

    w = worker(collected, make_renderer=make)
    w.submit(FrameRequest(0, state(0.0, 1.0)))
    assert not w.wait_idle(10)
    assert w.failed == "rendering failed (RuntimeError: GL_OUT_OF_MEMORY)"
    w.close()
    assert made[0].closed
