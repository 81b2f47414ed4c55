"""From a staircase of cells to a smooth path: string pulling under the travel cost, then
Nav2's simple smoother.

:func:`shortcut` (Theta*-style post-processing): from each kept point, jump straight to the
farthest later point whose straight segment costs no more than the cells it replaces, cost
being the integral of the cell weights along the way (a cell that cannot be entered weighs
``BLOCKED_WEIGHT``). So the path loses its 45° zig-zags but does not cut through the
inflation it went round.

:func:`smooth` (``nav2_smoother::SimpleSmoother``): resample at ``resample_m``, then move each
inner point toward its neighbours' mean (``w_smooth``) while holding it to where it was
(``w_data``), until the largest move is below ``tolerance`` or after ``max_its`` sweeps. A
smoothed point that would enter the inscribed zone goes back to where it was.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pppbot_common.params import ParameterError, check_finite_range
from pppbot_nav.costmap.costs import INSCRIBED_INFLATED_OBSTACLE, NO_INFORMATION
from pppbot_nav.costmap.grid import Costmap

#: What a cell that cannot be entered weighs in the shortcut's cost integral.
BLOCKED_WEIGHT = 1000.0


@dataclass(frozen=True)
class SmootherSettings:
    w_data: float = 0.2
    w_smooth: float = 0.3
    tolerance: float = 1e-6  # m: stop when no point moves more than this in a sweep
    max_its: int = 1000
    resample_m: float = 0.1

    def validate(self) -> None:
        check_finite_range("smoother.w_data", self.w_data, 0.0, 1.0)
        check_finite_range("smoother.w_smooth", self.w_smooth, 0.0, 0.5)
        check_finite_range("smoother.tolerance", self.tolerance, 0.0, 1.0)
        check_finite_range("smoother.resample_m", self.resample_m, 0.0, 10.0, low_open=True)
        if self.max_its < 0:
            raise ParameterError("smoother.max_its", self.max_its, "must be ≥ 0")


def _samples(a: np.ndarray, b: np.ndarray, step_m: float) -> tuple[np.ndarray, float]:
    """Points along a → b every ``step_m`` or less (a excluded, b included) and the length per sample."""
    length = float(np.hypot(*(b - a)))
    n = max(1, math.ceil(length / step_m))
    t = np.arange(1, n + 1)[:, None] / n
    return a + t * (b - a), length / n


def _cost(costmap: Costmap, weights: np.ndarray, points: np.ndarray) -> np.ndarray:
    row, col = costmap.cell_of(points[:, 0], points[:, 1])
    ok = costmap.inside(row, col)
    w = np.full(len(points), BLOCKED_WEIGHT)
    w[ok] = np.minimum(weights[row[ok], col[ok]], BLOCKED_WEIGHT)
    return w


def _segment_cost(costmap: Costmap, weights: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    points, ds = _samples(a, b, costmap.resolution / 2.0)
    return float(_cost(costmap, weights, points).sum() * ds)


def _edge_costs(costmap: Costmap, weights: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """:func:`_segment_cost` of every edge of a polyline, at once."""
    step = costmap.resolution / 2.0
    lengths = np.hypot(*(pts[1:] - pts[:-1]).T)
    counts = np.maximum(1, np.ceil(lengths / step).astype(int))
    edge = np.repeat(np.arange(len(lengths)), counts)
    first = np.concatenate([[0], np.cumsum(counts)[:-1]])
    t = ((np.arange(counts.sum()) - np.repeat(first, counts) + 1) / np.repeat(counts, counts))[:, None]
    samples = pts[edge] + t * (pts[edge + 1] - pts[edge])
    per_sample = _cost(costmap, weights, samples) * np.repeat(lengths / counts, counts)
    return np.bincount(edge, weights=per_sample, minlength=len(lengths))


def shortcut(points: np.ndarray, costmap: Costmap, weights: np.ndarray) -> np.ndarray:
    """The path's kept points after string pulling (start and end kept); ``weights`` are the
    planner's per-cell travel weights (inf: cannot be entered)."""
    pts = np.asarray(points, dtype=float)
    n = len(pts)
    if n <= 2:
        return pts
    raw = np.concatenate([[0.0], np.cumsum(_edge_costs(costmap, weights, pts))])

    def fits(i: int, j: int) -> bool:
        return _segment_cost(costmap, weights, pts[i], pts[j]) <= (raw[j] - raw[i]) * (1 + 1e-9) + 1e-9

    kept = [0]
    i = 0
    while i < n - 1:
        # Exponential then binary search for the farthest j that fits (j = i + 1 always does).
        good, step = i + 1, 1
        while good + step < n and fits(i, good + step):
            good += step
            step *= 2
        bad = min(good + step, n)
        while bad - good > 1:
            mid = (good + bad) // 2
            if fits(i, mid):
                good = mid
            else:
                bad = mid
        kept.append(good)
        i = good
    return pts[kept]


def resample(points: np.ndarray, step_m: float) -> np.ndarray:
    """The polyline with a point every ``step_m`` or less along each segment, corners kept."""
    pts = np.asarray(points, dtype=float)
    out = [pts[:1]]
    for a, b in zip(pts[:-1], pts[1:], strict=True):
        out.append(_samples(a, b, step_m)[0])
    return np.vstack(out)


def smooth(points: np.ndarray, costmap: Costmap, settings: SmootherSettings = SmootherSettings()) -> np.ndarray:
    """The path resampled and smoothed; ends fixed; no point moved into the inscribed zone."""
    original = resample(points, settings.resample_m)
    if len(original) <= 2:
        return original
    path = original.copy()
    for _ in range(settings.max_its):
        inner = path[1:-1]
        moved = (settings.w_data * (original[1:-1] - inner)
                 + settings.w_smooth * (path[:-2] + path[2:] - 2.0 * inner))
        path[1:-1] = inner + moved
        if float(np.abs(moved).max()) < settings.tolerance:
            break
    before = costmap.cost_at(original[:, 0], original[:, 1], NO_INFORMATION)
    after = costmap.cost_at(path[:, 0], path[:, 1], NO_INFORMATION)
    worse = (after >= INSCRIBED_INFLATED_OBSTACLE) & (after != NO_INFORMATION) & (after > before)
    path[worse] = original[worse]
    return path
