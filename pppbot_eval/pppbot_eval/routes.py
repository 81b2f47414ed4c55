"""Waypoint routes of a world: ``<world>.routes.yaml`` next to the world file.

    world: maze
    routes:
      coverage:
        description: visits every cell of the maze and returns to the start
        start: {x: 0.7, y: 0.7, yaw: 0.0}   # spawn pose (m, m, rad), world frame
        waypoints:                          # world frame (m); the start is implied first
          - [2.1, 0.7]
          - [2.1, 2.1]

The first route is the default. ``tools/make_routes.py`` generates the shipped files.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from pppbot_eval.errors import RouteError


@dataclass(frozen=True)
class Route:
    name: str
    start: tuple[float, float, float]  # x, y, yaw in the world
    waypoints: np.ndarray  # (N, 2), world frame, the start not included
    description: str = ""

    @property
    def points(self) -> np.ndarray:
        """The whole polyline: start, then the waypoints."""
        return np.vstack([np.array(self.start[:2])[None, :], self.waypoints])

    @property
    def length_m(self) -> float:
        return float(np.linalg.norm(np.diff(self.points, axis=0), axis=1).sum())

    def as_yaml(self) -> dict[str, Any]:
        x, y, yaw = self.start
        return {"description": self.description,
                "start": {"x": round(x, 3), "y": round(y, 3), "yaw": round(yaw, 4)},
                "waypoints": [[round(float(a), 3), round(float(b), 3)] for a, b in self.waypoints]}


def routes_file(world_file: Path) -> Path:
    return world_file.with_name(f"{world_file.stem}.routes.yaml")


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise RouteError(f"{where}: must be a finite number, not {value!r}")
    return float(value)


def _route(name: str, body: Any, where: str) -> Route:
    if not isinstance(body, dict):
        raise RouteError(f"{where}: must be a mapping with 'start' and 'waypoints'")
    unknown = sorted(set(body) - {"description", "start", "waypoints"})
    if unknown:
        raise RouteError(f"{where}: unknown key(s) {', '.join(unknown)} (allowed: description, start, waypoints)")
    start = body.get("start")
    if not isinstance(start, dict) or not {"x", "y"} <= set(start) or set(start) - {"x", "y", "yaw"}:
        raise RouteError(f"{where}.start: must be a mapping with x, y and optionally yaw, not {start!r}")
    pose = tuple(_number(start.get(k, 0.0), f"{where}.start.{k}") for k in ("x", "y", "yaw"))
    points = body.get("waypoints")
    if not isinstance(points, list) or not points:
        raise RouteError(f"{where}.waypoints: must be a non-empty list of [x, y] pairs")
    rows = []
    for i, point in enumerate(points):
        if not isinstance(point, list) or len(point) != 2:
            raise RouteError(f"{where}.waypoints[{i}]: must be [x, y], not {point!r}")
        rows.append([_number(v, f"{where}.waypoints[{i}]") for v in point])
    route = Route(name, (pose[0], pose[1], pose[2]), np.array(rows), str(body.get("description", "")))
    if route.length_m <= 1e-9:
        raise RouteError(f"{where}.waypoints: every waypoint is the start; a route must go somewhere")
    return route


def load_routes(path: Path) -> list[Route]:
    """Every route in a routes file, in file order.

    Raises:
        RouteError: missing file, bad YAML, or a bad field (named).
    """
    try:
        document = yaml.safe_load(path.read_text())
    except FileNotFoundError as exc:
        raise RouteError(f"{path}: no routes file for this world (make one with tools/make_routes.py "
                         "or give --route-file)") from exc
    except (OSError, yaml.YAMLError) as exc:
        raise RouteError(f"{path}: unreadable routes file: {exc}") from exc
    if not isinstance(document, dict) or not isinstance(document.get("routes"), dict) or not document["routes"]:
        raise RouteError(f"{path}: must be a mapping with a non-empty 'routes' mapping")
    return [_route(str(name), body, f"{path}: routes.{name}") for name, body in document["routes"].items()]


def select_route(routes: list[Route], name: str | None, path: Path) -> Route:
    """The route called ``name``, or the first one when ``name`` is None.

    Raises:
        RouteError: no such route; the message lists the known ones.
    """
    if name is None:
        return routes[0]
    for route in routes:
        if route.name == name:
            return route
    raise RouteError(f"{path}: no route '{name}' (routes: {', '.join(r.name for r in routes)})")


def save_routes(path: Path, world: str, routes: list[Route], header: str = "") -> None:
    document = {"world": world, "routes": {r.name: r.as_yaml() for r in routes}}
    text = yaml.safe_dump(document, sort_keys=False, default_flow_style=None, width=100)
    path.write_text((f"# {header}\n" if header else "") + text)
