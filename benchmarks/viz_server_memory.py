"""The rerun server's memory over a long run: an hour (``--hours``) of a mapping run's live-view
stream, sent as fast as it goes, to ``rerun --serve-web`` started as ``launch_sim`` starts it.

The stream is what the viz node sends while mapping, at the rates ``launch_sim`` produces
them, chunked as the node chunks them (one flush per 0.2 s of sim time): the scan (640
points, 10 Hz), four moving TF frames (odom, base_link and the wheels, 50 Hz), the trail's
newest segment (6 Hz), the map (400×400, every 5 s), the local costmap (60×60, 2 Hz), the
global costmap (every 1 s), the plans (1 Hz) and the SLAM graph (every 5 s, growing by a node
per 0.5 m). ``benchmarks/viz_cost.py --mapping --seconds 3600`` measures the same for real in
an hour of wall time; this takes minutes. The server's RSS is sampled every 5 minutes of sim
time; the last line is one JSON object with the samples and the plateau (the largest RSS
over the second half).

    ./pppbot env python benchmarks/viz_server_memory.py [--hours 1] [--limit 32MiB]
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import rerun as rr
from pppbot_viz.viewer import SERVER_MEMORY_LIMIT
from viz_cost import rss_mb  # the scripts' folder is on sys.path

from pppbot_viz import viewer

BATCH_S = 0.2
TICK_S = 0.02  # 50 Hz: the fastest stream (TF)


def stream(rec: rr.RecordingStream, seconds: float, server: int, samples: list[dict[str, float]]) -> None:
    rng = np.random.default_rng(0)
    scan = rng.random((640, 3), dtype=np.float32)
    trail = rng.random((200, 3), dtype=np.float32)
    grid = rng.integers(0, 255, (400, 400), dtype=np.uint8)
    local = rng.integers(0, 255, (60, 60), dtype=np.uint8)
    plan = rng.random((300, 3), dtype=np.float32)
    ticks = int(seconds / TICK_S)
    per_batch = int(round(BATCH_S / TICK_S))
    for tick in range(ticks):
        t = tick * TICK_S
        rec.set_time("sim_time", duration=t)
        for frame in ("odom", "base_link", "left_wheel", "right_wheel"):
            rec.log(f"tf/{frame}", rr.Transform3D(translation=[t * 0.01, 0.0, 0.0], parent_frame="map",
                                                  child_frame=frame))
        if tick % 5 == 0:
            rec.log("scan", rr.CoordinateFrame("lidar_frame"), rr.Points3D(scan, radii=0.02))
        if tick % 8 == 0:
            rec.log(f"odom/trail/{(tick // 1600) % 20}", rr.LineStrips3D([trail[: 2 + (tick // 8) % 198]]))
        if tick % 25 == 0:
            rec.log("costmaps/local", rr.Image(local, color_model="L"))
        if tick % 50 == 0:
            rec.log("costmaps/global", rr.Image(grid, color_model="L"))
            rec.log("plans/global", rr.LineStrips3D([plan]))
        if tick % 250 == 0:
            rec.log("map", rr.Image(grid, color_model="L"))
            nodes = max(2, int(t * 0.3 / 0.5))  # a keyframe per 0.5 m at 0.3 m/s
            rec.log("slam/graph/nodes", rr.Points3D(rng.random((nodes, 3), dtype=np.float32)))
        if tick % per_batch == per_batch - 1:
            rec.flush()
        if tick % int(300 / TICK_S) == 0 and tick:
            rec.flush()
            samples.append({"sim_minutes": round(t / 60), "server_rss_mb": round(rss_mb(server), 1)})
            print(f"sim {t / 60:5.1f} min: server {samples[-1]['server_rss_mb']} MB", file=sys.stderr, flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--hours", type=float, default=1.0)
    parser.add_argument("--limit", default=SERVER_MEMORY_LIMIT, help=f"--server-memory-limit (default "
                                                                       f"{SERVER_MEMORY_LIMIT}, launch_sim's)")
    args = parser.parse_args()
    state = Path(tempfile.mkdtemp(prefix="viz_server_memory_"))
    viewer.write_viewer_settings(state)
    grpc, web = viewer.free_port(), viewer.free_port()
    env = {**os.environ, **viewer.viewer_environment(state), "RUST_LOG": "warn"}
    server = subprocess.Popen(viewer.server_command(grpc, web, memory_limit=args.limit), env=env)
    samples: list[dict[str, float]] = []
    try:
        while not viewer.listening(grpc):
            time.sleep(0.1)
        rec = rr.RecordingStream("pppbot", batcher_config=rr.ChunkBatcherConfig(
            flush_tick=3600.0, flush_num_bytes=4 << 20, flush_num_rows=1 << 30))
        rec.connect_grpc(viewer.grpc_url(grpc))
        t0 = time.monotonic()
        stream(rec, args.hours * 3600.0, server.pid, samples)
        rec.flush()
        wall = time.monotonic() - t0
        time.sleep(2.0)
        final = round(rss_mb(server.pid), 1)
    finally:
        server.terminate()
        server.wait(10)
        shutil.rmtree(state, ignore_errors=True)
    half = [s["server_rss_mb"] for s in samples[len(samples) // 2:]] or [final]
    print(json.dumps({"sim_hours": args.hours, "server_memory_limit": args.limit, "wall_seconds": round(wall, 1),
                      "samples": samples, "final_rss_mb": final, "plateau_rss_mb": max(half),
                      "first_half_max_rss_mb": max([s["server_rss_mb"] for s in samples[:len(samples) // 2]] or [0])}))


if __name__ == "__main__":
    main()
