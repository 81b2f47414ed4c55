"""Routes files and the route driver, on a kinematic unicycle (no physics, no ROS)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from pppbot_eval.driver import DriverSettings, RouteDriver
from pppbot_eval.routes import Route, RouteError, load_routes, routes_file, save_routes, select_route


def drive(driver: RouteDriver, pose: tuple[float, float, float], dt: float = 0.02,
          max_steps: int = 20000) -> np.ndarray:
    """Integrate a unicycle under the driver's commands; the poses visited (N, 3)."""
    x, y, yaw = pose
    poses = [(x, y, yaw)]
    for _ in range(max_steps):
        v, w = driver.command(x, y, yaw)
        if driver.finished:
            break
        x += v * math.cos(yaw) * dt
        y += v * math.sin(yaw) * dt
        yaw += w * dt
        poses.append((x, y, yaw))
    return np.array(poses)


def distance_to_polyline(points: np.ndarray, polyline: np.ndarray) -> np.ndarray:
    a, b = polyline[:-1], polyline[1:]
    ab = b - a
    t = np.clip(np.einsum("pkd,kd->pk", points[:, None, :] - a[None], ab) / (ab ** 2).sum(1), 0, 1)
    closest = a[None] + t[..., None] * ab[None]
    return np.linalg.norm(points[:, None, :] - closest, axis=2).min(axis=1)


def test_driver_follows_a_square_and_stops_on_the_last_point():
    square = np.array([[0, 0], [2, 0], [2, 2], [0, 2], [0, 0]], dtype=float)
    driver = RouteDriver(square, DriverSettings(speed_mps=0.3))
    poses = drive(driver, (0.0, 0.0, 0.0))
    assert driver.finished and driver.progress == 1.0
    assert np.linalg.norm(poses[-1, :2] - square[-1]) <= 0.1
    # Turning on the spot at the corners keeps the robot on the route.
    assert distance_to_polyline(poses[:, :2], square).max() < 0.12
    assert driver.command(*poses[-1]) == (0.0, 0.0)


def test_driver_goes_out_and_back_along_the_same_corridor_in_order():
    out_and_back = np.array([[0, 0], [3, 0], [3, 0.5], [0, 0.5]], dtype=float)
    driver = RouteDriver(out_and_back)
    poses = drive(driver, (0.0, 0.0, 0.0))
    assert driver.finished
    # It reached the far end before coming back (no shortcut to the nearby return leg).
    assert poses[:, 0].max() > 2.85
    assert np.linalg.norm(poses[-1, :2] - [0, 0.5]) <= 0.1


def test_driver_respects_speed_and_turn_limits():
    settings = DriverSettings(speed_mps=0.25, max_angular_rps=0.7)
    driver = RouteDriver(np.array([[0, 0], [1, 1], [2, -1], [3, 1]], dtype=float), settings)
    x, y, yaw = 0.0, 0.0, math.pi  # facing away: turns first
    v, w = driver.command(x, y, yaw)
    assert v == 0.0 and abs(w) == pytest.approx(0.7)
    poses = drive(driver, (x, y, yaw))
    speeds = np.linalg.norm(np.diff(poses[:, :2], axis=0), axis=1) / 0.02
    assert speeds.max() <= 0.25 + 1e-9
    assert np.abs(np.diff(poses[:, 2])).max() / 0.02 <= 0.7 + 1e-9


def test_driver_rejects_degenerate_routes_and_settings():
    with pytest.raises(ValueError, match="two distinct points"):
        RouteDriver(np.array([[1.0, 1.0], [1.0, 1.0]]))
    with pytest.raises(ValueError, match="speed_mps must be a positive number, not -1"):
        DriverSettings(speed_mps=-1)


def test_routes_file_round_trip(tmp_path: Path):
    route = Route("loop", (0.5, -0.5, 0.25), np.array([[1.0, 0.0], [1.0, 1.0]]), "a small loop")
    path = tmp_path / "box.routes.yaml"
    save_routes(path, "box", [route, Route("other", (0, 0, 0), np.array([[2.0, 2.0]]))], "made by a test")
    routes = load_routes(path)
    assert [r.name for r in routes] == ["loop", "other"]
    loaded = select_route(routes, None, path)
    assert loaded.start == route.start and loaded.description == "a small loop"
    np.testing.assert_array_equal(loaded.waypoints, route.waypoints)
    assert loaded.length_m == pytest.approx(math.hypot(0.5, 0.5) + 1.0)
    assert select_route(routes, "other", path).name == "other"
    with pytest.raises(RouteError, match="no route 'nope' \\(routes: loop, other\\)"):
        select_route(routes, "nope", path)
    assert routes_file(Path("/w/maze.sdf")) == Path("/w/maze.routes.yaml")


@pytest.mark.parametrize("text, message", [
    ("routes: {}", "non-empty 'routes'"),
    ("routes: {a: {start: {x: 0}, waypoints: [[1, 1]]}}", "routes.a.start: must be a mapping with x, y"),
    ("routes: {a: {start: {x: 0, y: 0}, waypoints: []}}", "routes.a.waypoints: must be a non-empty list"),
    ("routes: {a: {start: {x: 0, y: 0}, waypoints: [[1, .nan]]}}", "waypoints\\[0\\]: must be a finite number"),
    ("routes: {a: {start: {x: 0, y: 0}, waypoints: [[1, 2, 3]]}}", "waypoints\\[0\\]: must be \\[x, y\\]"),
    ("routes: {a: {start: {x: 0, y: 0}, waypoints: [[1, 2]], speed: 3}}", "unknown key\\(s\\) speed"),
    ("routes: [", "unreadable routes file"),
    ("routes: {a: {start: {x: 1, y: 2}, waypoints: [[1, 2]]}}", "every waypoint is the start"),
])
def test_bad_routes_files_name_the_field(tmp_path: Path, text: str, message: str):
    path = tmp_path / "w.routes.yaml"
    path.write_text(text)
    with pytest.raises(RouteError, match=message):
        load_routes(path)


def test_missing_routes_file_says_how_to_make_one(tmp_path: Path):
    with pytest.raises(RouteError, match="no routes file for this world.*make_routes"):
        load_routes(tmp_path / "none.routes.yaml")
