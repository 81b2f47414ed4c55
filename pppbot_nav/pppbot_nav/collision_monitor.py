"""Collision monitoring as Nav2's ``collision_monitor`` does it, without ROS.

Zones are shapes in the robot's base frame (a polygon, or a circle around the origin), each with
an action. Given the obstacle points of the sources (N x 2 arrays, metres, base frame) and a
command, :func:`decide` returns what to send:

* **stop**: zero, when at least ``min_points`` points are inside the zone;
* **slowdown**: the command times ``slowdown_ratio``, on the same condition;
* **limit**: the command scaled (all axes by one factor, so its curvature is kept) to at most
  ``linear_limit`` m/s and ``angular_limit`` rad/s, on the same condition;
* **approach**: the zone is the robot's footprint. The command is simulated forward in steps of
  ``simulation_time_step_s`` for up to ``time_before_collision_s``; at the first step where
  ``min_points`` points fall inside the moved footprint, the collision time is taken as that of
  the last free pose, and the command is scaled by ``collision_time / time_before_collision_s``.
  The robot then always reaches the obstacle no sooner than ``time_before_collision_s`` ahead;
  as it nears, it slows to a stop one step's travel short of contact.

Zones are visited in order; the first stop wins outright, otherwise a zone's command replaces the
current one only when it is safer (slower: :meth:`Velocity.safer_than`). A source whose data is
missing, stale or cannot be placed in the base frame stops the robot (Nav2 Jazzy's "invalid
source"). After a stop, the zero command is repeated for ``stop_pub_timeout_s`` and then no longer
sent (:class:`StopRepeat`).
"""
from __future__ import annotations

import enum
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from pppbot_nav.errors import CollisionMonitorError

#: The polygon name of a stop for a source without valid data (Nav2's).
INVALID_SOURCE = "invalid source"
#: Vertices of a circle's outline (for visualization only: containment uses the radius).
CIRCLE_OUTLINE_VERTICES = 32


class ActionType(enum.IntEnum):
    """A zone's action; the values are nav2_msgs/CollisionMonitorState's."""
    DO_NOTHING = 0
    STOP = 1
    SLOWDOWN = 2
    APPROACH = 3
    LIMIT = 4


#: ``action_type`` parameter values.
ACTION_NAMES = {"stop": ActionType.STOP, "slowdown": ActionType.SLOWDOWN, "limit": ActionType.LIMIT,
                "approach": ActionType.APPROACH}


@dataclass(frozen=True)
class Velocity:
    """A planar command: x and y in m/s, yaw rate in rad/s."""
    x_mps: float = 0.0
    y_mps: float = 0.0
    yaw_radps: float = 0.0

    def scaled(self, factor: float) -> Velocity:
        return Velocity(self.x_mps * factor, self.y_mps * factor, self.yaw_radps * factor)

    def is_zero(self) -> bool:
        return self.x_mps == 0.0 and self.y_mps == 0.0 and self.yaw_radps == 0.0

    def is_finite(self) -> bool:
        return all(math.isfinite(v) for v in (self.x_mps, self.y_mps, self.yaw_radps))

    def safer_than(self, other: Velocity) -> bool:
        """Slower: a smaller linear speed, or the same with a smaller turn rate."""
        mine, theirs = math.hypot(self.x_mps, self.y_mps), math.hypot(other.x_mps, other.y_mps)
        return mine < theirs or (mine == theirs and abs(self.yaw_radps) < abs(other.yaw_radps))


