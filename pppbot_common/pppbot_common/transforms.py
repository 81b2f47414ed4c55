"""A planar transform tree with history: tf2's buffer for a 2D robot, without ROS.

Each frame has one parent; each edge keeps a time series of (x, y, yaw) (the
child's pose in the parent) for ``cache_s`` seconds, or one timeless value when
static. :meth:`TransformBuffer.lookup` composes the chain between two frames at
a time, interpolating every dynamic edge linearly (yaw the short way round),
as ``tf2::BufferCore::lookupTransform`` does. Heights, roll and pitch are left
out: pppbot's frames that matter for mapping and localization are planar.
"""
from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field

from pppbot_common.errors import TransformError
from pppbot_common.se2 import wrap_angle

Pose2D = tuple[float, float, float]


def compose(a: Pose2D, b: Pose2D) -> Pose2D:
    """``a ∘ b`` as a tuple: :func:`pppbot_common.se2.se2_compose` for one pose, on floats (numpy's
    arrays cost some twenty times the arithmetic here, and the buffer composes every lookup)."""
    ax, ay, ayaw = a
    bx, by, byaw = b
    c, s = math.cos(ayaw), math.sin(ayaw)
    return ax + c * bx - s * by, ay + s * bx + c * by, wrap_angle(ayaw + byaw)


def inverse(a: Pose2D) -> Pose2D:
    """``a⁻¹`` as a tuple (:func:`pppbot_common.se2.se2_inverse` for one pose)."""
    ax, ay, ayaw = a
    c, s = math.cos(ayaw), math.sin(ayaw)
    return -c * ax - s * ay, s * ax - c * ay, wrap_angle(-ayaw)


@dataclass
class _Edge:
    parent: str
    static: bool
    times: list[float] = field(default_factory=list)
    poses: list[Pose2D] = field(default_factory=list)

    def at(self, time_s: float | None, child: str) -> Pose2D:
        if self.static or time_s is None:
            return self.poses[-1]
        times = self.times
        if time_s < times[0] or time_s > times[-1]:
            side = "before the oldest" if time_s < times[0] else "after the newest"
            raise TransformError(f"{self.parent} → {child} at t = {time_s:.3f} s is {side} transform "
                                 f"(have {times[0]:.3f} … {times[-1]:.3f} s)")
        i = bisect.bisect_left(times, time_s)
        if times[i] == time_s:
            return self.poses[i]
        t0, t1 = times[i - 1], times[i]
        (x0, y0, a0), (x1, y1, a1) = self.poses[i - 1], self.poses[i]
        f = (time_s - t0) / (t1 - t0)
        return x0 + f * (x1 - x0), y0 + f * (y1 - y0), wrap_angle(a0 + f * wrap_angle(a1 - a0))


class TransformBuffer:
    def __init__(self, cache_s: float = 10.0) -> None:
        if not (math.isfinite(cache_s) and cache_s > 0):
            raise ValueError(f"cache_s must be a positive number of seconds, not {cache_s}")
        self.cache_s = cache_s
        self._edges: dict[str, _Edge] = {}

    def set_transform(self, parent: str, child: str, stamp_s: float, pose: Pose2D, static: bool = False) -> None:
        """Record ``child``'s pose in ``parent`` at ``stamp_s`` (a new parent replaces the old edge).

        Raises:
            ValueError: a non-finite pose or time, or a frame as its own parent.
        """
        if parent == child:
            raise ValueError(f"frame '{child}' cannot be its own parent")
        if not all(math.isfinite(v) for v in (*pose, stamp_s)):
            raise ValueError(f"non-finite transform {parent} → {child}: {pose} at {stamp_s}")
        edge = self._edges.get(child)
        if edge is None or edge.parent != parent or edge.static != static:
            edge = self._edges[child] = _Edge(parent, static)
        if static:
            edge.times, edge.poses = [stamp_s], [pose]
            return
        if edge.times and stamp_s <= edge.times[-1]:
            i = bisect.bisect_left(edge.times, stamp_s)
            if i < len(edge.times) and edge.times[i] == stamp_s:
                edge.poses[i] = pose
            else:
                edge.times.insert(i, stamp_s)
                edge.poses.insert(i, pose)
        else:
            edge.times.append(stamp_s)
            edge.poses.append(pose)
        keep = bisect.bisect_left(edge.times, edge.times[-1] - self.cache_s)
        if keep > 0:
            del edge.times[:keep], edge.poses[:keep]

    def frames(self) -> set[str]:
        return set(self._edges) | {e.parent for e in self._edges.values()}

    def _chain(self, frame: str) -> list[str]:
        chain = [frame]
        while chain[-1] in self._edges:
            chain.append(self._edges[chain[-1]].parent)
            if len(chain) > 1000:
                raise TransformError(f"the transform tree has a loop through '{frame}'")
        return chain

    def _to_ancestor(self, chain: list[str], ancestor: str, time_s: float | None) -> Pose2D:
        pose: Pose2D = (0.0, 0.0, 0.0)
        for child in chain[:chain.index(ancestor)]:
            pose = compose(self._edges[child].at(time_s, child), pose)
        return pose

    def lookup(self, target: str, source: str, time_s: float | None = None) -> Pose2D:
        """Pose of frame ``source`` in frame ``target`` at ``time_s`` (None: the newest of each edge).

        Raises:
            TransformError: unknown or unconnected frames, or a time outside an edge's history.
        """
        up_source, up_target = self._chain(source), self._chain(target)
        common = next((f for f in up_source if f in up_target), None)
        if common is None:
            known = ", ".join(sorted(self.frames())) or "none"
            raise TransformError(f"no transform from '{source}' to '{target}' (known frames: {known})")
        source_in_common = self._to_ancestor(up_source, common, time_s)
        target_in_common = self._to_ancestor(up_target, common, time_s)
        return compose(inverse(target_in_common), source_in_common)

    def latest_time(self, target: str, source: str) -> float | None:
        """The newest time at which every dynamic edge between the frames has data (None: all static)."""
        up_source, up_target = self._chain(source), self._chain(target)
        common = next((f for f in up_source if f in up_target), None)
        if common is None:
            raise TransformError(f"no transform from '{source}' to '{target}'")
        edges = [self._edges[f] for f in (*up_source[:up_source.index(common)], *up_target[:up_target.index(common)])]
        newest = [e.times[-1] for e in edges if not e.static]
        return min(newest) if newest else None
