"""An evaluation's report: ``report.json`` and PNG plots in the output directory.

Plots (matplotlib, Agg: no display needed):

* ``trajectory.png``: the true and the estimated path over the ground-truth map,
  the start, and where the robot touched something;
* ``error.png``: position and heading error of the estimate over sim time;
* ``map.png``: a map against the ground truth, true walls, mapped walls and false
  walls in three colours (scenarios that build or use a map).
"""
from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after choosing the backend)
import numpy as np  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from pppbot_common.maps import OCCUPIED, OccupancyGrid  # noqa: E402
from pppbot_eval.trajectory import AteResult, PoseSeries  # noqa: E402

TRUE_WALL = (0.55, 0.55, 0.55)
MAPPED_WALL = (0.10, 0.45, 0.85)
FALSE_WALL = (0.90, 0.15, 0.15)
DPI = 110


def json_safe(value: Any) -> Any:
    """Numbers JSON can carry: NaN and infinities become None, numpy scalars plain Python."""
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def write_json(path: Path, report: dict[str, Any]) -> str:
    """Write the report (pretty) and return it as one line (for stdout)."""
    safe = json_safe(report)
    path.write_text(json.dumps(safe, indent=2) + "\n")
    return json.dumps(safe, separators=(",", ":"))


def _figure_size(grid: OccupancyGrid) -> tuple[float, float]:
    aspect = grid.height / max(grid.width, 1)
    return 8.0, max(3.0, min(14.0, 8.0 * aspect)) + 0.6


def _draw_truth(ax: Any, truth_map: OccupancyGrid) -> None:
    walls = np.where(truth_map.data == OCCUPIED, 0.35, 1.0)
    ax.imshow(walls, origin="lower", extent=truth_map.extent, cmap="gray", vmin=0.0, vmax=1.0,
              interpolation="nearest")


def plot_trajectories(path: Path, truth_map: OccupancyGrid, truth: PoseSeries, estimate: PoseSeries | None,
                      estimate_label: str, collisions_xy: Sequence[tuple[float, float]] = (),
                      title: str = "", goals: Sequence[tuple[float, float, bool]] = ()) -> None:
    """True and estimated (already in the world frame) paths over the ground-truth map; navigation
    ``goals`` as (x, y, reached), numbered in order."""
    fig, ax = plt.subplots(figsize=_figure_size(truth_map))
    _draw_truth(ax, truth_map)
    ax.plot(truth.xy[:, 0], truth.xy[:, 1], color="black", lw=1.2, label="ground truth")
    if estimate is not None and len(estimate):
        ax.plot(estimate.xy[:, 0], estimate.xy[:, 1], color="tab:orange", lw=1.0, label=estimate_label)
    if len(truth):
        ax.plot(*truth.xy[0], marker="o", color="tab:green", ms=7, ls="none", label="start")
    if len(collisions_xy):
        points = np.asarray(collisions_xy)
        ax.plot(points[:, 0], points[:, 1], marker="x", color="red", ms=9, mew=2, ls="none", label="collision")
    for reached in (True, False):
        chosen = [(i, x, y) for i, (x, y, ok) in enumerate(goals, 1) if ok is reached]
        if chosen:
            ax.plot([x for _, x, _ in chosen], [y for _, _, y in chosen], marker="*", ls="none", ms=10,
                    color="tab:green" if reached else "red", label="goal reached" if reached else "goal missed")
            for i, x, y in chosen:
                ax.annotate(str(i), (x, y), textcoords="offset points", xytext=(4, 4), fontsize=6)
    ax.set_xlabel("x (m, world)")
    ax.set_ylabel("y (m, world)")
    ax.set_aspect("equal")
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def plot_errors(path: Path, error: AteResult, title: str = "") -> None:
    """Position error (m) and heading error (rad) over sim time."""
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    top.plot(error.t_s, error.position_error_m, color="tab:blue", lw=1.0)
    top.set_ylabel("position error (m)")
    top.set_title(title, fontsize=10)
    top.grid(alpha=0.3)
    bottom.plot(error.t_s, error.yaw_error_rad, color="tab:red", lw=1.0)
    bottom.set_ylabel("heading error (rad)")
    bottom.set_xlabel("sim time (s)")
    bottom.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def map_overlay_image(truth_map: OccupancyGrid, true_walls: np.ndarray, matched_walls: np.ndarray,
                      false_walls: np.ndarray) -> np.ndarray:
    """RGB (height, width, 3) in the truth grid: white background, then true, mapped and false walls."""
    image = np.ones((truth_map.height, truth_map.width, 3))
    image[true_walls] = TRUE_WALL
    image[matched_walls] = MAPPED_WALL
    image[false_walls] = FALSE_WALL
    return image


def plot_map_overlay(path: Path, truth_map: OccupancyGrid, true_walls: np.ndarray, matched_walls: np.ndarray,
                     false_walls: np.ndarray, title: str = "") -> None:
    fig, ax = plt.subplots(figsize=_figure_size(truth_map))
    ax.imshow(map_overlay_image(truth_map, true_walls, matched_walls, false_walls), origin="lower",
              extent=truth_map.extent, interpolation="nearest")
    ax.legend(handles=[Patch(color=TRUE_WALL, label="true walls"), Patch(color=MAPPED_WALL, label="mapped walls"),
                       Patch(color=FALSE_WALL, label="false walls")], loc="upper right", fontsize=8)
    ax.set_xlabel("x (m, world)")
    ax.set_ylabel("y (m, world)")
    ax.set_aspect("equal")
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
