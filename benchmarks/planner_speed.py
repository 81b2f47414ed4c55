"""Planner speed (issue 11): time per plan on the `office` map at 0.05 m.

The global costmap is built as the planner server builds it (``config/nav2_params.yaml``'s
``global_costmap``: the static layer of ``maps/office.yaml`` and inflation 0.55 m, cost
scaling 3.0, robot radius 0.3). Start and goal pairs are drawn from the free cells (cost 0)
of the costmap's largest traversable region, so every pair has a path; each plan is timed
whole (A* search, string pulling, smoothing), as the planner server answers a
``compute_path_to_pose`` request. Target: p95 ≤ 50 ms.

    ./pppbot env python benchmarks/planner_speed.py [--map maps/office.yaml] [--plans 200] [--seed 0]

Prints one JSON object on its last line.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import yaml

from pppbot_common.maps import load_map
from pppbot_nav.costmap.grid import Costmap
from pppbot_nav.costmap.layers import InflationLayer, LayeredCostmap, StaticLayer
from pppbot_nav.planner.grid_astar import GridPlanner

ROOT = Path(__file__).resolve().parent.parent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--map", default=str(ROOT / "maps" / "office.yaml"))
    parser.add_argument("--plans", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    config = yaml.safe_load((ROOT / "config" / "nav2_params.yaml").read_text())
    costmap_params = config["global_costmap"]["global_costmap"]["ros__parameters"]
    inflation = costmap_params["inflation_layer"]

    grid, _ = load_map(args.map)
    static = StaticLayer()
    static.set_map(grid)
    master = Costmap.filled(grid.width * grid.resolution, grid.height * grid.resolution, grid.resolution,
                            (grid.origin[0], grid.origin[1]), 255)
    layers = LayeredCostmap(master, [static, InflationLayer(inflation["inflation_radius"],
                                                            inflation["cost_scaling_factor"],
                                                            costmap_params["robot_radius"])])
    t0 = time.perf_counter()
    costmap = layers.update()
    planner = GridPlanner()
    planner.set_costmap(costmap)
    prepare_ms = (time.perf_counter() - t0) * 1000

    labels = planner.components
    largest = np.argmax(np.bincount(labels[labels > 0])[1:]) + 1
    free = np.argwhere((costmap.costs == 0) & (labels == largest))
    rng = np.random.default_rng(args.seed)
    times, lengths = [], []
    for _ in range(args.plans):
        a, b = free[rng.integers(len(free), size=2)]
        start = (costmap.origin[0] + (a[1] + 0.5) * grid.resolution, costmap.origin[1] + (a[0] + 0.5) * grid.resolution)
        goal = (costmap.origin[0] + (b[1] + 0.5) * grid.resolution, costmap.origin[1] + (b[0] + 0.5) * grid.resolution)
        t = time.perf_counter()
        plan = planner.plan(start, goal)
        times.append((time.perf_counter() - t) * 1000)
        lengths.append(plan.length_m)
    ms = np.array(times)
    result = {
        "benchmark": "planner_speed",
        "map": Path(args.map).name,
        "cells": int(costmap.costs.size),
        "plans": args.plans,
        "plan_median_ms": round(float(np.median(ms)), 2),
        "plan_p95_ms": round(float(np.percentile(ms, 95)), 2),
        "plan_max_ms": round(float(ms.max()), 2),
        "path_length_median_m": round(float(np.median(lengths)), 2),
        "costmap_and_components_ms": round(prepare_ms, 1),
        "target_p95_ms": 50.0,
    }
    result["ok"] = result["plan_p95_ms"] <= 50.0
    print(f"{args.plans} plans on {result['map']} ({costmap.width} × {costmap.height} cells): median "
          f"{result['plan_median_ms']} ms, p95 {result['plan_p95_ms']} ms, max {result['plan_max_ms']} ms")
    print(json.dumps(result))


if __name__ == "__main__":
    main()
