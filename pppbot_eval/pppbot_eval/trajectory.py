"""Trajectory accuracy against ground truth: absolute and relative pose error in SE(2).

Poses are (x, y, yaw) in m, m, rad (SE(2) helpers: ``pppbot_common.se2``).

The estimate's frame relation to the world is known (for SLAM the map frame is the
robot's spawn pose), so nothing is fitted: the estimate is moved into the world by
``estimate_to_world`` and compared sample by sample, with the truth interpolated at
the estimate's times. Absolute trajectory error (ATE) and relative pose error (RPE)
follow Sturm et al., "A benchmark for the evaluation of RGB-D SLAM systems" (IROS
2012), with RPE segments measured by truth path length as in the KITTI odometry
benchmark (errors per metre driven).
"""
from __future__ import annotations

import math
from array import array
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from pppbot_common.se2 import PoseLike, finite_pose, se2_compose, se2_inverse, se2_relative, wrap_angles
from pppbot_eval.errors import NoOverlapError, PoseSeriesError

# --- pose series --------------------------------------------------------------------------------


def _frozen(array: np.ndarray) -> np.ndarray:
    array = np.ascontiguousarray(array, dtype=float)
    array.setflags(write=False)
    return array


class PoseRows:
    """Timed planar poses as they come, (t_s, x_m, y_m, yaw_rad) rows kept as packed doubles: 32
    bytes a row, where a list of tuples took about 170 (a soak's eval grew by 82 MB per sim hour
    recording its truth, estimate and /tf at their rates). Appends, iterates and reads as an
    (N, 4) numpy array."""

    __slots__ = ("_values",)

    def __init__(self, rows: Iterable[Sequence[float]] = ()) -> None:
        self._values = array("d")
        for row in rows:
            self.append(row)

    def append(self, row: Sequence[float]) -> None:
        """Raises: PoseSeriesError: ``row`` is not four numbers."""
        if len(row) != 4:
            raise PoseSeriesError(f"a pose row is (t_s, x, y, yaw); got {len(row)} values: {tuple(row)}")
        try:
            values = array("d", row)  # whole before it is kept: a bad value leaves nothing behind
        except TypeError as exc:
            raise PoseSeriesError(f"a pose row is four numbers; got {tuple(row)}") from exc
        self._values.extend(values)

    def __len__(self) -> int:
        return len(self._values) // 4

    def __iter__(self) -> Iterator[tuple[float, float, float, float]]:
        values = self._values
        for i in range(0, len(values), 4):
            yield values[i], values[i + 1], values[i + 2], values[i + 3]

    def __array__(self, dtype: np.dtype | None = None, copy: bool | None = None) -> np.ndarray:
        return np.frombuffer(self._values, dtype=float).astype(dtype or float).reshape(-1, 4)


