"""Evaluation scenarios: what each one measures, from what a run recorded (no ROS here).

A run records the simulator's ground truth, the estimate under test (a pose
stream from TF), collisions and the route's progress into a :class:`Recording`;
a scenario turns that into the report's metrics and plots.

* ``map``: no run; a saved map (Nav2 YAML) scored against the world's ground truth.
* ``drive``: drive a route with wheel slip; the estimate is wheel odometry
  (``odom → base_link``), whose frame is the spawn pose: how far dead reckoning drifts.
* ``slam``: the same with the SLAM node; the estimate is ``map → odom → base_link``
  from TF, and the last ``/map`` is scored against the ground truth.
* ``localization``: map_server and AMCL on a saved map, started from a wrong initial
  pose (or globally); the estimate is ``map → odom → base_link``, scored once it has
  converged (``amcl_*``), with the travel it took to converge.
* ``navigation``: map_server, AMCL and the navigation nodes on a saved map; random
  reachable goals, one after another, through ``navigate_to_pose``; each goal's
  outcome is judged on ground truth (:func:`navigation_metrics`).
"""
from __future__ import annotations

import enum
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pppbot_common.maps import OccupancyGrid, load_map
from pppbot_eval.errors import PathError, PoseSeriesError
from pppbot_eval.map_quality import compare_maps
from pppbot_eval.navigation import (
    PPP_BOT_FOOTPRINT,
    GoalOutcome,
    barn_score,
    clearance_along,
    goal_reached,
    pose_error,
    summarize_navigation,
)
from pppbot_eval.report import plot_errors, plot_map_overlay, plot_trajectories
from pppbot_eval.routes import Route
from pppbot_eval.shortest_path import shortest_path
from pppbot_eval.trajectory import (
    AteResult,
    PoseRows,
    PoseSeries,
    absolute_trajectory_error,
    compose_chain,
    relative_pose_error,
)
from pppbot_sim.ground_truth import Bounds, ground_truth_map
from pppbot_sim.simulation import load_world
from pppbot_sim.worlds import model_paths

GROUND_TRUTH_RESOLUTION_M = 0.05
LIDAR_HEIGHT_M = 0.2  # where ppp_bot's lidar cuts the world
EMPTY_MARGIN_M = 3.0


class Scenario(enum.Enum):
    MAP = "map"
    DRIVE = "drive"
    SLAM = "slam"
    LOCALIZATION = "localization"
    NAVIGATION = "navigation"


#: Localization has converged once its error stays within these for CONVERGED_TRAVEL_M of travel.
CONVERGED_M = 0.1
CONVERGED_RAD = 0.05
CONVERGED_TRAVEL_M = 1.0

#: A navigation goal counts as reached when the navigator says so and the true pose is within the
#: goal checker's tolerances (0.25 m, 0.25 rad: config/nav2_params.yaml) widened by what
#: localization may be off by (the navigator judges on AMCL's estimate): CONVERGED_M, CONVERGED_RAD.
GOAL_XY_TOLERANCE_M = 0.25 + CONVERGED_M
GOAL_YAW_TOLERANCE_RAD = 0.25 + CONVERGED_RAD
#: A map-less navigation goal counts as reached within this of it (m), as BARN judges its runs.
BARN_ARRIVAL_M = 1.0

@dataclass(frozen=True)
class Estimate:
    """Where the pose under test comes from: an Odometry ``topic``, or else the TF chain ``frames``
    (e.g. map, odom, base_link), whose edges are recorded from /tf and composed afterwards."""

    frames: tuple[str, ...]
    topic: str | None = None

    def edges(self) -> list[tuple[str, str]]:
        return list(zip(self.frames[:-1], self.frames[1:], strict=True))


#: The estimate each scenario measures. Wheel odometry is read from /odom, which carries
#: the same pose as the odom → base_link transform: /tf also carries every wheel
#: transform at the joint-state rate, which is a lot to listen to at 10× real time.
ESTIMATES = {Scenario.DRIVE: Estimate(("odom", "base_link"), topic="/odom"),
             Scenario.SLAM: Estimate(("map", "odom", "base_link")),
             Scenario.LOCALIZATION: Estimate(("map", "odom", "base_link")),
             Scenario.NAVIGATION: Estimate(("map", "odom", "base_link"))}
