"""AMCL speed and accuracy (issue 10): time per filter update in the localizer core, on real scans.

Input: the dataset of ``benchmarks/slam_dataset.py`` (a world's route driven in the simulation
core with wheel slip; made on first use, cached in ``benchmarks/.cache/``): 640-beam scans,
wheel odometry and ground truth at 10 Hz. The map is the world's ground truth at 0.05 m
(what ``maps/<world>.yaml`` holds).

Every scan goes through :class:`pppbot_nav.amcl.localizer.Localizer` as the ``amcl`` node
drives it, with the node's default parameters (``config/nav2_params.yaml``: Nav2's values):
the beams for the particles and the full scan for the refinement are built from the ranges,
then ``update()``, and ``track()`` when the filter did not update. Two runs:

* **timing**: ``min_particles = max_particles = 2000`` (the target's particle count), started at
  the true pose; per filter update the wall time of the whole scan's handling (ms: median,
  p95, max) — target p95 ≤ 20 ms; per scan without an update the tracking time;
* **defaults**: Nav2's 500–2000 particles, started 0.5 m and 0.3 rad off; the error of the
  estimate (map → odom composed with odometry at each scan) against the truth once converged
  (within 0.1 m and 0.05 rad), and the particle count.

    ./pppbot env python benchmarks/amcl_speed.py [--world maze] [--seed 0]

Prints one JSON object on its last line.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from slam_dataset import SlamDataset, ensure_dataset, load_dataset  # noqa: E402

from pppbot_common.se2 import se2_compose, wrap_angle  # noqa: E402
from pppbot_eval.scenarios import world_truth  # noqa: E402
from pppbot_nav.amcl.filter import FilterSettings  # noqa: E402
from pppbot_nav.amcl.laser import laser_scans  # noqa: E402
from pppbot_nav.amcl.localizer import Localizer  # noqa: E402
from pppbot_nav.ros.amcl import INITIAL_COVARIANCE, AmclParameters  # noqa: E402
from pppbot_sim.worlds import find_world  # noqa: E402


def run(data: SlamDataset, localizer: Localizer, start: np.ndarray) -> dict[str, Any]:
    localizer.set_initial_pose(start, INITIAL_COVARIANCE)
    laser = localizer.settings.laser
    sensor = tuple(float(v) for v in data.sensor_offset)
    update_ms, track_ms, errors, particles = [], [], [], []
    for odom, truth, ranges in zip(data.odom, data.truth, data.ranges, strict=True):
        t0 = time.perf_counter()
        scan, full = laser_scans(ranges, data.angle_min, data.angle_increment, data.range_min, data.range_max,
                                 sensor, laser)
        update = localizer.update(odom, scan, full)
        if update is None and full is not None:
            localizer.track(odom, full)
        elapsed_ms = 1000.0 * (time.perf_counter() - t0)
        (update_ms if update is not None else track_ms).append(elapsed_ms)
        if update is not None:
            particles.append(len(localizer.filter))
        if localizer.last is not None:
            pose = se2_compose(localizer.last.map_to_odom, odom)
            errors.append((math.hypot(*(pose[:2] - truth[:2])), abs(wrap_angle(float(pose[2] - truth[2])))))
    return {"update_ms": np.array(update_ms), "track_ms": np.array(track_ms), "errors": np.array(errors),
            "particles": np.array(particles)}


def stats(values: np.ndarray) -> dict[str, float]:
    return {"median": round(float(np.median(values)), 3), "p95": round(float(np.percentile(values, 95)), 3),
            "max": round(float(values.max()), 3)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument("--world", default="maze")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    data = load_dataset(ensure_dataset(args.world, seed=args.seed))
    grid = world_truth(find_world(args.world))
    params = AmclParameters()
    rng = np.random.default_rng(args.seed)

    fixed = params.settings()
    fixed = type(fixed)(**{**fixed.__dict__, "filter": FilterSettings(2000, 2000, params.pf_err, params.pf_z)})
    timing = run(data, Localizer(fixed, grid, rng), data.truth[0])

    defaults = run(data, Localizer(params.settings(), grid, rng), data.truth[0] + np.array([0.35, 0.35, 0.3]))
    err = defaults["errors"]
    good = (err[:, 0] <= 0.1) & (err[:, 1] <= 0.05)
    first = int(np.argmax(good)) if good.any() else len(err)
    steady = err[first:]
    result = {
        "benchmark": "amcl_speed", "world": args.world, "scans": len(data.stamps), "beams": int(data.ranges.shape[1]),
        "timing_particles": 2000, "updates": len(timing["update_ms"]),
        **{f"update_{k}_ms": v for k, v in stats(timing["update_ms"]).items()},
        **{f"track_{k}_ms": v for k, v in stats(timing["track_ms"]).items()},
        "target_update_p95_ms": 20.0,
        "defaults_converged_after_scans": first,
        "defaults_rms_m": round(float(np.sqrt(np.mean(steady[:, 0] ** 2))), 4) if len(steady) else None,
        "defaults_yaw_rms_rad": round(float(np.sqrt(np.mean(steady[:, 1] ** 2))), 5) if len(steady) else None,
        "defaults_max_m": round(float(steady[:, 0].max()), 4) if len(steady) else None,
        "defaults_particles_median": int(np.median(defaults["particles"])),
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
