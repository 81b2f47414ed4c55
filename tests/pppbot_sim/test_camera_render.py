"""Cameras rendered with OpenGL (EGL or OSMesa, software Mesa is enough): a robot with a colour
camera and two depth cameras looks at boxes at known places (data/camera_box.xml)."""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from pppbot_description.urdf_model import parse_urdf
from pppbot_sim.camera_worker import CameraBinding, FrameRequest, produce
from pppbot_sim.cameras import POINT_STEP
from pppbot_sim.mj_build import SpawnPose
from pppbot_sim.render import SceneRenderer
from pppbot_sim.simulation import Simulation, load_world

DATA = Path(__file__).parent / "data"
SEED = 11
# The front cameras sit at (0.2, 0, 1.2) looking along +x; the red box's face is at x = 2.9,
# y 0.1..0.7, z 1.0..1.4: 2.7 m ahead.
FACE_DEPTH_M = 2.7


@pytest.fixture(scope="module")
def sim() -> Simulation:
    spec, _ = load_world(DATA / "camera_box.xml", [])
    robot = parse_urdf((DATA / "camera_bot.urdf").read_text())
    return Simulation(spec, robot, SpawnPose(0.0, 0.0, 1.0, 0.0), name="camera_bot", seed=SEED)


@pytest.fixture(scope="module")
def renderer(opengl: None, sim: Simulation) -> Iterator[SceneRenderer]:
    scene = SceneRenderer(sim.model, [b.view for b in sim.cameras])
    yield scene
    scene.close()


def camera(sim: Simulation, name: str) -> tuple[int, CameraBinding]:
    (found,) = [(i, b) for i, b in enumerate(sim.cameras) if b.spec.name == name]
    return found


def frame(sim: Simulation, renderer: SceneRenderer, name: str, binding: CameraBinding | None = None):
    index, own = camera(sim, name)
    return produce(renderer, binding or own, index, FrameRequest(index, sim.render_state()), SEED)


def pixel(binding: CameraBinding, x: float, y: float, z: float) -> tuple[float, float]:
    """Where a point in the optical frame lands (u, v), pixel centres at whole numbers."""
    s = binding.spec
    return s.focal_px * x / z + (s.width - 1) / 2, s.focal_px * y / z + (s.height - 1) / 2


def test_colour_camera_sees_the_box_where_it_projects(sim, renderer) -> None:
    index, binding = camera(sim, "front")
    image = frame(sim, renderer, "front").image
    assert image.shape == (240, 320, 3) and image.dtype == np.uint8
    red = (image == [255, 0, 0]).all(axis=2)
    rows, cols = np.flatnonzero(red.any(axis=1)), np.flatnonzero(red.any(axis=0))
    # optical x = -y (world), optical y = -(z - 1.2)
    left, top = pixel(binding, -0.7, -0.2, FACE_DEPTH_M)
    right, bottom = pixel(binding, -0.1, 0.2, FACE_DEPTH_M)
    assert abs(cols[0] - left) <= 1 and abs(cols[-1] - right) <= 1
    assert abs(rows[0] - top) <= 1 and abs(rows[-1] - bottom) <= 1
    assert red[rows[0] + 1:rows[-1], cols[0] + 1:cols[-1]].all()  # a filled rectangle (its side face at y = 0.1
    assert (image[~red] == 0).all()  # shows as a sliver on the right); nothing else in view: black


def test_camera_info_matches_the_image(sim) -> None:
    _, binding = camera(sim, "front")
    s = binding.spec
    fx = s.width / (2 * math.tan(s.hfov_rad / 2))
    assert s.k_matrix() == pytest.approx([fx, 0, s.width / 2, 0, fx, s.height / 2, 0, 0, 1])
    # the rendered image is the pinhole the info describes: the box's width in pixels over its
    # width in metres is fx / depth (checked in the test above), and fy = fx (square pixels)
    assert binding.view.width == s.width and binding.view.height == s.height


def test_depth_is_the_distance_along_the_optical_axis(sim, renderer) -> None:
    index, binding = camera(sim, "depth")
    depth = frame(sim, renderer, "depth").depth
    assert depth.shape == (240, 320) and depth.dtype == np.float32
    left, top = pixel(binding, -0.7, -0.2, FACE_DEPTH_M)
    right, bottom = pixel(binding, -0.1, 0.2, FACE_DEPTH_M)
    inside = depth[math.ceil(top) + 1:math.floor(bottom), math.ceil(left) + 1:math.floor(right)]
    assert inside.size > 2000
    np.testing.assert_allclose(inside, FACE_DEPTH_M, atol=0.01)
    assert np.isinf(depth).sum() == depth.size - np.isfinite(depth).sum()  # the rest sees nothing: +inf
    assert (depth[~np.isfinite(depth)] > 0).all()


def test_points_lie_on_the_box_face_in_the_optical_frame(sim, renderer) -> None:
    result = frame(sim, renderer, "depth")
    dtype = np.dtype({"names": ["x", "y", "z", "rgb"], "formats": ["<f4", "<f4", "<f4", "<u4"],
                      "offsets": [0, 4, 8, 16], "itemsize": POINT_STEP})
    cloud = result.points.view(dtype).reshape(240, 320)
    hit = np.isfinite(cloud["z"])
    assert hit.sum() > 2000 and not result.dense  # the face covers 60 x 40 pixels
    face = hit & (np.abs(cloud["z"] - FACE_DEPTH_M) < 0.01)
    assert face.sum() > 0.97 * hit.sum()  # the rest: the box's side face at y = 0.1, seen edge on
    x, y = cloud["x"][face], cloud["y"][face]  # depth_link_optical: x = -y (world), y = 1.2 - z
    assert x.min() >= -0.7 - 0.01 and x.max() <= -0.1 + 0.01 and y.min() >= -0.2 - 0.01 and y.max() <= 0.2 + 0.01
    assert x.max() - x.min() > 0.58 and y.max() - y.min() > 0.38  # the whole face
    np.testing.assert_array_equal(cloud["z"], result.depth)


