"""SLAM accuracy on a world's drive, offline: the mapper core over a ``slam_dataset.py`` drive, no ROS.

Every scan of the drive (``benchmarks/slam_dataset.py``: the route driven in the
simulation core, wheel slip and sensor noise seeded) goes through
:class:`pppbot_slam.mapper.Mapper` with the settings the ``slam`` node builds from its
defaults, loop closing right after each keyframe. After each scan the SLAM pose, the
latest keyframe's map pose composed with the odometry since (what ``map → base_footprint``
says at that moment), is compared with the truth; the map frame is the odom frame at the
first keyframe, as the node's is. Reported: that *online* error (RMS, max, and at twenty
evenly spaced moments of the drive), the error of the final optimised keyframe poses, and
the loop closures. The same drive and settings give the same figures on any machine; a
run takes a minute or a few, where ``eval slam`` takes ten.

``--matcher NAME=VALUE`` overrides a :class:`pppbot_slam.matcher.MatcherSettings` field
of the running matcher (say ``refine_smear_m=0.1`` to refine in the search's own field),
``--mapper NAME=VALUE`` a number of :class:`pppbot_slam.mapper.MapperSettings` (say
``loop_search_global_distance=0`` for no global loop search).

    ./pppbot env python benchmarks/slam_replay.py --world maze [--seed 0] [--wheel-slip 0.01] \
        [--matcher NAME=VALUE ...] [--mapper NAME=VALUE ...]
    ./pppbot env python benchmarks/slam_replay.py --world out/looped_maze_001.sdf   # a generated world (worldgen.py)
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from slam_dataset import SlamDataset, ensure_dataset, load_dataset  # noqa: E402

#: Moments of the drive the online error is also given at.
TIMELINE_POINTS = 20


def field_overrides(items: list[str], settings_class: type, flag: str) -> dict[str, float]:
    """``NAME=VALUE`` pairs as number fields of a settings dataclass (``--matcher``, ``--mapper``).

    Raises:
        ValueError: not NAME=VALUE, an unknown field, or a value that is not a number.
    """
    fields = [f for f in dataclasses.fields(settings_class) if f.type in (int, "int", float, "float")]
    names = {f.name for f in fields}
    counts = {f.name for f in fields if f.type in (int, "int")}
    out: dict[str, float] = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or name not in names:
            raise ValueError(f"{flag} {item!r}: give NAME=VALUE with NAME one of {', '.join(sorted(names))}")
        try:
            out[name] = int(value) if name in counts else float(value)
        except ValueError:
            raise ValueError(f"{flag} {item!r}: {value!r} is not a number") from None
    return out


def matcher_overrides(items: list[str]) -> dict[str, float]:
    """``NAME=VALUE`` pairs as MatcherSettings fields (see :func:`field_overrides`)."""
    from pppbot_slam.matcher import MatcherSettings

    return field_overrides(items, MatcherSettings, "--matcher")


def mapper_overrides(items: list[str]) -> dict[str, float]:
    """``NAME=VALUE`` pairs as MapperSettings number fields (see :func:`field_overrides`)."""
    from pppbot_slam.mapper import MapperSettings

    return field_overrides(items, MapperSettings, "--mapper")


def replay(ds: SlamDataset, matcher: dict[str, float], mapper_fields: dict[str, float] | None = None) -> dict[str, Any]:
    from pppbot_eval.closures import closure_errors, closure_figures
    from pppbot_slam.mapper import Mapper
    from pppbot_slam.ros.slam import SlamParameters

    settings = SlamParameters().mapper_settings()
    if matcher:
        settings = dataclasses.replace(settings, matcher=dataclasses.replace(settings.matcher, **matcher))
    settings = dataclasses.replace(settings, **(mapper_fields or {}))
    mapper = Mapper(settings, defer_loops=True)
    mapper.sensor_offset = np.asarray(ds.sensor_offset, dtype=float).copy()
    started = time.perf_counter()
    keyframe_scans: list[int] = []
    online: list[np.ndarray] = []
    for i, stamp in enumerate(ds.stamps):
        keyframe = mapper.process(float(stamp), ds.odom[i], ds.scan_rays(i))
        if keyframe is not None:
            keyframe_scans.append(i)
            if settings.do_loop_closing:
                mapper.close_loops(keyframe.index)
        if keyframe_scans:
            online.append(np.asarray(mapper.predict(ds.odom[i]), dtype=float))
    wall_s = max(time.perf_counter() - started, 1e-9)
    duration_s = float(ds.stamps[-1] - ds.stamps[0])
    first = keyframe_scans[0]
    truth = ds.truth_in_map(first)[first:]
    errors = np.linalg.norm(np.array(online)[:, :2] - truth[:, :2], axis=1)
    final = np.array([mapper.map_pose(k) for k in range(len(keyframe_scans))])
    closures = closure_figures(closure_errors(final, truth[np.array(keyframe_scans) - first],
                                              [e for e in mapper.graph.edges if e.loop]))
    final_errors = np.linalg.norm(final[:, :2] - truth[np.array(keyframe_scans) - first, :2], axis=1)
    moments = np.linspace(0, len(errors) - 1, TIMELINE_POINTS).round().astype(int)
    return {"online_rms_cm": round(float(np.sqrt(np.mean(errors ** 2))) * 100, 2),
            "online_max_cm": round(float(errors.max()) * 100, 2),
            "online_timeline_cm": [round(float(errors[k]) * 100, 1) for k in moments],
            "final_keyframes_rms_cm": round(float(np.sqrt(np.mean(final_errors ** 2))) * 100, 2),
            "keyframes": len(keyframe_scans), "loop_closures": len(mapper.loop_closures),
            "rejected_closures": mapper.rejected_closures, "rejected_why": mapper.rejected_why,
            "false_closures": closures["false_closures"],
            "false_claims": closures["false_claims"], "closure_max_error_m": closures["closure_max_error_m"],
            "wall_s": round(wall_s, 1), "duration_s": round(duration_s, 1), "scans": len(ds.stamps),
            "scans_per_s": round(len(ds.stamps) / wall_s, 1), "real_time_factor": round(duration_s / wall_s, 1)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--world", default="maze", help="a shipped world's name or a world file")
    parser.add_argument("--route", default=None)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--wheel-slip", type=float, default=0.01)
    parser.add_argument("--matcher", nargs="*", default=[], metavar="NAME=VALUE")
    parser.add_argument("--mapper", nargs="*", default=[], metavar="NAME=VALUE",
                        help="a MapperSettings number, e.g. loop_search_global_distance=0")
    args = parser.parse_args(argv)
    try:
        overrides = matcher_overrides(args.matcher)
        mapper_fields = mapper_overrides(args.mapper)
    except ValueError as exc:
        parser.error(str(exc))
    ds = load_dataset(ensure_dataset(args.world, args.route, args.seed, args.wheel_slip))
    result = {"benchmark": "slam_replay", "world": ds.world, "route": ds.route, "seed": ds.seed,
              "wheel_slip": ds.wheel_slip, "matcher": overrides, "mapper": mapper_fields,
              **replay(ds, overrides, mapper_fields)}
    print(f"{ds.world}: SLAM pose error RMS {result['online_rms_cm']} cm, max {result['online_max_cm']} cm; "
          f"final keyframes {result['final_keyframes_rms_cm']} cm; {result['loop_closures']} loop closures "
          f"({result['rejected_closures']} rejected, {result['false_closures']} false); {result['scans']} scans "
          f"at {result['scans_per_s']} scans/s, {result['real_time_factor']}x real time")
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