@dataclass(frozen=True, eq=False)
class PoseSeries:
    """Timed planar poses: ``t_s`` (N,) s, ``xy`` (N, 2) m, ``yaw_rad`` (N,) rad.

    Times must be non-decreasing; of samples sharing one time only the last is kept.
    The arrays are stored read-only.

    Raises:
        PoseSeriesError: mismatched shapes, non-finite values or decreasing times.
    """

    t_s: np.ndarray
    xy: np.ndarray
    yaw_rad: np.ndarray

    def __post_init__(self) -> None:
        t = np.asarray(self.t_s, dtype=float)
        xy = np.asarray(self.xy, dtype=float)
        yaw = np.asarray(self.yaw_rad, dtype=float)
        if t.ndim != 1 or xy.shape != (t.size, 2) or yaw.shape != t.shape:
            raise PoseSeriesError(f"a pose series needs t_s (N,), xy (N, 2), yaw_rad (N,); "
                                  f"got shapes {t.shape}, {xy.shape}, {yaw.shape}")
        for name, values in (("t_s", t), ("xy", xy), ("yaw_rad", yaw)):
            if not np.isfinite(values).all():
                raise PoseSeriesError(f"{name} has a non-finite value: {values[~np.isfinite(values)][0]}")
        steps = np.diff(t)
        if (steps < 0).any():
            i = int(np.argmax(steps < 0))
            raise PoseSeriesError(f"times must be non-decreasing: t_s[{i + 1}] = {t[i + 1]} s "
                                  f"follows t_s[{i}] = {t[i]} s")
        keep = np.append(steps > 0, True) if t.size else np.zeros(0, dtype=bool)  # the last of each equal time
        object.__setattr__(self, "t_s", _frozen(t[keep]))
        object.__setattr__(self, "xy", _frozen(xy[keep]))
        object.__setattr__(self, "yaw_rad", _frozen(yaw[keep]))

    @classmethod
    def from_rows(cls, rows: Iterable[Sequence[float]]) -> PoseSeries:
        """From rows of (t_s, x_m, y_m, yaw_rad).

        Raises:
            PoseSeriesError: a row is not four numbers, or as the constructor.
        """
        table = np.asarray(rows if isinstance(rows, PoseRows) else list(rows), dtype=float)
        if table.size == 0:
            table = table.reshape(0, 4)
        if table.ndim != 2 or table.shape[1] != 4:
            raise PoseSeriesError(f"rows must be (t_s, x, y, yaw); got an array of shape {table.shape}")
        return cls(table[:, 0], table[:, 1:3], table[:, 3])

    @classmethod
    def from_poses(cls, t_s: np.ndarray, poses: np.ndarray) -> PoseSeries:
        """From times (N,) s and poses (N, 3) of (x, y, yaw)."""
        poses = np.asarray(poses, dtype=float).reshape(-1, 3)
        return cls(np.asarray(t_s, dtype=float), poses[:, :2], poses[:, 2])

    def __len__(self) -> int:
        return int(self.t_s.size)

    @property
    def poses(self) -> np.ndarray:
        """(N, 3) array of (x, y, yaw)."""
        return np.column_stack([self.xy, self.yaw_rad])

    def span_s(self) -> tuple[float, float] | None:
        """(first, last) time in s, or None for an empty series."""
        return (float(self.t_s[0]), float(self.t_s[-1])) if len(self) else None

    def transformed(self, pose: PoseLike) -> PoseSeries:
        """The series in ``pose``'s parent frame: every sample left-composed, ``pose ∘ sample``.

        E.g. ``estimate.transformed(map_to_world)`` expresses a map-frame estimate in the world.

        Raises:
            PoseSeriesError: ``pose`` is not a finite (x, y, yaw).
        """
        return PoseSeries.from_poses(self.t_s, se2_compose(finite_pose(pose, "pose", PoseSeriesError), self.poses))

    def within(self, t0_s: float, t1_s: float) -> PoseSeries:
        """The samples with ``t0_s <= t <= t1_s``."""
        keep = (self.t_s >= t0_s) & (self.t_s <= t1_s)
        return PoseSeries(self.t_s[keep], self.xy[keep], self.yaw_rad[keep])

    def interpolate(self, t_s: np.ndarray | Sequence[float]) -> PoseSeries:
        """The poses at times ``t_s`` (s): linear in x, y and in unwrapped yaw (the short way round).

        ``t_s`` must be non-decreasing (the result is a :class:`PoseSeries`) and lie within the
        series' span: select the times first (:meth:`span_s`) when they may not.

        Raises:
            PoseSeriesError: the series is empty, or a time lies outside its span.
        """
        t = np.asarray(t_s, dtype=float).reshape(-1)
        if not len(self):
            raise PoseSeriesError("cannot interpolate an empty pose series")
        outside = (t < self.t_s[0]) | (t > self.t_s[-1]) | ~np.isfinite(t)
        if outside.any():
            raise PoseSeriesError(f"time {t[outside][0]} s is outside the series' span "
                                  f"[{self.t_s[0]}, {self.t_s[-1]}] s")
        x = np.interp(t, self.t_s, self.xy[:, 0])
        y = np.interp(t, self.t_s, self.xy[:, 1])
        yaw = wrap_angles(np.interp(t, self.t_s, np.unwrap(self.yaw_rad)))
        return PoseSeries(t, np.column_stack([x, y]), yaw)

    def cumulative_length_m(self) -> np.ndarray:
        """(N,) distance driven (m) from the first sample to each sample."""
        steps = np.linalg.norm(np.diff(self.xy, axis=0), axis=1)
        return np.concatenate([[0.0], np.cumsum(steps)])

    def path_length_m(self) -> float:
        """Length (m) of the polyline through the positions."""
        return float(self.cumulative_length_m()[-1]) if len(self) else 0.0


