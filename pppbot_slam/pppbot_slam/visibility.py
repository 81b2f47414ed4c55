"""Whether scans placed by a match can all be right: free space one saw where another saw a wall.

A scan matcher scores how many hits of a scan land on the walls of a map; it never asks what
the scan's beams passed through. Two places that look alike (the next corridor of a maze) can
line up most of their walls, and the alias then shows in what does not line up: a beam of one
scan that returned well beyond a wall the other saw — it would have passed through that wall.
A true match has next to none of these (a wall seen from both sides is both seen, not passed).

:func:`see_through_fraction` counts them both ways between one scan and a set of others, each
placed in the map. Only beams that returned are believed (a beam without a return may have
missed a dark or glassy surface), a beam counts only against a surface it crosses, not one
it grazes, and only surfaces half a metre long or more count (walls, not people). No ROS here.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pppbot_common.se2 import PoseLike, se2_compose
from pppbot_slam.likelihood_field import rotate, scan_normals
from pppbot_slam.occupancy import BeamClasses, ScanRays

#: A beam passed a surface when it returned this much beyond it (m): a few cells of the map,
#: more than a refined match is off by.
SEE_THROUGH_TOLERANCE_M = 0.15
#: A beam crosses a surface (rather than grazing along it) when its direction and the surface
#: normal are within 60° (|cos| above this): along a wall a beam's path brushes the wall's cells.
CROSSING_COS = 0.5
#: Only hits on surfaces this long (m) count: runs of hits less than SURFACE_GAP_M apart.
MIN_SURFACE_M = 0.5
SURFACE_GAP_M = 0.3
#: A beam stands for the directions within this many of its spacings (the edge of a 180° scan).
BEAM_REACH = 0.75


@dataclass(frozen=True)
class View:
    """A scan placed in the map: where its sensor was, and its rays (sensor frame)."""

    sensor_pose: np.ndarray  # (x, y, yaw) in the map
    rays: ScanRays

    def _beams(self, limit_m: float) -> tuple[np.ndarray, np.ndarray, BeamClasses]:
        """The beams' directions as angles in increasing order, that order, and what each beam does."""
        angles = np.arctan2(self.rays.directions[:, 1], self.rays.directions[:, 0])
        order = np.argsort(angles)
        return angles[order], order, self.rays.classify(limit_m)

    def surfaces(self, limit_m: float) -> tuple[np.ndarray, np.ndarray]:
        """The scan's hits (within ``limit_m``) on surfaces at least :data:`MIN_SURFACE_M` long,
        in the map, with their normals: runs of consecutive hits less than :data:`SURFACE_GAP_M`
        apart. A person's legs or a chair's are shorter: they may have moved between the scans."""
        _, order, classes = self._beams(limit_m)
        hit = order[classes.hit[order]]
        local = self.rays.directions[hit] * self.rays.ranges_m[hit, None]
        if len(local) < 3:
            return np.zeros((0, 2)), np.zeros((0, 2))
        normals = scan_normals(local, max_gap_m=SURFACE_GAP_M)
        breaks = np.flatnonzero(np.hypot(*np.diff(local, axis=0).T) >= SURFACE_GAP_M) + 1
        long_enough = np.zeros(len(local), dtype=bool)
        for start, stop in zip(np.r_[0, breaks], np.r_[breaks, len(local)], strict=True):
            run = local[start:stop]
            long_enough[start:stop] = float(np.hypot(*(run[-1] - run[0]))) >= MIN_SURFACE_M
        yaw = float(self.sensor_pose[2])
        return (np.asarray(rotate(local[long_enough], yaw)) + self.sensor_pose[:2],
                np.asarray(rotate(normals[long_enough], yaw)))

    def passed(self, points: np.ndarray, normals: np.ndarray, limit_m: float) -> tuple[int, int]:
        """Of ``points`` (map frame, with unit surface ``normals``): how many this scan had in view
        (:meth:`in_view`) and how many of those its beams passed through a surface they cross."""
        through, visible = self.in_view(points, limit_m, normals)
        return int(through.sum()), int(visible.sum())

    def in_view(self, points: np.ndarray, limit_m: float,
                normals: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Per point of ``points`` (map frame): whether this scan's beams passed through it (only
        with ``normals``: across a surface, well beyond it), and whether this scan had it in view:
        its beams there returned no nearer than the point, less the tolerance. The beams around a
        point are its nearest in direction and the one either side: all must have returned (within
        ``limit_m``) and all must reach past it, so a corner or a wall's end is not a beam through
        a wall. Two boolean arrays (P,)."""
        points = np.asarray(points, dtype=float).reshape(-1, 2)
        nothing = np.zeros(len(points), dtype=bool)
        if len(points) == 0:
            return nothing, nothing
        angles, order, classes = self._beams(limit_m)
        lengths = np.where(classes.hit, classes.length_m, np.nan)[order]
        beams = len(angles)
        if beams < 3:
            return nothing, nothing
        spacing = float(np.median(np.diff(angles)))
        full_circle = angles[-1] - angles[0] + 1.5 * spacing >= 2 * math.pi
        local = np.asarray(rotate(points - self.sensor_pose[:2], -float(self.sensor_pose[2])))
        ranges = np.hypot(local[:, 0], local[:, 1])
        bearings = np.arctan2(local[:, 1], local[:, 0])
        # The nearest beam: on a full circle the first and last beams are neighbours too.
        lookup = np.concatenate([[angles[-1] - 2 * math.pi], angles, [angles[0] + 2 * math.pi]]) if full_circle \
            else angles
        after = np.clip(np.searchsorted(lookup, bearings), 1, len(lookup) - 1)
        nearest = after - (bearings - lookup[after - 1] < lookup[after] - bearings)
        in_view = np.abs(bearings - lookup[nearest]) <= BEAM_REACH * spacing
        if full_circle:
            nearest = (nearest - 1) % beams
            around = np.stack([(nearest - 1) % beams, nearest, (nearest + 1) % beams])
        else:
            in_view &= (nearest > 0) & (nearest < beams - 1)
            around = np.stack([np.maximum(nearest - 1, 0), nearest, np.minimum(nearest + 1, beams - 1)])
        reach = lengths[around]
        returned = ~np.isnan(reach).any(axis=0)
        shortest = np.where(np.isnan(reach), 0.0, reach).min(axis=0)
        visible = in_view & returned & (ranges < limit_m) & (shortest > ranges - SEE_THROUGH_TOLERANCE_M)
        if normals is None:
            return nothing, visible
        direction = local / np.maximum(ranges, 1e-9)[:, None]
        local_normals = np.asarray(rotate(np.asarray(normals, dtype=float).reshape(-1, 2),
                                          -float(self.sensor_pose[2])))
        crossing = np.abs((direction * local_normals).sum(axis=1)) > CROSSING_COS
        through = visible & crossing & (shortest > ranges + SEE_THROUGH_TOLERANCE_M)
        return through, visible


def view_of(base_pose: PoseLike, sensor_offset: PoseLike, rays: ScanRays) -> View:
    """The view of a scan taken with the robot's base at ``base_pose`` (map frame)."""
    return View(np.asarray(se2_compose(base_pose, sensor_offset), dtype=float), rays)


def see_through_fraction(view: View, others: Sequence[View], limit_m: float) -> float:
    """The share of surface hits one side saw that the other side's beams passed through:
    ``view`` against the surfaces of ``others``, and each of ``others`` against ``view``'s.
    0 when nothing was in view of the other."""
    points, normals = view.surfaces(limit_m)
    other_surfaces = [other.surfaces(limit_m) for other in others]
    through, visible = view.passed(np.vstack([p for p, _ in other_surfaces] + [np.zeros((0, 2))]),
                                   np.vstack([n for _, n in other_surfaces] + [np.zeros((0, 2))]), limit_m)
    for other in others:
        t, v = other.passed(points, normals, limit_m)
        through, visible = through + t, visible + v
    return through / visible if visible else 0.0

