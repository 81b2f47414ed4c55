"""The report of a scenario run (:class:`pppbot_eval.ros.cli.Run`): its metrics against ground
truth, whether it succeeded and why not, as ``report.json`` holds it."""
from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from pppbot_common.errors import PppbotError
from pppbot_common.maps import OccupancyGrid, save_map
from pppbot_eval.closures import closure_errors, closure_figures
from pppbot_eval.scenarios import (
    BARN_ARRIVAL_M,
    CONVERGED_M,
    CONVERGED_RAD,
    CONVERGED_TRAVEL_M,
    GOAL_XY_TOLERANCE_M,
    Scenario,
    map_metrics,
    navigation_metrics,
    route_metrics,
    save_recording,
    world_truth,
)
from pppbot_eval.trajectory import PoseSeries
from pppbot_slam.serialization import load_posegraph

if TYPE_CHECKING:
    from pppbot_eval.ros.cli import Run

#: The live view's rerun recording in ``--out`` (``--view``).
VIEW_FILE = "view.rrd"


def slam_health(values: dict[str, str]) -> dict[str, Any]:
    """The slam node's last /diagnostics values, as numbers and booleans where they are."""
    def parse(text: str) -> Any:
        if text in ("true", "false"):
            return text == "true"
        try:
            return int(text)
        except ValueError:
            try:
                return float(text)
            except ValueError:
                return text
    return {key: parse(value) for key, value in values.items()}


def posegraph_closures(posegraph: str, truth_rows: Iterable[Sequence[float]]) -> dict[str, Any]:
    """The saved pose graph's loop closures against ground truth (:mod:`pppbot_eval.closures`): each
    keyframe's true pose at its scan's stamp, beside its solved one."""
    mapper = load_posegraph(posegraph)
    truth = PoseSeries.from_rows(truth_rows)
    span = truth.span_s()
    assert span is not None  # the caller has truth rows
    stamps = np.clip([k.stamp_s for k in mapper.keyframes], *span)
    solved = np.array([mapper.map_pose(k.index) for k in mapper.keyframes]).reshape(-1, 3)
    loops = [e for e in mapper.graph.edges if e.loop]
    return closure_figures(closure_errors(solved, truth.interpolate(stamps).poses.reshape(-1, 3), loops))


def report(run: Run, truth_map: OccupancyGrid) -> dict[str, Any]:
    if run.route is None:
        return navigation_report(run, truth_map)
    rec = run.recording
    title = f"{run.scenario.value} in {run.world_file.stem}, route {run.route.name}"
    save_recording(run.out / "recording.npz", rec)
    metrics: dict[str, Any] = {}
    problem = None
    if rec.truth_rows:
        try:
            localizing = run.scenario is Scenario.LOCALIZATION
            map_pose = run.config.map_pose if localizing else None
            metrics, problem = route_metrics(run.scenario, rec, run.route, truth_map, run.out, title, map_pose,
                                             run.scored.amcl_transform_tolerance if localizing else 0.0)
            if run.scenario is Scenario.SLAM and rec.final_map is not None:
                # The map as map_saver would save it: the localization and navigation scenarios take it.
                metrics["map"] = str(save_map(rec.final_map, run.out / "map.yaml"))
                map_truth = world_truth(run.world_file, run.route, rec.final_map.resolution)
                metrics.update(map_metrics(rec.final_map, map_truth, run.route.start, run.out, title + " — map"))
                metrics["slam_health"] = slam_health(rec.slam_health)
                if rec.posegraph:
                    metrics["posegraph"] = rec.posegraph
                    metrics.update(posegraph_closures(rec.posegraph, rec.truth_rows))
        except (PppbotError, ValueError, OSError) as exc:
            problem = f"metrics: {exc}"
    failure = rec.failure
    if failure is None and not rec.route_finished:
        failure = "route not finished"
    if failure is None and metrics.get("collisions", 0):
        failure = f"{metrics['collisions']} collision(s)"
    if failure is None and metrics.get("converged") is False:
        failure = (f"AMCL never converged (error within {CONVERGED_M} m and {CONVERGED_RAD} rad for "
                   f"{CONVERGED_TRAVEL_M} m of travel)")
    return _result(run, failure or problem, {"start": list(run.start), "speed_mps": run.config.speed, **metrics})


def navigation_report(run: Run, truth_map: OccupancyGrid) -> dict[str, Any]:
    """The navigation scenario's report: ok when every goal was sent, the success rate is at least
    ``--min-success-rate`` and nothing was touched."""
    rec = run.recording
    save_recording(run.out / "recording.npz", rec)
    metrics: dict[str, Any] = {}
    problem = None
    if rec.truth_rows and rec.goals:
        try:
            what = "without a map" if run.map_free else f"{len(run.goals)} goals (seed {run.config.seed})"
            metrics = navigation_metrics(rec, truth_map, run.frame_in_world, run.max_speed_mps, run.out,
                                         f"navigation in {run.world_file.stem}, {what}", map_free=run.map_free)
        except (PppbotError, ValueError, OSError) as exc:
            problem = f"metrics: {exc}"
    failure = rec.failure
    if failure is None and len(rec.goals) < len(run.goals):
        failure = f"only {len(rec.goals)} of {len(run.goals)} goals were sent"
    if failure is None and metrics.get("collisions", 0):
        failure = f"{metrics['collisions']} collision(s)"
    rate = metrics.get("success_rate")
    if failure is None and rate is not None and rate < run.config.min_success_rate:
        rule = (f"the robot comes within {BARN_ARRIVAL_M:g} m of it in time without a collision" if run.map_free
                else f"the navigator succeeds and the true pose is within {GOAL_XY_TOLERANCE_M:g} m of it")
        failure = f"success rate {rate:.3f} < {run.config.min_success_rate} (a goal counts when {rule})"
    where = {"map_free": True, "goal": list(run.goals[0])} if run.map_free else {"map_pose": list(run.config.map_pose)}
    return _result(run, failure or problem, {"start": list(run.start), **where, **metrics})


def _result(run: Run, failure: str | None, metrics: dict[str, Any]) -> dict[str, Any]:
    rec = run.recording
    drive_wall = rec.drive_wall_seconds
    return {
        "scenario": run.scenario.value,
        "world": run.world_file.stem,
        "ok": failure is None,
        "failure": failure,
        "sim_seconds": round(rec.sim_seconds, 3),
        "wall_seconds": round(rec.wall_seconds, 3),
        "real_time_factor": round(rec.sim_seconds / drive_wall, 3) if drive_wall > 0 else None,
        "target_real_time_factor": run.config.real_time_factor,
        "lockstep": run.config.lockstep,
        "seed": run.config.seed,
        "wheel_slip": run.config.wheel_slip,
        "params_file": str(run.config.params_file) if run.config.params_file else None,
        **metrics,
        "out": str(run.out),
        "plots": sorted(p.name for p in run.out.glob("*.png")),
        "view": VIEW_FILE if (run.out / VIEW_FILE).is_file() else None,
    }
