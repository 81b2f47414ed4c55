"""The pose graph as RViz markers (``~/graph_visualization``, visualization_msgs/MarkerArray)."""
from __future__ import annotations

from typing import Any

import numpy as np
from geometry_msgs.msg import Point
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from pppbot_slam.pose_graph import Edge

#: Localization scans of the rolling buffer: green spheres (slam_toolbox draws localization nodes in
#: a colour of their own too).
LOCALIZATION_RGBA = (0.1, 0.8, 0.2, 1.0)


def graph_markers(poses: np.ndarray, edges: list[Edge], frame: str, stamp: Any,
                  localization_poses: np.ndarray | None = None) -> MarkerArray:
    """The pose graph for RViz: keyframes (blue spheres), matching edges (thin blue lines) and
    loop closures (red lines); with ``localization_poses`` ((N, 3), localization mode) the rolling
    buffer's scans too (green spheres). One marker each, replaced on every update."""
    points = [Point(x=float(x), y=float(y)) for x, y, _ in poses]
    layers: list[tuple[int, float, tuple[float, float, float, float], list[Point]]] = [
        (Marker.SPHERE_LIST, 0.1, (0.1, 0.3, 1.0, 1.0), points),
        (Marker.LINE_LIST, 0.02, (0.1, 0.3, 1.0, 0.6), [points[i] for e in edges if not e.loop
                                                        for i in (e.source, e.target)]),
        (Marker.LINE_LIST, 0.03, (1.0, 0.1, 0.1, 1.0), [points[i] for e in edges if e.loop
                                                        for i in (e.source, e.target)])]
    if localization_poses is not None:
        layers.append((Marker.SPHERE_LIST, 0.12, LOCALIZATION_RGBA,
                       [Point(x=float(x), y=float(y)) for x, y, _ in localization_poses]))
    markers = []
    for ident, (kind, width, rgba, layer_points) in enumerate(layers):
        marker = Marker(type=kind, action=Marker.ADD, id=ident, ns="slam_toolbox")
        marker.header.frame_id, marker.header.stamp = frame, stamp
        marker.pose.orientation.w = 1.0
        marker.scale.x = marker.scale.y = marker.scale.z = width
        marker.color = ColorRGBA(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3])
        marker.points = layer_points
        markers.append(marker)
    return MarkerArray(markers=markers)
