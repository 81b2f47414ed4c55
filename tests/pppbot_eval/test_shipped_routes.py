"""The shipped routes: start at the spawn pose, close their loop, and keep clear of every wall."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

from pppbot_eval.map_quality import occupied_cells
from pppbot_eval.routes import load_routes
from pppbot_sim.ground_truth import ground_truth_map
from pppbot_sim.simulation import load_world
from pppbot_sim.worlds import model_paths

WORLDS = Path(__file__).resolve().parents[2] / "worlds"
#: ppp_bot's chassis corners are 0.25 m from base_link; the routes keep this much more.
MIN_CLEARANCE_M = 0.25 + 0.02


def sampled(points: np.ndarray, step_m: float = 0.02) -> np.ndarray:
    pieces = [np.linspace(a, b, max(2, int(np.ceil(np.linalg.norm(b - a) / step_m)) + 1))
              for a, b in zip(points[:-1], points[1:], strict=True)]
    return np.vstack(pieces)


@pytest.mark.parametrize("world", ["maze", "room", "office", "cones"])
def test_route_is_collision_free_covers_and_closes_its_loop(world: str):
    path = WORLDS / f"{world}.sdf"
    route = load_routes(WORLDS / f"{world}.routes.yaml")[0]
    assert route.start == (0.0, 0.0, 0.0)  # launch_sim's default spawn: SLAM's map frame is the world's
    np.testing.assert_allclose(route.waypoints[-1], [0.0, 0.0])
    spec, _ = load_world(path, model_paths(path))
    truth = ground_truth_map(spec.compile(), 0.05, 0.2)
    clearance = ndimage.distance_transform_edt(~occupied_cells(truth), sampling=truth.resolution)
    points = sampled(route.points)
    rows, cols = truth.cell_of(points[:, 0], points[:, 1])
    # Distance from a cell centre to the nearest wall cell's centre, less a whole cell: half a
    # cell to that wall cell's edge, and half a cell for where in its own cell the point lies.
    nearest_wall_m = clearance[rows, cols] - truth.resolution
    assert nearest_wall_m.min() >= MIN_CLEARANCE_M, f"the route passes {nearest_wall_m.min():.2f} m from a wall"
    # Coverage: most of the free space is within 3 m of the route.
    route_mask = np.zeros(truth.data.shape, dtype=bool)
    route_mask[rows, cols] = True
    near_route = ndimage.distance_transform_edt(~route_mask, sampling=truth.resolution) <= 3.0
    inside = ndimage.binary_fill_holes(occupied_cells(truth)) & ~occupied_cells(truth)
    if world == "cones":  # open ground: the area among the cones
        inside = np.zeros_like(inside)
        inside[20:-20, 20:-20] = ~occupied_cells(truth)[20:-20, 20:-20]
    assert near_route[inside].mean() > 0.95


def test_empty_world_has_a_closed_square():
    route = load_routes(WORLDS / "empty.routes.yaml")[0]
    assert route.start == (0.0, 0.0, 0.0) and route.length_m == pytest.approx(12.0)
    np.testing.assert_allclose(route.waypoints[-1], [0.0, 0.0])
