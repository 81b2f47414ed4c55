"""Navigation metrics against ground truth: footprint clearance, goal outcomes and their summary.

Clearance is measured from the robot's footprint outline to the truth's occupied cells
with one Euclidean distance transform of the truth grid. Path and time efficiency
follow the usual navigation benchmark ratios (e.g. Nav2's and BARN's): driven length
over the shortest feasible length, and time over the time the shortest path takes at
full speed.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from shapely.geometry import box
from shapely.ops import unary_union

from pppbot_common.maps import OccupancyGrid
from pppbot_common.se2 import PoseLike, se2_apply, wrap_angles
from pppbot_eval.errors import NavigationMetricError
from pppbot_eval.map_quality import cells_of, grid_coordinates, in_grid, occupied_cells
from pppbot_eval.trajectory import PoseSeries

#: Vertices of a circle footprint's polygon (its outline is within 4e-5·radius of the circle).
CIRCLE_VERTICES = 360



def _positive(value: float, name: str) -> float:
    if not (math.isfinite(value) and value > 0):
        raise NavigationMetricError(f"{name} must be a positive number, not {value}")
    return float(value)


@dataclass(frozen=True, eq=False)
class Footprint:
    """The robot's outline: a polygon ``vertices_xy`` (K, 2) in m in the base frame (x forward, y left).

    Raises:
        NavigationMetricError: fewer than three vertices, or non-finite ones.
    """

    vertices_xy: np.ndarray

    def __post_init__(self) -> None:
        vertices = np.array(self.vertices_xy, dtype=float)
        if vertices.ndim != 2 or vertices.shape[0] < 3 or vertices.shape[1] != 2 or not np.isfinite(vertices).all():
            raise NavigationMetricError(f"a footprint is a polygon of at least 3 finite (x, y) vertices, "
                                        f"not an array of shape {vertices.shape}")
        vertices.setflags(write=False)
        object.__setattr__(self, "vertices_xy", vertices)

    @classmethod
    def rectangle(cls, x_min: float, x_max: float, y_min: float, y_max: float) -> Footprint:
        """An axis-aligned rectangle (m).

        Raises:
            NavigationMetricError: an empty rectangle (min >= max).
        """
        if not (x_min < x_max and y_min < y_max):
            raise NavigationMetricError(f"rectangle x {x_min}..{x_max}, y {y_min}..{y_max} m is empty")
        return cls(np.array([[x_min, y_min], [x_max, y_min], [x_max, y_max], [x_min, y_max]]))

    @classmethod
    def circle(cls, radius_m: float) -> Footprint:
        """A circle of ``radius_m`` about the base origin (a :data:`CIRCLE_VERTICES`-gon).

        Raises:
            NavigationMetricError: a radius that is not positive.
        """
        radius_m = _positive(radius_m, "radius_m")
        angle = np.linspace(0.0, 2.0 * math.pi, CIRCLE_VERTICES, endpoint=False)
        return cls(radius_m * np.column_stack([np.cos(angle), np.sin(angle)]))

    def perimeter_points(self, spacing_m: float = 0.02) -> np.ndarray:
        """Points (M, 2) along the outline, at most ``spacing_m`` apart, every vertex included.

        Raises:
            NavigationMetricError: a spacing that is not positive.
        """
        spacing_m = _positive(spacing_m, "spacing_m")
        start = self.vertices_xy
        edge = np.roll(start, -1, axis=0) - start
        steps = np.maximum(1, np.ceil(np.linalg.norm(edge, axis=1) / spacing_m).astype(np.int64))
        which = np.repeat(np.arange(start.shape[0]), steps)
        fraction = (np.arange(which.size) - np.repeat(np.cumsum(steps) - steps, steps)) / steps[which]
        return start[which] + fraction[:, None] * edge[which]


#: ppp_bot's chassis in base_link: x −0.1 … 0.2 m, y −0.15 … 0.15 m.
def _ppp_bot_outline() -> Footprint:
    """ppp_bot seen from above in base_link: the chassis box and the two wheels sticking out of its sides."""
    chassis = box(-0.1, -0.15, 0.2, 0.15)
    # The 5 mm between chassis and wheel (y 0.15 to 0.155) is filled: one outline, nothing fits there.
    wheels = [box(-0.05, 0.15, 0.05, 0.195), box(-0.05, -0.195, 0.05, -0.15)]
    outline = unary_union([chassis, *wheels])
    return Footprint(np.asarray(outline.exterior.coords)[:-1])


#: chassis 0.3 × 0.3 m from x = −0.1 to 0.2, wheels r 0.05 m, 0.04 m wide at y = ±0.175
PPP_BOT_FOOTPRINT = _ppp_bot_outline()
#: Poses per batch in :func:`clearance_along` (bounds memory on long runs).
CLEARANCE_BATCH = 4096


def clearance_along(poses: PoseSeries, truth: OccupancyGrid, footprint: Footprint,
                    spacing_m: float = 0.02) -> np.ndarray:
    """(N,) clearance in m of the footprint at each pose of ``poses`` (in the truth's world frame).

    For every outline point (``spacing_m`` apart) the distance to the nearest occupied
    truth cell's centre, bilinearly interpolated in one distance transform of the truth,
    less half a cell (so the distance to the cell's edge: exact for axis-aligned walls);
    the minimum over the outline, clipped at 0, and 0 when an outline point lies in an
    occupied cell. The truth grid should cover the driving area: points outside it are
    measured as at the nearest edge cell. A truth without occupied cells gives inf.
    """
    occupied = occupied_cells(truth)
    if not len(poses):
        return np.zeros(0)
    if not occupied.any():
        return np.full(len(poses), np.inf)
    distance_m = ndimage.distance_transform_edt(~occupied, sampling=truth.resolution)
    outline = footprint.perimeter_points(spacing_m)
    return np.concatenate([_clearance(poses.poses[i:i + CLEARANCE_BATCH], outline, truth, occupied, distance_m)
                           for i in range(0, len(poses), CLEARANCE_BATCH)])


def _clearance(poses: np.ndarray, outline: np.ndarray, truth: OccupancyGrid, occupied: np.ndarray,
               distance_m: np.ndarray) -> np.ndarray:
    points = se2_apply(poses[:, None, :], outline[None, :, :])  # (N, M, 2)
    row, col = grid_coordinates(truth, points)
    sampled = ndimage.map_coordinates(distance_m, [row.ravel() - 0.5, col.ravel() - 0.5], order=1, mode="nearest")
    clearance = np.clip(sampled.reshape(row.shape) - truth.resolution / 2.0, 0.0, None)
    rows, cols = cells_of(truth, points)
    inside = in_grid(truth, rows, cols)
    hit = np.zeros(rows.shape, dtype=bool)
    hit[inside] = occupied[rows[inside], cols[inside]]
    clearance[hit] = 0.0
    return np.asarray(clearance.min(axis=1))


def pose_error(final_pose: PoseLike, goal: PoseLike) -> tuple[float, float]:
    """(position error in m, signed wrapped yaw error in rad) of ``final_pose`` against ``goal``."""
    final, target = np.asarray(final_pose, dtype=float), np.asarray(goal, dtype=float)
    return (float(math.hypot(final[0] - target[0], final[1] - target[1])),
            float(wrap_angles(final[2] - target[2])))


def goal_reached(final_pose: PoseLike, goal: PoseLike, xy_tolerance_m: float = 0.25,
                 yaw_tolerance_rad: float = 0.25) -> bool:
    """Whether ``final_pose`` is within ``xy_tolerance_m`` and ``yaw_tolerance_rad`` (inclusive) of ``goal``."""
    position_m, yaw_rad = pose_error(final_pose, goal)
    return position_m <= xy_tolerance_m and abs(yaw_rad) <= yaw_tolerance_rad


@dataclass(frozen=True)
class GoalOutcome:
    """One navigation goal's result, measured on the ground truth.

    ``time_s`` is simulated time from sending the goal to its result; ``path_length_m`` the
    length driven (truth poses); ``shortest_path_m`` the shortest feasible length, None
    when there is none.
    """

    goal: tuple[float, float, float]
    reached: bool
    final_pose: tuple[float, float, float]
    position_error_m: float
    yaw_error_rad: float
    time_s: float
    path_length_m: float
    shortest_path_m: float | None
    collisions: int
    min_clearance_m: float


def _mean(values: Sequence[float]) -> float | None:
    finite = [v for v in values if math.isfinite(v)]
    return float(np.mean(finite)) if finite else None


def summarize_navigation(outcomes: Sequence[GoalOutcome], max_speed_mps: float) -> dict[str, float | int | None]:
    """Aggregate goal outcomes into JSON-safe scalars (None where undefined, never NaN).

    * ``goals``, ``successes``, ``success_rate`` (None without goals), ``collisions`` (sum);
    * over successful goals: ``mean_time_s``, ``mean_path_ratio`` (driven / shortest) and
      ``mean_time_ratio`` (time / (shortest / ``max_speed_mps``)), the ratios over those with a
      positive shortest path;
    * over all goals: ``min_clearance_m``, ``mean_position_error_m``, and ``barn_score``, the mean
      of :func:`barn_score` (a goal neither reached nor clear of collisions scores 0).

    Raises:
        NavigationMetricError: ``max_speed_mps`` is not positive.
    """
    max_speed_mps = _positive(max_speed_mps, "max_speed_mps")
    successes = [o for o in outcomes if o.reached]
    rated = [o for o in successes if o.shortest_path_m is not None and o.shortest_path_m > 0]
    clearances = [o.min_clearance_m for o in outcomes if not math.isnan(o.min_clearance_m)]
    return {
        "goals": len(outcomes),
        "successes": len(successes),
        "success_rate": len(successes) / len(outcomes) if outcomes else None,
        "collisions": sum(o.collisions for o in outcomes),
        "mean_time_s": _mean([o.time_s for o in successes]),
        "mean_path_ratio": _mean([o.path_length_m / o.shortest_path_m for o in rated if o.shortest_path_m]),
        "mean_time_ratio": _mean([o.time_s * max_speed_mps / o.shortest_path_m for o in rated
                                  if o.shortest_path_m]),
        "min_clearance_m": float(min(clearances)) if clearances and math.isfinite(min(clearances)) else None,
        "mean_position_error_m": _mean([o.position_error_m for o in outcomes]),
        "barn_score": _mean([barn_score(o, max_speed_mps) for o in outcomes]),
    }


def barn_score(outcome: GoalOutcome, max_speed_mps: float) -> float:
    """The BARN challenge's score of one goal: ``success × OT / clip(AT, 2·OT, 8·OT)``, OT the
    shortest path's time at ``max_speed_mps``, AT the time taken; success is reached without a
    collision. 0.5 at best (twice the optimal time or faster), 0.125 at eight times or more, 0 when
    failed (or without a shortest path to time against)."""
    shortest = outcome.shortest_path_m
    if not (outcome.reached and not outcome.collisions and shortest):
        return 0.0
    optimal_s = shortest / max_speed_mps
    return optimal_s / float(np.clip(outcome.time_s, 2.0 * optimal_s, 8.0 * optimal_s))