# --- matching an estimate to the truth ----------------------------------------------------------


def _span_text(series: PoseSeries) -> str:
    span = series.span_s()
    return "no samples" if span is None else f"[{span[0]:.3f}, {span[1]:.3f}] s"


def _matched(estimate: PoseSeries, truth: PoseSeries, estimate_to_world: PoseLike,
             max_gap_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(times, estimate poses in the world, truth poses), at the estimate samples that overlap.

    An estimate sample overlaps when its time equals a truth time, or lies between two
    truth samples at most ``max_gap_s`` apart.
    """
    if not (math.isfinite(max_gap_s) and max_gap_s >= 0):
        raise PoseSeriesError(f"max_gap_s must be a non-negative number, not {max_gap_s}")
    world = estimate.transformed(finite_pose(estimate_to_world, "estimate_to_world", PoseSeriesError))
    t, tt = world.t_s, truth.t_s
    right = np.searchsorted(tt, t, side="left")
    exact = (right < tt.size) & (tt[np.minimum(right, tt.size - 1)] == t) if tt.size else np.zeros(t.shape, bool)
    inside = (right > 0) & (right < tt.size)
    gap = np.full(t.shape, np.inf)
    gap[inside] = tt[right[inside]] - tt[right[inside] - 1]
    keep = exact | (inside & (gap <= max_gap_s))
    if not keep.any():
        raise NoOverlapError(f"no estimate sample overlaps the truth: the estimate spans {_span_text(estimate)}, "
                             f"the truth {_span_text(truth)} (truth samples at most {max_gap_s} s apart)")
    return t[keep], world.poses[keep], truth.interpolate(t[keep]).poses


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


@dataclass(frozen=True, eq=False)
class AteResult:
    """Absolute trajectory error per matched sample: position (m) and signed yaw (rad)."""

    t_s: np.ndarray
    position_error_m: np.ndarray
    yaw_error_rad: np.ndarray
    rms_m: float
    max_m: float
    yaw_rms_rad: float
    yaw_max_rad: float  # of |yaw error|
    samples: int

    def as_dict(self, prefix: str = "ate") -> dict[str, float | int]:
        """The scalars, JSON-ready: ``{prefix}_rms_m``, ``_max_m``, ``_yaw_rms_rad``, ``_yaw_max_rad``, ``_samples``."""
        return {f"{prefix}_rms_m": self.rms_m, f"{prefix}_max_m": self.max_m,
                f"{prefix}_yaw_rms_rad": self.yaw_rms_rad, f"{prefix}_yaw_max_rad": self.yaw_max_rad,
                f"{prefix}_samples": self.samples}


def compose_chain(outer: PoseSeries, inner: PoseSeries) -> PoseSeries:
    """``outer ∘ inner`` at the inner series' stamps: e.g. map → odom composed with odom → base_link.

    The outer transform is interpolated at each inner stamp within its span (a single
    outer sample holds for all times, like a static transform); inner samples outside the
    outer span are left out, as tf2 refuses to extrapolate.

    Raises:
        PoseSeriesError: either series is empty.
    """
    if not len(outer) or not len(inner):
        raise PoseSeriesError(f"cannot compose an empty series ({len(outer)} outer, {len(inner)} inner poses)")
    if len(outer) == 1:
        t = inner.t_s
        at = np.repeat(outer.poses, len(t), axis=0)
    else:
        t = inner.t_s[(inner.t_s >= outer.t_s[0]) & (inner.t_s <= outer.t_s[-1])]
        at = outer.interpolate(t).poses
    keep = np.isin(inner.t_s, t)
    composed = se2_compose(at, inner.poses[keep])
    return PoseSeries(t, composed[:, :2], composed[:, 2])


def absolute_trajectory_error(estimate: PoseSeries, truth: PoseSeries, estimate_to_world: PoseLike = (0.0, 0.0, 0.0),
                              max_gap_s: float = 0.1) -> AteResult:
    """ATE of ``estimate`` (in its own frame) against ``truth`` (in the world), without alignment.

    ``estimate_to_world`` is the estimate's frame in the world (x, y, yaw). Only estimate
    samples within the truth's span whose neighbouring truth samples are at most
    ``max_gap_s`` apart count; the truth is interpolated at their times.

    Raises:
        NoOverlapError: no estimate sample overlaps the truth (the message gives both spans).
        PoseSeriesError: a bad ``estimate_to_world`` or ``max_gap_s``.
    """
    t, est, ref = _matched(estimate, truth, estimate_to_world, max_gap_s)
    position = np.linalg.norm(est[:, :2] - ref[:, :2], axis=1)
    yaw = wrap_angles(est[:, 2] - ref[:, 2])
    return AteResult(_frozen(t), _frozen(position), _frozen(yaw), _rms(position), float(position.max()),
                           _rms(yaw), float(np.abs(yaw).max()), int(t.size))


@dataclass(frozen=True, eq=False)
class RpeResult:
    """Relative pose error over segments of ``segment_m`` of truth path, per metre of that path.

    When the matched trajectory is shorter than one segment, ``segments`` is 0 and the
    four statistics are None (JSON null), not NaN.
    """

    segment_m: float
    t_s: np.ndarray  # start time of each segment
    trans_error_m_per_m: np.ndarray
    rot_error_rad_per_m: np.ndarray
    trans_mean_m_per_m: float | None
    trans_max_m_per_m: float | None
    rot_mean_rad_per_m: float | None
    rot_max_rad_per_m: float | None
    segments: int

    def as_dict(self, prefix: str = "rpe") -> dict[str, float | int | None]:
        """The scalars, JSON-ready: ``{prefix}_trans_mean_m_per_m``, ``_trans_max_m_per_m``,
        ``_rot_mean_rad_per_m``, ``_rot_max_rad_per_m``, ``_segments``."""
        return {f"{prefix}_trans_mean_m_per_m": self.trans_mean_m_per_m,
                f"{prefix}_trans_max_m_per_m": self.trans_max_m_per_m,
                f"{prefix}_rot_mean_rad_per_m": self.rot_mean_rad_per_m,
                f"{prefix}_rot_max_rad_per_m": self.rot_max_rad_per_m,
                f"{prefix}_segments": self.segments}


def _segment_ends(length_m: np.ndarray, segment_m: float) -> tuple[np.ndarray, np.ndarray]:
    """(i, j) pairs: j is the first sample whose path length from i reaches ``segment_m``."""
    j = np.searchsorted(length_m, length_m + segment_m, side="left")
    i = np.flatnonzero(j < length_m.size)
    return i, j[i]


def relative_pose_error(estimate: PoseSeries, truth: PoseSeries, estimate_to_world: PoseLike = (0.0, 0.0, 0.0),
                        segment_m: float = 1.0, max_gap_s: float = 0.1) -> RpeResult:
    """RPE: for each matched sample i and the first j at least ``segment_m`` of truth path later,
    the error ``(T_i⁻¹ T_j)⁻¹ (E_i⁻¹ E_j)``; its translation norm and |yaw| divided by the truth
    path length from i to j (m/m and rad/m).

    Samples are matched as in :func:`absolute_trajectory_error`.

    Raises:
        NoOverlapError: no estimate sample overlaps the truth.
        PoseSeriesError: ``segment_m`` is not positive, a bad ``estimate_to_world`` or ``max_gap_s``.
    """
    if not (math.isfinite(segment_m) and segment_m > 0):
        raise PoseSeriesError(f"segment_m must be a positive number, not {segment_m}")
    t, est, ref = _matched(estimate, truth, estimate_to_world, max_gap_s)
    length = PoseSeries.from_poses(t, ref).cumulative_length_m()
    i, j = _segment_ends(length, segment_m)
    error = se2_compose(se2_inverse(se2_relative(ref[i], ref[j])), se2_relative(est[i], est[j]))
    driven = length[j] - length[i]
    trans = np.linalg.norm(error[:, :2], axis=1) / driven
    rot = np.abs(error[:, 2]) / driven

    if not i.size:
        return RpeResult(float(segment_m), _frozen(t[i]), _frozen(trans), _frozen(rot),
                             None, None, None, None, 0)
    return RpeResult(float(segment_m), _frozen(t[i]), _frozen(trans), _frozen(rot), float(trans.mean()),
                         float(trans.max()), float(rot.mean()), float(rot.max()), int(i.size))