#: Navigation without a map has only odometry to go by.
MAP_FREE_ESTIMATE = ESTIMATES[Scenario.DRIVE]
#: How each scenario's estimate is labelled in plots.
ESTIMATE_LABELS = {Scenario.DRIVE: "wheel odometry", Scenario.SLAM: "SLAM (map → base_link)",
                   Scenario.LOCALIZATION: "AMCL (map → base_link)",
                   Scenario.NAVIGATION: "AMCL (map → base_link)"}


class GoalAnswer(str, enum.Enum):
    """How a goal ended as the run saw it; the value is the report's ``status``."""

    SUCCEEDED = "succeeded"
    ABORTED = "aborted"
    CANCELED = "canceled"
    REJECTED = "rejected"
    UNANSWERED = "unanswered"  # the server never said whether it took the goal
    TIMEOUT = "timeout"  # the run gave up and canceled it
    UNKNOWN = "unknown"  # an action status the run does not know (error_msg has it)


@dataclass(frozen=True)
class GoalRecord:
    """One goal as the run saw it: the goal in the world frame, sim times of sending it and of
    its result, what the navigator answered (``status``), and the shortest path's length from
    where the robot was when the goal was sent (:func:`shortest_path_m`)."""

    goal: tuple[float, float, float]
    start_s: float
    end_s: float
    status: GoalAnswer
    error_code: int = 0
    error_msg: str = ""
    recoveries: int = 0
    shortest_path_m: float | None = None
    limit_s: float | None = None  # how long it was given (sim s); None: not known


@dataclass
class Recording:
    """What a run saw; times are sim seconds."""

    truth_rows: PoseRows | list[tuple[float, float, float, float]] = field(default_factory=PoseRows)
    estimate_rows: PoseRows | list[tuple[float, float, float, float]] = field(default_factory=PoseRows)  # a topic's
    edge_rows: dict[tuple[str, str], PoseRows | list[tuple[float, float, float, float]]] = field(
        default_factory=dict)  # /tf
    collisions: list[tuple[float, float, float]] = field(default_factory=list)  # t, x, y
    route_progress: float = 0.0
    route_finished: bool = False
    start_sim_s: float = 0.0
    end_sim_s: float = 0.0
    wall_seconds: float = 0.0
    drive_wall_seconds: float = 0.0  # wall time of the scenario itself (without start and stop)
    failure: str | None = None
    not_upright: str | None = None  # when the robot tipped over or sank into the ground: what and when
    final_map: OccupancyGrid | None = None  # the last /map, for scenarios that map
    final_map_stamp_s: float = -1.0
    slam_health: dict[str, str] = field(default_factory=dict)  # the last /diagnostics of the slam node
    posegraph: str = ""  # the pose graph the slam node serialized at the end, if it did
    goals: list[GoalRecord] = field(default_factory=list)  # navigation

    @property
    def sim_seconds(self) -> float:
        return max(0.0, self.end_sim_s - self.start_sim_s)


def map_metrics(estimate: OccupancyGrid, truth: OccupancyGrid, map_to_world: tuple[float, float, float],
                out: Path, title: str) -> dict[str, Any]:
    """A map against the ground truth (its frame placed at ``map_to_world``); writes ``map.png``.

    The reference free space is what is reachable from the map frame's origin (the spawn
    point, where mapping started).

    Raises:
        MapQualityError: the origin is not in free space, or the truth has no walls there.
    """
    quality = compare_maps(estimate, truth, map_to_world, reachable_from=map_to_world[:2])
    plot_map_overlay(out / "map.png", truth, quality.true_walls, quality.matched_walls, quality.false_walls, title)
    return {**quality.as_dict(), "map_resolution_m": estimate.resolution}


