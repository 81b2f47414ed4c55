"""Follow a route's polyline with a differential drive: pure pursuit plus turning on the spot.

The driver sees the true pose (the evaluation gives it ground truth), so it
exercises mapping and localization without depending on navigation. It keeps
a position along the route that only moves forward, searching a short window
ahead for the closest point, so a route that passes the same corridor twice is
followed in order. When the lookahead point is far off the heading the robot
stops and turns first (a lidar sees a sharp turn better than a wide skid).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pppbot_common.se2 import wrap_angle
from pppbot_eval.errors import RouteError


@dataclass(frozen=True)
class DriverSettings:
    speed_mps: float = 0.3
    max_angular_rps: float = 0.8
    lookahead_m: float = 0.4
    goal_tolerance_m: float = 0.1
    turn_in_place_rad: float = 0.6  # heading error above which the robot stops and turns
    heading_gain: float = 2.0  # rad/s per rad while turning in place
    search_window_m: float = 1.0  # how far ahead the closest-point search looks

    def __post_init__(self) -> None:
        for name in ("speed_mps", "max_angular_rps", "lookahead_m", "goal_tolerance_m", "turn_in_place_rad",
                     "heading_gain", "search_window_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise RouteError(f"route driver: {name} must be a positive number, not {value}")


class RouteDriver:
    def __init__(self, points: np.ndarray, settings: DriverSettings = DriverSettings()) -> None:
        """``points``: (N ≥ 2, 2) polyline in the frame of the poses given to :meth:`command`."""
        points = np.asarray(points, dtype=float)
        keep = np.concatenate([[True], np.linalg.norm(np.diff(points, axis=0), axis=1) > 1e-9])
        self.points = points[keep]
        if len(self.points) < 2:
            raise RouteError("a route needs at least two distinct points")
        self.settings = settings
        segments = np.diff(self.points, axis=0)
        self._seg_len = np.linalg.norm(segments, axis=1)
        self._seg_dir = segments / self._seg_len[:, None]
        self._cumulative = np.concatenate([[0.0], np.cumsum(self._seg_len)])
        self.length_m = float(self._cumulative[-1])
        self.travelled_m = 0.0  # progress along the route (m), never decreases
        self.finished = False

    @property
    def progress(self) -> float:
        return 1.0 if self.finished else min(1.0, self.travelled_m / self.length_m)

    def point_at(self, s: float) -> np.ndarray:
        s = min(max(s, 0.0), self.length_m)
        i = int(min(np.searchsorted(self._cumulative, s, side="right") - 1, len(self._seg_len) - 1))
        return np.asarray(self.points[i] + self._seg_dir[i] * (s - self._cumulative[i]))

    def _advance(self, xy: np.ndarray) -> None:
        """Move the route position to the closest point within the search window ahead."""
        s0, s1 = self.travelled_m, self.travelled_m + self.settings.search_window_m
        first = max(int(np.searchsorted(self._cumulative, s0, side="right")) - 1, 0)
        last = min(int(np.searchsorted(self._cumulative, s1, side="right")), len(self._seg_len))
        best_s, best_d = s0, math.inf
        for i in range(first, last):
            t = float(np.clip((xy - self.points[i]) @ self._seg_dir[i], 0.0, self._seg_len[i]))
            s = self._cumulative[i] + t
            if not s0 <= s <= s1:
                s = min(max(s, s0), s1)
            d = float(np.linalg.norm(self.point_at(s) - xy))
            if d < best_d - 1e-12:
                best_s, best_d = s, d
        self.travelled_m = max(self.travelled_m, best_s)

    def command(self, x: float, y: float, yaw: float) -> tuple[float, float]:
        """(linear m/s, angular rad/s) for the robot at (x, y, yaw); (0, 0) once finished."""
        if self.finished:
            return 0.0, 0.0
        p = self.settings
        xy = np.array([x, y])
        self._advance(xy)
        end = self.points[-1]
        to_end = float(np.linalg.norm(end - xy))
        if self.length_m - self.travelled_m <= p.lookahead_m and to_end <= p.goal_tolerance_m:
            self.finished = True
            return 0.0, 0.0
        target = self.point_at(self.travelled_m + p.lookahead_m)
        dx, dy = target - xy
        distance = math.hypot(dx, dy)
        alpha = wrap_angle(math.atan2(dy, dx) - yaw)
        if abs(alpha) > p.turn_in_place_rad:
            return 0.0, float(np.clip(p.heading_gain * alpha, -p.max_angular_rps, p.max_angular_rps))
        curvature = 2.0 * math.sin(alpha) / max(distance, 1e-6)
        speed = p.speed_mps
        if self.length_m - self.travelled_m < p.lookahead_m:
            speed = min(speed, max(0.05, to_end))  # slow down onto the last point
        if abs(curvature) > 1e-9:
            speed = min(speed, p.max_angular_rps / abs(curvature))
        return speed, speed * curvature
