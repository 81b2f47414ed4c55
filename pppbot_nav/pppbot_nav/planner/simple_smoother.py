"""Nav2's ``nav2_smoother::SimpleSmoother`` for a path someone else planned (the smoother_server's plugin).

The path is cut where it changes direction (a cusp: consecutive steps pointing apart, or a turn
on the spot), as Nav2's ``findDirectionalPathSegments``. Each segment of more than
:data:`MIN_SEGMENT_POSES` poses is smoothed with its ends fixed: every inner point moves toward
its neighbours (``w_smooth``) while held to where it was (``w_data``), sweep after sweep, until
the sum of the moves of a sweep is below ``tolerance``. Then, with ``do_refinement``, the same
again ``refinement_num`` times on the smoothed segment. Shorter segments stay as they are.
A sweep that puts a point on an inscribed or lethal cell, or ``max_its`` sweeps, stop a segment
at the sweep before (the result is then not *completed*); running out of time raises
:class:`~pppbot_nav.errors.SmootherTimedOut`. Poses face along the smoothed path (backwards on
a reversing segment); the last pose keeps its heading.

Sweeps go over the odd inner points, then the even ones (red-black Gauss-Seidel, vectorised;
Nav2 sweeps point after point): the fixed point, the path both converge to, is the same.

Unlike :func:`pppbot_nav.planner.smoother.smooth` (the planner's own smoothing of its cell path)
this neither resamples nor reverts single points: it smooths the poses it is given.

:class:`SimpleSmootherParameters` is the smoother server's ``nav2_smoother::SimpleSmoother``
plugin (the ``pppbot_nav.smoothers`` entry point, :mod:`pppbot_nav.planner.smoother_interface`):
Nav2's parameter names and defaults under the smoother's name.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pppbot_common.maps import OccupancyGrid
from pppbot_common.params import ParameterError, check_finite_range, param
from pppbot_common.se2 import wrap_angle
from pppbot_nav.behaviors import INSCRIBED_OCCUPANCY
from pppbot_nav.errors import SmootherError, SmootherTimedOut
from pppbot_nav.planner.smoother_interface import SmoothedPath

#: Segments of this many poses or fewer are not smoothed (Nav2: ``end - start > 9``).
MIN_SEGMENT_POSES = 10
#: Consecutive points closer than this (m, in x and in y) give a pose no new heading.
SAME_POINT_M = 1e-4


@dataclass(frozen=True)
class SimpleSmootherSettings:
    tolerance: float = 1e-10  # m: a sweep moving the points less than this in sum ends the smoothing
    max_its: int = 1000  # sweeps before a segment is given up (not completed)
    w_data: float = 0.2  # pull toward the original path
    w_smooth: float = 0.3  # pull toward the neighbours
    do_refinement: bool = True
    refinement_num: int = 2  # smoothings of the smoothed path, with do_refinement

    def validate(self, prefix: str = "simple_smoother") -> None:
        """Raises: ParameterError naming ``<prefix>.<setting>`` (``<setting>`` with an empty prefix)."""
        at = f"{prefix}." if prefix else ""
        check_finite_range(f"{at}tolerance", self.tolerance, 0.0, 1.0)
        check_finite_range(f"{at}w_data", self.w_data, 0.0, 1.0)
        check_finite_range(f"{at}w_smooth", self.w_smooth, 0.0, 0.5)
        if self.max_its < 1:
            raise ParameterError(f"{at}max_its", self.max_its, "must be ≥ 1")
        if self.refinement_num < 0:
            raise ParameterError(f"{at}refinement_num", self.refinement_num, "must be ≥ 0")


def directional_segments(points_xy: np.ndarray, yaws_rad: np.ndarray) -> list[tuple[int, int]]:
    """(start, end) pose indices, ends included, of the path's pieces of one direction: a new one
    starts at a cusp (the steps into and out of a pose point apart) and at a turn on the spot."""
    n = len(points_xy)
    segments: list[tuple[int, int]] = []
    start = 0
    steps = np.diff(points_xy, axis=0)
    for i in range(1, n - 1):
        into, out = steps[i - 1], steps[i]
        turn = abs(wrap_angle(float(yaws_rad[i + 1] - yaws_rad[i])))
        on_the_spot = abs(out[0]) < SAME_POINT_M and abs(out[1]) < SAME_POINT_M and turn > 1e-4
        if float(into @ out) < 0.0 or on_the_spot:
            segments.append((start, i))
            start = i
    segments.append((start, n - 1))
    return segments


def smooth_path(points_xy: np.ndarray, yaws_rad: np.ndarray, settings: SimpleSmootherSettings, *,
                clock_s: Callable[[], float], max_duration_s: float,
                blocked: Callable[[np.ndarray], np.ndarray] | None = None) -> SmoothedPath:
    """The path smoothed as the module's docstring says.

    Args:
        points_xy: (N, 2) the poses' positions (m).
        yaws_rad: (N,) the poses' headings.
        settings: the smoother's settings.
        clock_s: the time (s) by which ``max_duration_s`` is measured.
        max_duration_s: the time smoothing may take.
        blocked: (K, 2) points → (K,) bool, True where a point may not go (see
            :func:`blocked_cells`); None: anywhere.

    Raises:
        SmootherError: an empty path, shapes that differ, or a non-finite value.
        SmootherTimedOut: smoothing took longer than ``max_duration_s``.
    """
    points = np.asarray(points_xy, dtype=float).reshape(-1, 2)
    yaws = np.asarray(yaws_rad, dtype=float).reshape(-1)
    if len(points) == 0:
        raise SmootherError("the path to smooth is empty")
    if len(yaws) != len(points):
        raise SmootherError(f"the path has {len(points)} points but {len(yaws)} headings")
    if not (np.isfinite(points).all() and np.isfinite(yaws).all()):
        raise SmootherError("the path to smooth has a non-finite coordinate or heading")
    deadline_s = clock_s() + max_duration_s

    def check_time() -> None:
        if clock_s() > deadline_s:
            raise SmootherTimedOut(f"smoothing took longer than the {max_duration_s:g} s it was given")

    out_points, out_yaws = points.copy(), yaws.copy()
    completed = True
    for start, end in directional_segments(points, yaws):
        if end - start + 1 <= MIN_SEGMENT_POSES:
            continue
        segment = points[start:end + 1]
        smoothed, converged = _smooth_pass(segment, settings, blocked, check_time)
        if converged and settings.do_refinement:
            for _ in range(settings.refinement_num):
                smoothed, refined = _smooth_pass(smoothed, settings, blocked, check_time)
                if not refined:
                    break
        completed = completed and converged
        out_points[start:end + 1] = smoothed
        out_yaws[start:end + 1] = _headings(smoothed, yaws[start:end + 1])
    return SmoothedPath(out_points, out_yaws, completed)


def _smooth_pass(original: np.ndarray, settings: SimpleSmootherSettings,
                 blocked: Callable[[np.ndarray], np.ndarray] | None,
                 check_time: Callable[[], None]) -> tuple[np.ndarray, bool]:
    """One smoothing of a segment (Nav2's ``smoothImpl`` without its refinement): the path, and
    whether it converged (False: it is the last sweep before a collision or ``max_its``)."""
    path = original.copy()
    last = original.copy()
    odd, even = np.arange(1, len(path) - 1, 2), np.arange(2, len(path) - 1, 2)
    its = 0
    change = settings.tolerance
    while change >= settings.tolerance:
        its += 1
        change = 0.0
        if its >= settings.max_its:
            return last, False
        check_time()
        for idx in (odd, even):
            before = path[idx]
            moved = (settings.w_data * (original[idx] - before)
                     + settings.w_smooth * (path[idx - 1] + path[idx + 1] - 2.0 * before))
            path[idx] = before + moved
            change += float(np.abs(moved).sum())
        if blocked is not None and bool(blocked(path[1:-1]).any()):
            return last, False
        last = path.copy()
    return path, True


def _headings(points: np.ndarray, yaws: np.ndarray) -> np.ndarray:
    """Nav2's ``updateApproximatePathOrientations``: each pose but the last faces the next point
    (the opposite way on a reversing segment, told by its second pose); coinciding points keep
    their heading."""
    out = yaws.copy()
    step = np.diff(points, axis=0)
    along = np.arctan2(step[:, 1], step[:, 0])
    reversing = abs(wrap_angle(float(along[1] - yaws[1]))) > math.pi / 2 if len(step) > 1 else False
    moved = (np.abs(step[:, 0]) >= SAME_POINT_M) | (np.abs(step[:, 1]) >= SAME_POINT_M)
    facing = along + (math.pi if reversing else 0.0)
    out[:-1] = np.where(moved, np.arctan2(np.sin(facing), np.cos(facing)), yaws[:-1])
    return out


def _occupancy(grid: OccupancyGrid, points_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each point's cell value on ``grid`` (0 off the map) and whether it is on the map."""
    row, col = grid.cell_of(points_xy[:, 0], points_xy[:, 1])
    inside = (row >= 0) & (row < grid.height) & (col >= 0) & (col < grid.width)
    values = np.zeros(len(points_xy), dtype=int)
    values[inside] = grid.data[row[inside], col[inside]]
    return values, inside


def blocked_cells(grid: OccupancyGrid) -> Callable[[np.ndarray], np.ndarray]:
    """Where the smoother may not move a point on ``grid`` (a published costmap, 0-100): inscribed
    and lethal cells (≥ :data:`~pppbot_nav.behaviors.INSCRIBED_OCCUPANCY`). Unknown and off-map
    cells are no obstacle, as in Nav2's smoother."""
    def blocked(points_xy: np.ndarray) -> np.ndarray:
        values, inside = _occupancy(grid, points_xy)
        return inside & (values >= INSCRIBED_OCCUPANCY)
    return blocked


def first_collision(grid: OccupancyGrid, points_xy: np.ndarray) -> int | None:
    """The index of the first point that is in collision on ``grid``, or None: on an inscribed or
    lethal cell (the robot's footprint circle on an obstacle) or off the map (Nav2's collision
    checker refuses a pose it cannot place). Unknown cells are no collision here: pppbot plans
    through unknown space (``allow_unknown``)."""
    values, inside = _occupancy(grid, np.asarray(points_xy, dtype=float).reshape(-1, 2))
    hits = np.flatnonzero(~inside | (values >= INSCRIBED_OCCUPANCY))
    return int(hits[0]) if len(hits) else None


class SimpleSmoother:
    """Nav2's SimpleSmoother on the server's costmap: points kept off its inscribed and lethal cells."""

    def __init__(self, settings: SimpleSmootherSettings) -> None:
        self.settings = settings

    def smooth(self, points_xy: np.ndarray, yaws_rad: np.ndarray, costmap: OccupancyGrid, *,
               clock_s: Callable[[], float], max_duration_s: float) -> SmoothedPath:
        """:func:`smooth_path` kept off :func:`blocked_cells` of ``costmap`` (raises as it does)."""
        return smooth_path(points_xy, yaws_rad, self.settings, clock_s=clock_s, max_duration_s=max_duration_s,
                           blocked=blocked_cells(costmap))


@dataclass(frozen=True)
class SimpleSmootherParameters:
    """``nav2_smoother::SimpleSmoother``'s parameters (Nav2's names and defaults), under its name."""

    tolerance: float = param(1e-10, "a sweep moving the points less than this in sum ends the smoothing (m)")
    max_its: int = param(1000, "sweeps before a segment is given up")
    w_data: float = param(0.2, "pull toward the original path")
    w_smooth: float = param(0.3, "pull toward the neighbours")
    do_refinement: bool = param(True, "smooth the smoothed path again")
    refinement_num: int = param(2, "refinements with do_refinement")

    def validate(self) -> None:
        """Raises: ParameterError naming the parameter (the server adds the smoother's name)."""
        self.settings().validate(prefix="")

    def settings(self) -> SimpleSmootherSettings:
        return SimpleSmootherSettings(self.tolerance, self.max_its, self.w_data, self.w_smooth, self.do_refinement,
                                      self.refinement_num)

    def make(self) -> SimpleSmoother:
        return SimpleSmoother(self.settings())