def save_recording(path: Path, recording: Recording) -> None:
    """The raw streams as numpy arrays (t, x, y, yaw rows): ``truth``, ``estimate``, ``collisions``
    (t, x, y), navigation ``goals`` (sent and ended at, x, y, yaw) and one ``tf_<parent>__<child>``
    per recorded TF edge, to re-plot or re-score later."""
    arrays = {"truth": np.array(recording.truth_rows).reshape(-1, 4),
              "estimate": np.array(recording.estimate_rows).reshape(-1, 4),
              "collisions": np.array(recording.collisions).reshape(-1, 3),
              "goals": np.array([(r.start_s, r.end_s, *r.goal) for r in recording.goals]).reshape(-1, 5)}
    for (parent, child), rows in recording.edge_rows.items():
        arrays[f"tf_{parent}__{child}"] = np.array(rows).reshape(-1, 4)
    np.savez_compressed(path, **arrays)  # type: ignore[arg-type]


def estimate_series(recording: Recording, estimate: Estimate, outer_ahead_s: float = 0.0) -> PoseSeries:
    """The estimated pose stream: the topic's poses, or the TF chain composed at the innermost edge's stamps.
    ``outer_ahead_s``: the outer edges are stamped this far ahead of the data they were computed
    from (AMCL's ``transform_tolerance``), and are taken back to that time.

    Raises:
        PoseSeriesError: an edge of the chain was never received.
    """
    if estimate.topic is not None:
        return PoseSeries.from_rows(recording.estimate_rows)
    edges = [PoseSeries.from_rows(recording.edge_rows.get(edge, [])) for edge in estimate.edges()]
    if outer_ahead_s:
        edges[:-1] = [PoseSeries(e.t_s - outer_ahead_s, e.xy, e.yaw_rad) for e in edges[:-1]]
    series = edges[-1]
    for outer in reversed(edges[:-1]):
        series = compose_chain(outer, series)
    return series


def localization_metrics(ate: AteResult, truth: PoseSeries) -> dict[str, Any]:
    """AMCL's figures: the travel until the error stays within :data:`CONVERGED_M` and
    :data:`CONVERGED_RAD` for :data:`CONVERGED_TRAVEL_M`, and the error from then on
    (``amcl_rms_m``, ``amcl_yaw_rms_rad``, ``amcl_max_m``); ``converged`` false when it never did."""
    travel = np.interp(ate.t_s, truth.t_s, truth.cumulative_length_m())
    travel = travel - travel[0]
    good = (ate.position_error_m <= CONVERGED_M) & (np.abs(ate.yaw_error_rad) <= CONVERGED_RAD)
    # The first sample from which every sample within CONVERGED_TRAVEL_M of travel is good.
    bad_travel = np.where(good, np.inf, travel)
    next_bad = np.minimum.accumulate(bad_travel[::-1])[::-1]
    stays = good & (next_bad - travel >= CONVERGED_TRAVEL_M)
    # ... and that much travel is left to show it (the whole run, for a run shorter than that).
    stays &= travel[-1] - travel >= min(CONVERGED_TRAVEL_M, travel[-1])
    metrics: dict[str, Any] = {"initial_position_error_m": float(ate.position_error_m[0]),
                               "initial_yaw_error_rad": float(abs(ate.yaw_error_rad[0]))}
    if not stays.any():
        return {**metrics, "converged": False, "converged_after_m": None}
    first = int(np.argmax(stays))
    steady = slice(first, None)
    return {**metrics, "converged": True, "converged_after_m": round(float(travel[first]), 3),
            "amcl_rms_m": float(np.sqrt(np.mean(ate.position_error_m[steady] ** 2))),
            "amcl_yaw_rms_rad": float(np.sqrt(np.mean(ate.yaw_error_rad[steady] ** 2))),
            "amcl_max_m": float(ate.position_error_m[steady].max()),
            "amcl_yaw_max_rad": float(np.abs(ate.yaw_error_rad[steady]).max())}


