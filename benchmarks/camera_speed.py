"""How fast the cameras render, and what a watched camera costs the lockstep mapping stack (issue 27).

* ``rgb_ms`` / ``depth_ms``: ppp_bot's camera (640 x 480 RGB, ``camera.xacro``) and its depth camera
  (640 x 480, ``use_depth_camera:=true``) in ``--world`` (default maze), the robot turning on the
  spot through ``--frames`` headings; each frame rendered in this process as the camera thread
  renders it (one OpenGL context: ``MUJOCO_GL``, EGL when unset). Medians of the whole frame (state,
  OpenGL draw and read-back, noise and encoding; depth: metres with REP-118's infinities), of the
  OpenGL part alone (``*_render_ms``) and of a depth frame with its 7 MB point cloud
  (``depth_with_points_ms``).
* ``mapping_rtf_camera_off`` / ``mapping_rtf_camera_on``: ``pppbot eval slam`` in lockstep (the
  mapping stack of ``benchmarks/stack_speed.py``, ``--mapping-seconds`` sim s of its route), with
  nobody watching the camera (it is then not rendered at all) and with a subscriber to
  ``/camera/image_raw`` for the whole run (taking the frames as bytes, so that what the simulator's
  camera costs is measured, not what its reader does with 900 kB frames); runs alternate
  ``--repeats`` times (the machine's other load changes), medians reported, and how many of the
  10 Hz camera's frames the subscriber got.

    ./pppbot env python benchmarks/camera_speed.py [--world maze] [--frames 60] [--mapping-seconds 120]
        [--repeats 1] [--no-mapping]
"""
from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from pppbot_common.dds_isolation import isolate_dds

ROOT = Path(__file__).resolve().parent.parent
PPPBOT = str(ROOT / "pppbot")
TARGETS = {"rgb_ms": 30.0, "depth_ms": 20.0, "mapping_rtf_camera_on": 5.0}
#: A plain subscriber to the camera: prints 'ready', then at SIGINT the stamps of the frames it got (JSON).
#: It takes the frames as bytes (their stamp is at bytes 4-12): what a frame costs its reader is not counted.
WATCHER = """
import json, struct, rclpy
from sensor_msgs.msg import Image
rclpy.init(); node = rclpy.create_node('bench_camera_watcher'); stamps = []
def on_frame(data):
    sec, nanosec = struct.unpack_from('<iI', data, 4)
    stamps.append(sec + nanosec * 1e-9)
node.create_subscription(Image, '/camera/image_raw', on_frame, 10, raw=True)
print('ready', flush=True)
try:
    rclpy.spin(node)
except BaseException:
    pass
print(json.dumps(stamps), flush=True)
"""


def frame_times(world: str, frames: int, depth: bool) -> tuple[float, float, float]:
    """Medians (ms) of a frame as the camera thread makes it (a depth camera's with its points), of a
    depth image without its points (nan for a colour camera), and of the OpenGL part, for ppp_bot's
    camera (or depth camera) turning through ``frames`` headings at the spawn point of ``world``."""
    from pppbot_description.urdf_model import parse_urdf
    from pppbot_description.xacro_model import process_xacro
    from pppbot_sim.camera_worker import FrameRequest, produce
    from pppbot_sim.cameras import depth_from_zbuffer
    from pppbot_sim.mj_build import SpawnPose
    from pppbot_sim.render import SceneRenderer
    from pppbot_sim.simulation import Simulation, load_world
    from pppbot_sim.worlds import find_world, model_paths

    world_file = find_world(world)
    spec, sdf = load_world(world_file, model_paths(world_file))
    robot = parse_urdf(process_xacro(mappings={"use_depth_camera": str(depth).lower()}))
    sim = Simulation(spec, robot, SpawnPose(0.0, 0.0, math.nan, 0.0), world=sdf)
    (binding,) = sim.cameras
    renderer = SceneRenderer(sim.model, [binding.view])
    free = sim._free_qpos  # the robot's root: turned in place between frames
    whole, without_points, gl = [], [], []
    try:
        for i in range(frames + 1):
            yaw = 2 * math.pi * i / frames
            sim.data.qpos[free + 3:free + 7] = [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]
            state = sim.render_state()
            start = time.perf_counter()
            produce(renderer, binding, 0, FrameRequest(0, state), seed=0)
            middle = time.perf_counter()
            if depth:
                produce(renderer, binding, 0, FrameRequest(0, state, points=False), seed=0)
            image_only = time.perf_counter()
            renderer.set_state(state)
            drawn = time.perf_counter()
            if depth:
                depth_from_zbuffer(renderer.zbuffer(binding.view), binding.view.near_m, binding.view.far_m)
            else:
                renderer.color(binding.view)
            end = time.perf_counter()
            if i:  # the first frame compiles shaders and uploads the model
                whole.append(1000 * (middle - start))
                without_points.append(1000 * (image_only - middle))
                gl.append(1000 * (end - drawn))
    finally:
        renderer.close()
    return (statistics.median(whole), statistics.median(without_points) if depth else math.nan,
            statistics.median(gl))