# ---------------------------------------------------------------------- shapes
def _within(points: np.ndarray, radius_m: float) -> np.ndarray:
    """The points (N x 2) no farther than ``radius_m`` from the origin (a margin kept for rounding):
    the only ones a shape of that reach can hold."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    bound = radius_m * (1.0 + 1e-9) + 1e-9
    return pts[np.einsum("ij,ij->i", pts, pts) <= bound * bound]


def points_in_polygon(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """Which of ``points`` (N x 2) lie inside the polygon ``vertices`` (M x 2, in order, closed
    implicitly): the even-odd rule, a ray cast along +x crossing the edges (Shimrat, "Algorithm
    112: position of point relative to polygon", CACM 5(8), 1962). A bool array of N."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    inside = np.zeros(len(pts), dtype=bool)
    if len(pts) == 0:
        return inside
    x, y = pts[:, 0:1], pts[:, 1:2]
    x0, y0 = vertices[:, 0], vertices[:, 1]
    x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
    straddles = (y0 > y) != (y1 > y)  # N x M: the edge crosses the point's horizontal line
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
    crossings = straddles & (x < x_cross)
    return np.asarray(crossings.sum(axis=1) % 2 == 1)


@dataclass(frozen=True)
class PolygonShape:
    """A polygon; ``vertices`` M x 2 (m), M >= 3."""
    vertices: np.ndarray = field(compare=False)

    def contains(self, points: np.ndarray) -> np.ndarray:
        return points_in_polygon(points, self.vertices)

    @property
    def reach_m(self) -> float:
        """No point farther than this from the base frame's origin is inside."""
        return float(np.max(np.hypot(self.vertices[:, 0], self.vertices[:, 1])))

    def outline(self) -> np.ndarray:
        return self.vertices


@dataclass(frozen=True)
class CircleShape:
    """A circle of ``radius_m`` around the base frame's origin (boundary excluded)."""
    radius_m: float

    def contains(self, points: np.ndarray) -> np.ndarray:
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        return np.asarray(np.einsum("ij,ij->i", pts, pts) < self.radius_m ** 2)

    @property
    def reach_m(self) -> float:
        return self.radius_m

    def outline(self) -> np.ndarray:
        angles = np.linspace(0.0, 2.0 * math.pi, CIRCLE_OUTLINE_VERTICES, endpoint=False)
        return self.radius_m * np.column_stack([np.cos(angles), np.sin(angles)])


Shape = PolygonShape | CircleShape


def parse_points(value: object) -> np.ndarray:
    """Polygon vertices from a ``points`` parameter: Nav2 Jazzy's string ``"[[x, y], [x, y], ...]"``
    or the older flat list ``[x1, y1, x2, y2, ...]``. An M x 2 array, M >= 3.

    Raises:
        CollisionMonitorError: malformed, odd-length, fewer than three vertices or not finite
            (parameter ``points``).
    """
    if isinstance(value, str):
        try:
            pairs = json.loads(value)
        except json.JSONDecodeError as exc:
            raise CollisionMonitorError(f"points {value!r} is not of the form '[[x, y], [x, y], ...]': {exc}",
                                        "points") from exc
        if not (isinstance(pairs, list) and all(isinstance(p, list) and len(p) == 2 for p in pairs)):
            raise CollisionMonitorError(f"points {value!r} is not of the form '[[x, y], [x, y], ...]'", "points")
        flat = [c for pair in pairs for c in pair]
    elif isinstance(value, (list, tuple)):
        flat = list(value)
        if len(flat) % 2:
            raise CollisionMonitorError(f"points {flat} has an odd number of coordinates: x, y pairs expected",
                                        "points")
    else:
        raise CollisionMonitorError(f"points must be '[[x, y], ...]' or [x1, y1, x2, y2, ...], not {value!r}",
                                    "points")
    if not all(isinstance(c, (int, float)) and not isinstance(c, bool) for c in flat):
        raise CollisionMonitorError(f"points {value!r} has a coordinate that is not a number", "points")
    vertices = np.asarray(flat, dtype=float).reshape(-1, 2)
    if len(vertices) < 3 or not np.isfinite(vertices).all():
        raise CollisionMonitorError(f"points {value!r}: a polygon needs at least 3 finite vertices", "points")
    return vertices


# ----------------------------------------------------------------------- zones
@dataclass(frozen=True)
class Zone:
    """One of Nav2's polygons: a shape, its action and the action's settings."""
    name: str
    shape: Shape
    action: ActionType
    min_points: int = 4
    slowdown_ratio: float = 0.5
    linear_limit_mps: float = 0.5
    angular_limit_radps: float = 0.5
    time_before_collision_s: float = 2.0
    simulation_time_step_s: float = 0.1
    enabled: bool = True
    #: The sources whose points count (empty: all).
    sources: tuple[str, ...] = ()

    def validate(self) -> None:
        """Raises:
            CollisionMonitorError: naming the setting (its ROS parameter name, relative to the zone).
        """
        if self.action is ActionType.DO_NOTHING:
            raise CollisionMonitorError(f"zone '{self.name}' has no action", "action_type")
        if self.min_points < 1:
            raise CollisionMonitorError(f"min_points {self.min_points} must be at least 1", "min_points")
        if isinstance(self.shape, CircleShape) and not (math.isfinite(self.shape.radius_m) and self.shape.radius_m > 0):
            raise CollisionMonitorError(f"radius {self.shape.radius_m} must be a positive number of metres", "radius")
        checks = (("slowdown_ratio", self.slowdown_ratio, 0.0, 1.0), ("linear_limit", self.linear_limit_mps, 0.0, None),
                  ("angular_limit", self.angular_limit_radps, 0.0, None),
                  ("time_before_collision", self.time_before_collision_s, 0.0, None),
                  ("simulation_time_step", self.simulation_time_step_s, 0.0, None))
        for name, value, low, high in checks:
            if not math.isfinite(value) or value < low or (high is not None and value > high):
                allowed = f"in [{low}, {high}]" if high is not None else f">= {low}"
                raise CollisionMonitorError(f"{name} {value} must be a finite number {allowed}", name)
        if self.action is ActionType.APPROACH and not (self.time_before_collision_s > 0
                                                        and self.simulation_time_step_s > 0):
            raise CollisionMonitorError("an approach zone needs time_before_collision and simulation_time_step > 0",
                                        "time_before_collision" if self.time_before_collision_s <= 0
                                        else "simulation_time_step")

    def points_of(self, points: Mapping[str, np.ndarray]) -> np.ndarray:
        """The points of the zone's sources, K x 2."""
        chosen = [p for name, p in points.items() if not self.sources or name in self.sources]
        return np.concatenate(chosen) if chosen else np.empty((0, 2))

    def triggered(self, points: np.ndarray) -> bool:
        return int(self.shape.contains(_within(points, self.shape.reach_m)).sum()) >= self.min_points

    def collision_time(self, points: np.ndarray, command: Velocity) -> float | None:
        """Seconds until the footprint, moving with ``command``, holds ``min_points`` points (the
        time of the last free simulated pose; 0 when already hit), or None within the horizon.
        Only points the moved footprint can reach are tested, at every simulated pose at once."""
        step = self.simulation_time_step_s
        steps = int(math.floor(self.time_before_collision_s / step + 1e-9)) + 1
        poses = np.empty((steps, 4))  # x, y, cos(yaw), sin(yaw) of each simulated pose
        x = y = yaw = 0.0
        for k in range(steps):
            # The pose one step on (Euler, as Nav2): the points as the moved robot sees them.
            x += (command.x_mps * math.cos(yaw) - command.y_mps * math.sin(yaw)) * step
            y += (command.x_mps * math.sin(yaw) + command.y_mps * math.cos(yaw)) * step
            yaw += command.yaw_radps * step
            poses[k] = (x, y, math.cos(yaw), math.sin(yaw))
        travel = float(np.max(np.hypot(poses[:, 0], poses[:, 1])))
        near = _within(points, self.shape.reach_m + travel)
        if int(self.shape.contains(_within(near, self.shape.reach_m)).sum()) >= self.min_points:
            return 0.0
        if len(near) < self.min_points:
            return None
        xs, ys, c, s = (poses[:, i:i + 1] for i in range(4))
        dx, dy = near[:, 0] - xs, near[:, 1] - ys  # steps x n
        seen = np.stack([c * dx + s * dy, -s * dx + c * dy], axis=-1).reshape(-1, 2)
        hits = self.shape.contains(seen).reshape(steps, len(near)).sum(axis=1)
        first = np.flatnonzero(hits >= self.min_points)
        return float(first[0] * step) if len(first) else None

    def outline(self) -> np.ndarray:
        return self.shape.outline()


@dataclass(frozen=True)
class Decision:
    """What to send: the action, the zone that chose it ("" for none) and the command."""
    action: ActionType
    polygon_name: str
    velocity: Velocity


def decide(zones: Sequence[Zone], command: Velocity, points: Mapping[str, np.ndarray],
           invalid_sources: Sequence[str] = ()) -> Decision:
    """The action for ``command`` given each source's points (base frame, K x 2 each).

    ``invalid_sources``: sources without usable data; any stops the robot.
    """
    if invalid_sources:
        return Decision(ActionType.STOP, INVALID_SOURCE, Velocity())
    decision = Decision(ActionType.DO_NOTHING, "", command)
    for zone in zones:
        if not zone.enabled:
            continue
        zone_points = zone.points_of(points)
        safe: Velocity | None = None
        if zone.action is ActionType.APPROACH:
            time_s = zone.collision_time(zone_points, command)
            if time_s is not None:
                safe = command.scaled(time_s / zone.time_before_collision_s)
        elif zone.triggered(zone_points):
            if zone.action is ActionType.STOP:
                return Decision(ActionType.STOP, zone.name, Velocity())
            safe = command.scaled(zone.slowdown_ratio if zone.action is ActionType.SLOWDOWN
                                  else limit_ratio(command, zone.linear_limit_mps, zone.angular_limit_radps))
        if safe is not None and safe.safer_than(decision.velocity):
            decision = Decision(zone.action, zone.name, safe)
    return decision


def limit_ratio(command: Velocity, linear_limit_mps: float, angular_limit_radps: float) -> float:
    """The one factor in [0, 1] that brings ``command`` within both limits."""
    ratio = 1.0
    linear = math.hypot(command.x_mps, command.y_mps)
    if linear > 0.0:
        ratio = min(ratio, linear_limit_mps / linear)
    if command.yaw_radps != 0.0:
        ratio = min(ratio, angular_limit_radps / abs(command.yaw_radps))
    return max(0.0, ratio)


def describe(decision: Decision, zones: Sequence[Zone]) -> str:
    """The log line for a new decision (Nav2's wording)."""
    zone = next((z for z in zones if z.name == decision.polygon_name), None)
    if decision.action is ActionType.STOP and decision.polygon_name == INVALID_SOURCE:
        return ("Robot to stop due to invalid source: a source has no data yet, none newer than its timeout, "
                "or none that can be transformed to the base frame")
    if decision.action is ActionType.STOP:
        return f"Robot to stop due to {decision.polygon_name} polygon"
    if decision.action is ActionType.SLOWDOWN and zone is not None:
        return f"Robot to slowdown for {zone.slowdown_ratio * 100:g} percents due to {zone.name} polygon"
    if decision.action is ActionType.LIMIT:
        return f"Robot to limit speed due to {decision.polygon_name} polygon"
    if decision.action is ActionType.APPROACH and zone is not None:
        return f"Robot to approach for {zone.time_before_collision_s:g} seconds away from collision"
    return "Robot to continue normal operation"


# --------------------------------------------------------------------- sources
def scan_points(ranges: Sequence[float], angle_min: float, angle_increment: float, range_min: float,
                range_max: float) -> np.ndarray:
    """A LaserScan's returns within [range_min, range_max] as K x 2 points in the sensor's frame
    (NaN and infinite ranges are no return)."""
    r = np.asarray(ranges, dtype=float)
    angles = angle_min + angle_increment * np.arange(len(r))
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(r) & (r >= range_min) & (r <= range_max)
    return np.column_stack([r[valid] * np.cos(angles[valid]), r[valid] * np.sin(angles[valid])])


def transformed(points: np.ndarray, pose: tuple[float, float, float]) -> np.ndarray:
    """``points`` (K x 2, in a frame whose pose in the target frame is ``pose`` (x, y, yaw)) in the target frame."""
    x, y, yaw = pose
    c, s = math.cos(yaw), math.sin(yaw)
    return np.column_stack([x + c * points[:, 0] - s * points[:, 1], y + s * points[:, 0] + c * points[:, 1]])


def fresh(stamp_s: float, now_s: float, timeout_s: float) -> bool:
    """Whether data stamped ``stamp_s`` is still valid at ``now_s`` (a timeout of 0: always)."""
    return timeout_s == 0.0 or now_s - stamp_s <= timeout_s


class StopRepeat:
    """Whether to send a decision: a zero command is sent for ``timeout_s`` after the robot was
    told to stop, then no longer (Nav2's stop_pub_timeout); anything else always."""

    def __init__(self, timeout_s: float) -> None:
        self.timeout_s = timeout_s
        self._stopped_at_s: float | None = None

    def allow(self, velocity: Velocity, now_s: float) -> bool:
        if not velocity.is_zero():
            self._stopped_at_s = None
            return True
        if self._stopped_at_s is None:
            self._stopped_at_s = now_s
        return now_s - self._stopped_at_s <= self.timeout_s