def route_metrics(scenario: Scenario, recording: Recording, route: Route, truth_map: OccupancyGrid, out: Path,
                  title: str, map_to_world: tuple[float, float, float] | None = None,
                  estimate_ahead_s: float = 0.0) -> tuple[dict[str, Any], str | None]:
    """The estimate's error along the route (ATE, RPE, final error), clearance and collisions;
    writes the trajectory and error plots. For ``drive`` the estimate is wheel odometry,
    for ``slam`` the map → base_link chain (the map frame is the spawn pose unless
    ``map_to_world`` says where it is), for ``localization`` the same with AMCL's figures,
    taken at the scans' times (``estimate_ahead_s``: how far ahead map → odom is stamped).

    Returns the metrics and what kept some of them from being measured (None: nothing).

    Raises:
        PoseSeriesError: the recorded streams do not overlap in time.
    """
    truth = PoseSeries.from_rows(recording.truth_rows)
    estimate = estimate_series(recording, ESTIMATES[scenario])
    metrics: dict[str, Any] = {
        "route": route.name,
        "route_length_m": round(route.length_m, 3),
        "route_completed": recording.route_finished,
        "route_progress": round(recording.route_progress, 4),
        "distance_m": round(truth.path_length_m(), 3) if len(truth) else 0.0,
        "collisions": len(recording.collisions),
    }
    if len(truth):
        clearance = clearance_along(truth, truth_map, PPP_BOT_FOOTPRINT)
        metrics["min_clearance_m"] = round(float(clearance.min()), 3)
    if len(truth) < 2 or len(estimate) < 2:
        return metrics, f"too little data: {len(truth)} true poses, {len(estimate)} estimated poses"
    frame = route.start if map_to_world is None else map_to_world
    ate = absolute_trajectory_error(estimate, truth, frame)
    rpe = relative_pose_error(estimate, truth, frame)
    metrics.update(ate.as_dict("ate"))
    metrics.update(rpe.as_dict("rpe"))
    metrics["final_position_error_m"] = float(ate.position_error_m[-1])
    metrics["final_yaw_error_rad"] = float(ate.yaw_error_rad[-1])
    if scenario is Scenario.LOCALIZATION:
        # AMCL's own estimate: map → odom at the scan it was computed from, not at the stamp
        # transform_tolerance ahead that TF users interpolate (which the ate_* keys measure).
        at_scan = estimate_series(recording, ESTIMATES[scenario], estimate_ahead_s)
        metrics.update(localization_metrics(absolute_trajectory_error(at_scan, truth, frame), truth))
    label = ESTIMATE_LABELS[scenario]
    plot_trajectories(out / "trajectory.png", truth_map, truth, estimate.transformed(frame),
                      label, [(x, y) for _, x, y in recording.collisions], title)
    plot_errors(out / "error.png", ate, f"{title} — {label} error")
    return metrics, None


#: The shortest path a goal is compared with is that of a disc around the footprint (its
#: circumscribed radius, 0.25 m for ppp_bot): the robot fits wherever that disc does.
FOOTPRINT_RADIUS_M = float(np.linalg.norm(PPP_BOT_FOOTPRINT.vertices_xy, axis=1).max())


def shortest_path_m(truth_map: OccupancyGrid, start_xy: Sequence[float], goal_xy: Sequence[float]) -> float | None:
    """The shortest path's length (m) for the footprint's disc (:data:`FOOTPRINT_RADIUS_M`), None when none."""
    try:
        return shortest_path(truth_map, start_xy, goal_xy, FOOTPRINT_RADIUS_M).length_m
    except PathError:
        return None


#: Turning in place, as the truth shows it: slower than this (m/s) while turning faster than TURNING_RADPS.
STANDING_MPS = 0.02
TURNING_RADPS = 0.05


def turning_in_place_s(driven: PoseSeries) -> float:
    """Sim seconds of ``driven`` spent turning on the spot (speed below :data:`STANDING_MPS`, turn
    rate above :data:`TURNING_RADPS`): what a goal costs beyond its path at the base's angular
    acceleration, which the shortest path's time does not count."""
    if len(driven) < 2:
        return 0.0
    dt = np.diff(driven.t_s)
    moving = dt > 0
    dt, step_m = dt[moving], np.linalg.norm(np.diff(driven.xy, axis=0), axis=1)[moving]
    turn = np.abs(np.diff(np.unwrap(driven.yaw_rad)))[moving]
    return float(dt[(step_m / dt < STANDING_MPS) & (turn / dt > TURNING_RADPS)].sum())