def test_depth_infinities_and_points_in_a_frame_that_is_not_optical(sim, renderer) -> None:
    """The rear camera (near clip 0.5 m, far 5 m, frame rear_link: x forward) sees a box 0.19 m
    away over the upper half of its view and a wall 4.4 m away over the lower half."""
    index, binding = camera(sim, "rear")
    assert binding.spec.frame_id == "rear_link"
    result = frame(sim, renderer, "rear")
    depth = result.depth
    height, width = depth.shape
    assert (depth[: height // 2 - 1] == -np.inf).all()  # nearer than the near clip
    wall = depth[height // 2 + 1:]
    np.testing.assert_allclose(wall[0, width // 2], 4.4, atol=0.01)
    assert (wall[-1, [0, -1]] == np.inf).all()  # 4.4 m deep, but more than 5 m away
    ranges = wall * np.hypot(np.hypot(np.arange(width) - (width - 1) / 2,
                                      (np.arange(height // 2 + 1, height) - (height - 1) / 2)[:, None]),
                             binding.spec.focal_px) / binding.spec.focal_px
    assert (np.isfinite(wall) == (ranges <= 5.0)).all()
    cloud = result.points.view(np.float32).reshape(height, width, POINT_STEP // 4)
    finite = np.isfinite(cloud[:, :, 0])
    np.testing.assert_allclose(cloud[:, :, 0][finite], 4.4, atol=0.01)  # x forward in rear_link
    assert (cloud[:, :, 2][finite] < 0).all()  # the wall is below the camera: z up
    assert (cloud[: height // 2 - 1, :, :3] == -np.inf).all()


def test_frames_are_reproducible_and_noise_is_seeded(sim, renderer) -> None:
    index, binding = camera(sim, "front")
    noisy = dataclasses.replace(binding, spec=dataclasses.replace(binding.spec, noise_stddev=0.05))
    a, b = frame(sim, renderer, "front", noisy).image, frame(sim, renderer, "front", noisy).image
    np.testing.assert_array_equal(a, b)  # same seed, same stamp: the same frame
    clean = frame(sim, renderer, "front").image.astype(float)
    black = (clean == 0).all(axis=2)
    noise = a.astype(float)[black][:, 0]  # on black, half the samples clamp at 0: the rest is the noise
    assert 0.3 < (noise > 0).mean() < 0.7
    assert noise.max() > 0.1 * 255


def drive_box_room(render: bool, every_frame: bool = False) -> tuple[list[np.ndarray], np.ndarray, dict[float, bytes]]:
    """ppp_bot driving a curve in the box room for 3 sim s with wheel slip; its camera rendered in
    the camera thread meanwhile (``render``; ``every_frame``: physics waits for each frame, none is
    skipped) or not at all: the scans, the final state, the frames by stamp."""
    from pppbot_description.xacro_model import process_xacro
    from pppbot_sim.camera_worker import CameraWorker
    from pppbot_sim.runner import CameraReading, LidarReading, PhysicsRunner
    from pppbot_sim.simulation import EventKind
    from pppbot_sim.wheel_slip import SlipModel
    from pppbot_sim.worlds import model_paths

    world_file = DATA / "box_room.sdf"
    spec, world = load_world(world_file, model_paths(world_file))
    ppp_bot = Simulation(spec, parse_urdf(process_xacro()), SpawnPose(0.0, 0.0, math.nan, 0.0), seed=3,
                         slip=SlipModel(0.02, 2.0), world=world)
    runner = PhysicsRunner(ppp_bot, command_timeout_s=0.0)
    runner.command({"left_wheel_joint": 3.0, "right_wheel_joint": 5.0})
    frames: dict[float, bytes] = {}
    worker = CameraWorker(ppp_bot.model, ppp_bot.cameras, 3,
                          lambda f: frames.__setitem__(f.stamp_s, np.asarray(f.image).tobytes()),
                          log=lambda text: None) if render else None
    scans = []
    try:
        while ppp_bot.time_s < 3.0:
            for reading in runner.advance(wanted=lambda e: render or e.kind is not EventKind.CAMERA):
                if isinstance(reading, LidarReading):
                    scans.append(reading.scan.ranges.copy())
                elif isinstance(reading, CameraReading) and worker is not None:
                    worker.submit(FrameRequest(reading.index, reading.state))
                    if every_frame:
                        assert worker.wait_idle(30)
        if worker is not None:
            assert worker.wait_idle(30)
    finally:
        if worker is not None:
            worker.close()
    return scans, ppp_bot.data.qpos.copy(), frames


def test_rendering_alongside_leaves_physics_and_lidar_alone(renderer) -> None:
    """What lockstep's determinism rests on: the camera thread reads copies of the state and draws
    no random numbers the simulation draws, so scans and motion are bit for bit the same whether
    or not a camera renders; and a frame at a given stamp is the same in every run."""
    quiet_scans, quiet_state, _ = drive_box_room(render=False)
    scans, state, some = drive_box_room(render=True)  # physics far faster than rendering: most skipped
    _, _, every = drive_box_room(render=True, every_frame=True)
    _, _, again = drive_box_room(render=True, every_frame=True)
    assert len(scans) == len(quiet_scans) == 31  # one at the first step, then every 0.1 s
    for a, b in zip(scans, quiet_scans, strict=True):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(state, quiet_state)
    assert len(every) == 31 and every == again
    assert some and all(every[t] == frame for t, frame in some.items())
    assert len(set(every.values())) > 20  # the robot moved: the frames differ over time
