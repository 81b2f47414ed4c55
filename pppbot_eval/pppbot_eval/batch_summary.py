"""A batch's summary: one row per run, figures per world family and scenario and overall.

What a run's report holds is the evaluation's (:mod:`pppbot_eval.ros.cli`); here each scenario's
headline figures are collected (:data:`FIGURES`), their median taken per group, and the whole
written as a table for the terminal, ``summary.csv`` (a row per run) and ``summary.json``.
"""
from __future__ import annotations

import csv
import json
import statistics
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

#: Each scenario's headline figures, whose median a group's summary gives.
FIGURES: dict[str, tuple[str, ...]] = {
    "map": ("map_f1",),
    "drive": ("ate_rms_m", "final_position_error_m"),
    "slam": ("map_f1", "ate_rms_m", "ate_max_m"),
    "localization": ("amcl_rms_m", "converged_after_m"),
    "navigation": ("success_rate", "mean_time_ratio", "barn_score"),
}
#: Figures whose mean is the benchmark's own figure too (BARN ranks by the mean score over its worlds).
MEAN_FIGURES = ("barn_score",)
#: Report values that depend on the machine and the moment, not on the scenario: a batch's reports
#: are the same on any number of workers or machines apart from these (and the folders they name).
WALL_KEYS = ("wall_seconds", "real_time_factor")


@dataclass(frozen=True)
class RunResult:
    """A run of the batch as it ended: its report (or why there is none)."""

    id: str
    scenario: str
    world: str
    family: str
    axes: Mapping[str, Any]
    report: Mapping[str, Any]
    resumed: bool = False  # kept from an earlier, interrupted batch (--resume)

    @property
    def ok(self) -> bool:
        return bool(self.report.get("ok"))

    @property
    def failure(self) -> str | None:
        return self.report.get("failure")


def _number(value: Any) -> float | None:
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else None


def _median(values: Sequence[float]) -> float | None:
    return round(statistics.median(values), 4) if values else None


def group_figures(results: Sequence[RunResult]) -> dict[str, Any]:
    """A group's figures: runs, how many ok, collisions, sim and wall time, each figure's median."""
    figures: dict[str, Any] = {
        "runs": len(results),
        "ok": sum(r.ok for r in results),
        "ok_fraction": round(sum(r.ok for r in results) / len(results), 4) if results else None,
        "collisions": sum(int(_number(r.report.get("collisions")) or 0) for r in results),
        "sim_seconds": round(sum(_number(r.report.get("sim_seconds")) or 0.0 for r in results), 1),
        "wall_seconds": round(sum(_number(r.report.get("wall_seconds")) or 0.0 for r in results), 1),
    }
    goals = [g for r in results for g in r.report.get("goal_results") or []]
    if goals:
        figures["goals"] = len(goals)
        figures["goals_reached"] = sum(bool(g.get("reached")) for g in goals)
    for key in sorted({k for r in results for k in FIGURES.get(r.scenario, ())}):
        values = [v for r in results if (v := _number(r.report.get(key))) is not None]
        if values:
            figures[f"{key}_median"] = _median(values)
            if key in MEAN_FIGURES:
                figures[f"{key}_mean"] = round(statistics.fmean(values), 4)
    return figures


def summarize(results: Sequence[RunResult], wall_seconds: float) -> dict[str, Any]:
    """The batch's summary: overall, per scenario, per world family and scenario, and the failures."""
    by_scenario: dict[str, list[RunResult]] = {}
    by_family: dict[str, dict[str, list[RunResult]]] = {}
    for r in results:
        by_scenario.setdefault(r.scenario, []).append(r)
        by_family.setdefault(r.family, {}).setdefault(r.scenario, []).append(r)
    overall = group_figures(results)
    return {
        "runs": len(results), "ok": overall["ok"], "wall_seconds": round(wall_seconds, 1),
        "runs_per_hour": round(len(results) * 3600.0 / wall_seconds, 1) if wall_seconds > 0 else None,
        "overall": overall,
        "scenarios": {s: group_figures(rs) for s, rs in sorted(by_scenario.items())},
        "families": {f: {s: group_figures(rs) for s, rs in sorted(ss.items())} for f, ss in sorted(by_family.items())},
        "failures": {r.id: r.failure for r in results if not r.ok},
    }


def table(summary: Mapping[str, Any]) -> str:
    """The summary per world family and scenario as a text table."""
    keys = sorted({k for ss in summary["families"].values() for g in ss.values() for k in g
                   if k.endswith(("_median", "_mean"))})
    header = ["family", "scenario", "runs", "ok", "collisions", *[k.replace("_median", "") for k in keys]]
    rows = [[family, scenario, str(g["runs"]), str(g["ok"]), str(g["collisions"]),
             *[_cell(g.get(k)) for k in keys]]
            for family, ss in summary["families"].items() for scenario, g in ss.items()]
    o = summary["overall"]
    rows.append(["all", "", str(o["runs"]), str(o["ok"]), str(o["collisions"]), *[_cell(o.get(k)) for k in keys]])
    widths = [max(len(row[i]) for row in [header, *rows]) for i in range(len(header))]
    return "\n".join("  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)).rstrip()
                     for row in [header, *rows])


def _cell(value: Any) -> str:
    return "-" if value is None else f"{value:.4g}" if isinstance(value, float) else str(value)


def comparable_reports(out: Path) -> dict[str, dict[str, Any]]:
    """Every run's report in a batch's folder ``out``, by run id, without what depends on the machine and
    the moment (:data:`WALL_KEYS`, and ``out`` itself as ``<out>``): two batches of one spec, on any
    number of workers or machines, give equal ones."""
    found = {}
    for path in sorted(out.glob("**/report.json")):
        report = json.loads(path.read_text().replace(str(out), "<out>"))
        found[str(path.parent.relative_to(out))] = {k: v for k, v in report.items() if k not in WALL_KEYS}
    return found


def write_files(out: Path, results: Sequence[RunResult], summary: Mapping[str, Any]) -> str:
    """``summary.csv`` (a row per run) and ``summary.json`` in ``out``; the JSON as one line."""
    keys = sorted({k for r in results for k in FIGURES.get(r.scenario, ())})
    axes = sorted({k for r in results for k in r.axes})
    with open(out / "summary.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["id", "scenario", "world", "family", *axes, "ok", "failure", "collisions", *keys,
                         "sim_seconds", "wall_seconds"])
        for r in results:
            writer.writerow([r.id, r.scenario, r.world, r.family, *[json.dumps(r.axes.get(a)) for a in axes],
                             r.ok, r.failure or "", r.report.get("collisions", ""),
                             *[r.report.get(k, "") for k in keys], r.report.get("sim_seconds", ""),
                             r.report.get("wall_seconds", "")])
    line = json.dumps(summary)
    (out / "summary.json").write_text(line + "\n")
    return line