def goal_outcome(record: GoalRecord, truth: PoseSeries, truth_map: OccupancyGrid,
                 collisions: list[tuple[float, float, float]], arrival_m: float | None = None) -> GoalOutcome:
    """A goal judged on ground truth: reached when the navigator succeeded and the true pose at the
    result is within :data:`GOAL_XY_TOLERANCE_M` and :data:`GOAL_YAW_TOLERANCE_RAD`; the time, the
    length driven, collisions and clearance between sending the goal and its result.

    With ``arrival_m`` (BARN's rule, :data:`BARN_ARRIVAL_M`), reached when the true position comes
    within ``arrival_m`` of the goal within the goal's time limit (``record.limit_s``; without one,
    before the navigator's answer unless it timed out), without a collision, whatever the navigator
    answers; the time and the length driven are up to that moment.

    Raises:
        PoseSeriesError: no ground truth at the goal's start or end.
    """
    span = truth.span_s()
    if span is None:
        raise PoseSeriesError("no ground truth recorded")
    start_s, end_s = max(record.start_s, span[0]), min(record.end_s, span[1])
    collided = sum(1 for t, _, _ in collisions if record.start_s <= t <= end_s)
    if arrival_m is not None:
        during = truth.within(start_s, end_s)
        near = np.flatnonzero(np.hypot(*(during.xy - np.asarray(record.goal[:2])).T) <= arrival_m)
        arrived_s = float(during.t_s[near[0]]) if len(near) else None
        timely = arrived_s is not None and (
            arrived_s - record.start_s <= record.limit_s if record.limit_s is not None
            else record.status not in (GoalAnswer.TIMEOUT, GoalAnswer.UNANSWERED))
        if arrived_s is not None and timely:
            end_s = arrived_s
            collided = sum(1 for t, _, _ in collisions if record.start_s <= t <= end_s)
        reached = timely and not collided
    final = truth.interpolate([end_s]).poses[0]
    driven = truth.within(start_s, end_s)
    position_m, yaw_rad = pose_error(final, record.goal)
    clearance = clearance_along(driven, truth_map, PPP_BOT_FOOTPRINT) if len(driven) else np.array([np.nan])
    if arrival_m is None:
        reached = record.status is GoalAnswer.SUCCEEDED and goal_reached(final, record.goal, GOAL_XY_TOLERANCE_M,
                                                                        GOAL_YAW_TOLERANCE_RAD)
    return GoalOutcome(
        goal=record.goal, reached=reached, final_pose=(float(final[0]), float(final[1]), float(final[2])),
        position_error_m=position_m, yaw_error_rad=yaw_rad, time_s=end_s - record.start_s,
        path_length_m=driven.path_length_m(), shortest_path_m=record.shortest_path_m,
        collisions=collided, min_clearance_m=float(np.min(clearance)))