def eval_slam(world: str, seconds: float, watch: bool) -> dict[str, Any]:
    """One lockstep ``pppbot eval slam`` (with a watcher of the camera): its real-time factor and,
    watched, the frames the watcher got."""
    watcher = None
    if watch:
        watcher = subprocess.Popen([PPPBOT, "env", "python", "-c", WATCHER], stdout=subprocess.PIPE, text=True,
                                   start_new_session=True)
        if watcher.stdout is None or watcher.stdout.readline().strip() != "ready":
            raise SystemExit("camera_speed: the camera watcher did not start")
    with tempfile.TemporaryDirectory(prefix="camera_speed_slam_") as directory:
        out = Path(directory)
        try:
            result = subprocess.run([PPPBOT, "eval", "slam", "--world", world, "--timeout", str(seconds), "--no-view",
                                     "--out", str(out)], capture_output=True, text=True)
        finally:
            got = ""
            if watcher is not None:
                watcher.send_signal(2)
                got, _ = watcher.communicate(timeout=30)
        report_file = out / "report.json"
        if not report_file.is_file():
            raise SystemExit(f"camera_speed: eval slam wrote no report:\n{result.stderr[-2000:]}")
        report = json.loads(report_file.read_text())
    run = {"real_time_factor": round(float(report["real_time_factor"]), 2),
           "sim_seconds": round(float(report["sim_seconds"]), 1)}
    if watcher is not None:  # the frames of the run's sim time (the simulator runs on while the stack stops)
        lines = got.strip().splitlines()
        stamps = set(json.loads(lines[-1])) if lines else set()
        run["frames"] = sum(1 for t in stamps if t <= run["sim_seconds"] + 1e-6)
        run["frames_expected"] = int(round(run["sim_seconds"] * 10))
    return run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--world", default="maze")
    parser.add_argument("--frames", type=int, default=60, help="frames per camera (headings)")
    parser.add_argument("--mapping-seconds", type=float, default=120.0, help="sim seconds of each mapping run")
    parser.add_argument("--repeats", type=int, default=1, help="mapping runs with the camera off and on, alternating")
    parser.add_argument("--no-mapping", action="store_true", help="frame times only")
    args = parser.parse_args()
    isolate_dds()
    figures: dict[str, Any] = {"world": args.world, "cores": os.cpu_count(),
                               "gl_backend": os.environ.get("MUJOCO_GL", "egl"), "image": "640x480"}
    rgb, _, rgb_gl = frame_times(args.world, args.frames, depth=False)
    depth_points, depth, depth_gl = frame_times(args.world, args.frames, depth=True)
    figures.update(rgb_ms=round(rgb, 1), rgb_render_ms=round(rgb_gl, 1), depth_ms=round(depth, 1),
                   depth_render_ms=round(depth_gl, 1), depth_with_points_ms=round(depth_points, 1))
    print(f"frames: rgb {rgb:.1f} ms ({rgb_gl:.1f} ms OpenGL), depth {depth:.1f} ms ({depth_gl:.1f} ms OpenGL), "
          f"depth with its points {depth_points:.1f} ms", file=sys.stderr)
    if not args.no_mapping:
        off, on = [], []
        for _ in range(args.repeats):
            off.append(eval_slam(args.world, args.mapping_seconds, watch=False))
            print(f"mapping, camera off: {off[-1]}", file=sys.stderr)
            on.append(eval_slam(args.world, args.mapping_seconds, watch=True))
            print(f"mapping, camera on: {on[-1]}", file=sys.stderr)
        figures.update(
            mapping_rtf_camera_off=statistics.median(r["real_time_factor"] for r in off),
            mapping_rtf_camera_on=statistics.median(r["real_time_factor"] for r in on),
            camera_frames_received=sum(r["frames"] for r in on),
            camera_frames_expected=sum(r["frames_expected"] for r in on),
            mapping_runs={"camera_off": off, "camera_on": on})
    figures["targets"] = TARGETS
    figures["met"] = {k: (figures[k] >= t if k.endswith("_rtf_camera_on") else figures[k] <= t)
                      for k, t in TARGETS.items() if k in figures}
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
