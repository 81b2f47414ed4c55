"""Localization accuracy on a world's drive, offline: map one seed's drive, localize another's in it.

The first drive (``--map-seed``) is mapped as ``slam_replay.py`` maps it and the pose graph serialized
and loaded back; the second (``--seed``: other wheel slip and sensor noise on the same route) is
localized in it with :class:`pppbot_slam.localizer.Localizer` and the slam node's default settings,
starting ``--start-error`` off the truth. After each scan the localized pose (map → odom composed with
odometry) is compared with the truth in the map frame, and each taken scan also with the map
itself: its error less the mean error of the three keyframes nearest to it (the map's own distortion
there), what localization adds to the map's error.

    ./pppbot env python benchmarks/localization_replay.py --world maze [--map-seed 0] [--seed 1]
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from slam_dataset import ensure_dataset, load_dataset  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    from pppbot_common.se2 import se2_compose, se2_inverse, wrap_angles
    from pppbot_slam.localizer import Localizer
    from pppbot_slam.mapper import Mapper
    from pppbot_slam.ros.slam import SlamParameters
    from pppbot_slam.serialization import load_posegraph, save_posegraph

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--world", default="maze")
    parser.add_argument("--route", default=None)
    parser.add_argument("--map-seed", type=int, default=0)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--wheel-slip", type=float, default=0.01)
    parser.add_argument("--start-error", type=float, nargs=3, default=[0.1, -0.1, 0.05], metavar=("X", "Y", "YAW"))
    args = parser.parse_args(argv)
    mapped = load_dataset(ensure_dataset(args.world, args.route, args.map_seed, args.wheel_slip))
    drive = load_dataset(ensure_dataset(args.world, args.route, args.seed, args.wheel_slip))
    settings = SlamParameters().mapper_settings()
    mapper = Mapper(settings, defer_loops=True)
    mapper.sensor_offset = np.asarray(mapped.sensor_offset, dtype=float).copy()
    first = None
    keyframe_scans = []
    for i, stamp in enumerate(mapped.stamps):
        keyframe = mapper.process(float(stamp), mapped.odom[i], mapped.scan_rays(i))
        if keyframe is not None:
            first = i if first is None else first
            keyframe_scans.append(i)
            mapper.close_loops(keyframe.index)
    assert first is not None
    world_to_map = np.asarray(se2_compose(mapped.odom[first], se2_inverse(mapped.truth[first])))
    with tempfile.TemporaryDirectory() as tmp:
        graph = load_posegraph(save_posegraph(mapper, Path(tmp) / "graph"), settings)
    truth = np.asarray(se2_compose(world_to_map, drive.truth))
    kf_truth = np.asarray(se2_compose(world_to_map, mapped.truth[np.array(keyframe_scans)]))
    kf_pose = np.array([graph.map_pose(k) for k in range(len(keyframe_scans))])
    kf_err = kf_pose[:, :2] - kf_truth[:, :2]
    map_rms = float(np.sqrt(np.mean(np.sum(kf_err ** 2, axis=1))))
    rel = []
    localizer = Localizer(graph, truth[0] + np.array(args.start_error))
    started = time.perf_counter()
    online, taken, matched, taken_errors = [], 0, 0, []
    for i, stamp in enumerate(drive.stamps):
        localized = localizer.process(float(stamp), drive.odom[i], drive.scan_rays(i), drive.sensor_offset)
        if localized is not None:
            taken += 1
            matched += localized.matched
            e = localized.pose - truth[i]
            taken_errors.append((float(np.hypot(e[0], e[1])), abs(float(wrap_angles(e[2])))))
            near = np.argsort(np.hypot(*(kf_truth[:, :2] - truth[i, :2]).T))[:3]
            local = kf_err[near].mean(axis=0)
            rel.append(float(np.hypot(*(e[:2] - local))))
        pose = localizer.predict(drive.odom[i])
        e = pose - truth[i]
        online.append((float(np.hypot(e[0], e[1])), abs(float(wrap_angles(e[2])))))
    wall = time.perf_counter() - started
    online_arr, taken_arr = np.array(online), np.array(taken_errors)
    result = {"benchmark": "localization_replay", "world": drive.world, "route": drive.route,
              "map_seed": args.map_seed, "seed": args.seed, "keyframes": len(graph.keyframes),
              "scans": len(drive.stamps), "taken": taken, "matched": matched,
              "online_rms_cm": round(float(np.sqrt(np.mean(online_arr[:, 0] ** 2))) * 100, 2),
              "online_max_cm": round(float(online_arr[:, 0].max()) * 100, 2),
              "online_yaw_rms_deg": round(float(np.degrees(np.sqrt(np.mean(online_arr[:, 1] ** 2)))), 3),
              "online_yaw_max_deg": round(float(np.degrees(online_arr[:, 1].max())), 3),
              "taken_rms_cm": round(float(np.sqrt(np.mean(taken_arr[:, 0] ** 2))) * 100, 2),
              "taken_max_cm": round(float(taken_arr[:, 0].max()) * 100, 2),
              "map_keyframes_rms_cm": round(map_rms * 100, 2),
              "taken_vs_local_map_rms_cm": round(float(np.sqrt(np.mean(np.square(rel)))) * 100, 2),
              "taken_vs_local_map_max_cm": round(float(np.max(rel)) * 100, 2),
              "ms_per_taken_scan": round(wall / max(taken, 1) * 1000, 1),
              "drive_s": round(float(drive.stamps[-1] - drive.stamps[0]), 1), "wall_s": round(wall, 1)}
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