def navigation_metrics(recording: Recording, truth_map: OccupancyGrid, map_to_world: tuple[float, float, float],
                       max_speed_mps: float, out: Path, title: str, map_free: bool = False) -> dict[str, Any]:
    """The goals' outcomes and their summary (:func:`summarize_navigation`: ``success_rate``,
    ``collisions``, ``mean_time_ratio`` against the shortest path at ``max_speed_mps``, ...),
    ``total_time_ratio`` (all successful goals' time over all their shortest times), the time spent
    turning on the spot (``turning_in_place_s``) and that ratio without it, AMCL's error
    along the way (``ate_*``), one entry per goal under ``goal_results``; writes ``trajectory.png``.

    Raises:
        PoseSeriesError: no ground truth was recorded.
    """
    truth = PoseSeries.from_rows(recording.truth_rows)
    arrival = BARN_ARRIVAL_M if map_free else None
    outcomes = [goal_outcome(r, truth, truth_map, recording.collisions, arrival) for r in recording.goals]
    metrics: dict[str, Any] = dict(summarize_navigation(outcomes, max_speed_mps))
    metrics["collisions"] = len(recording.collisions)  # also those outside a goal's time (there should be none)
    rated = [o for o in outcomes if o.reached and o.shortest_path_m]
    metrics["total_time_ratio"] = (sum(o.time_s for o in rated) * max_speed_mps /
                                   sum(o.shortest_path_m or 0.0 for o in rated)) if rated else None
    turning = [turning_in_place_s(truth.within(r.start_s, r.end_s)) for r in recording.goals]
    metrics["turning_in_place_s"] = round(sum(turning), 3)
    rated_turning = [t for t, o in zip(turning, outcomes, strict=True) if o.reached and o.shortest_path_m]
    metrics["total_time_ratio_without_turning"] = (
        (sum(o.time_s for o in rated) - sum(rated_turning)) * max_speed_mps /
        sum(o.shortest_path_m or 0.0 for o in rated)) if rated else None
    metrics["max_speed_mps"] = max_speed_mps
    metrics["distance_m"] = round(truth.path_length_m(), 3)
    metrics["recoveries"] = sum(r.recoveries for r in recording.goals)
    kind = MAP_FREE_ESTIMATE if map_free else ESTIMATES[Scenario.NAVIGATION]
    estimate = estimate_series(recording, kind)
    if len(estimate) >= 2 and len(truth) >= 2:
        ate = absolute_trajectory_error(estimate, truth, map_to_world)
        metrics.update(ate.as_dict("ate"))
    metrics["goal_results"] = [
        {"goal": list(o.goal), "status": r.status.value, "error_code": r.error_code, "error_msg": r.error_msg,
         "reached": o.reached, "time_s": round(o.time_s, 3),
         "shortest_path_m": None if o.shortest_path_m is None else round(o.shortest_path_m, 3),
         "path_length_m": round(o.path_length_m, 3), "position_error_m": round(o.position_error_m, 3),
         "yaw_error_rad": round(o.yaw_error_rad, 3), "collisions": o.collisions,
         "min_clearance_m": round(o.min_clearance_m, 3), "recoveries": r.recoveries, "start_s": round(r.start_s, 3),
         "turning_in_place_s": round(t, 3), "barn_score": round(barn_score(o, max_speed_mps), 4)}
        for r, o, t in zip(recording.goals, outcomes, turning, strict=True)]
    plot_trajectories(out / "trajectory.png", truth_map, truth, estimate.transformed(map_to_world),
                      ESTIMATE_LABELS[Scenario.DRIVE if map_free else Scenario.NAVIGATION],
                      [(x, y) for _, x, y in recording.collisions], title,
                      goals=[(o.goal[0], o.goal[1], o.reached) for o in outcomes])
    return metrics


def world_truth(world_file: Path, route: Route | None = None,
                resolution_m: float = GROUND_TRUTH_RESOLUTION_M) -> OccupancyGrid:
    """The world's ground-truth grid at the lidar's height; a world with nothing at that height
    (``empty``) gets the route's surroundings.

    Raises:
        WorldError: the world file cannot be loaded.
        ValueError: nothing to map and no route to bound it.
    """
    spec, _ = load_world(world_file, model_paths(world_file))
    model = spec.compile()
    try:
        return ground_truth_map(model, resolution_m, LIDAR_HEIGHT_M)
    except ValueError:
        if route is None:
            raise
        (x0, y0), (x1, y1) = route.points.min(axis=0) - EMPTY_MARGIN_M, route.points.max(axis=0) + EMPTY_MARGIN_M
        return ground_truth_map(model, resolution_m, LIDAR_HEIGHT_M, Bounds(x0, y0, x1, y1))


def score_saved_map(map_file: Path, world_file: Path, map_to_world: tuple[float, float, float],
                    out: Path) -> dict[str, Any]:
    """The ``map`` scenario's report: a saved map against the ground truth at the map's resolution.

    Raises:
        MapFileError: the map cannot be read.
        MapQualityError: the map's origin pose is not in the world's free space.
    """
    wall0 = time.monotonic()
    estimate, _ = load_map(map_file)
    truth = world_truth(world_file, resolution_m=estimate.resolution)
    metrics = map_metrics(estimate, truth, map_to_world, out, f"{map_file.name} in {world_file.stem}")
    return {"scenario": Scenario.MAP.value, "world": world_file.stem, "ok": True, "failure": None,
            "sim_seconds": 0.0, "wall_seconds": round(time.monotonic() - wall0, 3), "map": str(map_file),
            "map_pose": list(map_to_world), **metrics, "out": str(out), "plots": ["map.png"]}
