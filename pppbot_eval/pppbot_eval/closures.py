"""Loop closures judged against ground truth: which ones a SLAM run got wrong.

A loop closure ties an older keyframe to a newer one that sees the same place. After the
graph is solved, the two keyframes' relative pose (the *corrected* one) should be what it
truly is; a closure taken in a place that only looks the same (the next identical corridor,
a repeated room) pulls them to a relation the world does not have. A closure is **false**
when its corrected relative pose is off the true one by more than :data:`FALSE_CLOSURE_M` or
:data:`FALSE_CLOSURE_RAD`; what the closure itself claimed (its match) is measured too. No ROS
here: the eval's SLAM report and the real-log benchmark (``benchmarks/carmen_slam.py``) share it.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from pppbot_common.se2 import se2_compose, se2_inverse, wrap_angles
from pppbot_slam.pose_graph import Edge

#: A closure whose corrected relative pose is off by more than this is false (m, rad: 5°).
FALSE_CLOSURE_M = 0.5
FALSE_CLOSURE_RAD = math.radians(5.0)


@dataclass(frozen=True)
class ClosureError:
    """One closure against ground truth: the corrected relative pose's error and the claim's (m, rad)."""

    source: int
    target: int
    position_m: float
    yaw_rad: float
    claimed_position_m: float
    claimed_yaw_rad: float

    @property
    def false(self) -> bool:
        """The solved graph holds the two keyframes wrong: the harm a closure did (or failed to undo)."""
        return self.position_m > FALSE_CLOSURE_M or abs(self.yaw_rad) > FALSE_CLOSURE_RAD

    @property
    def false_claim(self) -> bool:
        """The match itself was wrong: a place taken for another, whether or not the graph followed it."""
        return self.claimed_position_m > FALSE_CLOSURE_M or abs(self.claimed_yaw_rad) > FALSE_CLOSURE_RAD


def _error(estimate: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """Position (m) and wrapped yaw (rad) of ``truth⁻¹ ∘ estimate``, two relative poses."""
    off = se2_compose(se2_inverse(truth), estimate)
    return float(math.hypot(off[0], off[1])), float(wrap_angles(off[2]))


def closure_errors(poses: np.ndarray, truth: np.ndarray, closures: Sequence[Edge]) -> list[ClosureError]:
    """Each closure's error: ``poses`` (K, 3) the keyframes' solved poses, ``truth`` (K, 3) their true
    poses (any fixed frame each: only relative poses are compared).

    Raises:
        ValueError: ``poses`` and ``truth`` differ in shape, or a closure names no keyframe of them.
    """
    poses, truth = np.asarray(poses, dtype=float), np.asarray(truth, dtype=float)
    if poses.shape != truth.shape or poses.ndim != 2 or poses.shape[1] != 3:
        raise ValueError(f"poses {poses.shape} and truth {truth.shape} must both be (K, 3)")
    errors = []
    for c in closures:
        if not (0 <= c.source < len(poses) and 0 <= c.target < len(poses)):
            raise ValueError(f"closure {c.source} -> {c.target}: the run has {len(poses)} keyframes")
        true = se2_compose(se2_inverse(truth[c.source]), truth[c.target])
        solved = se2_compose(se2_inverse(poses[c.source]), poses[c.target])
        errors.append(ClosureError(c.source, c.target, *_error(solved, true), *_error(np.asarray(c.relative), true)))
    return errors


def closure_figures(errors: Sequence[ClosureError]) -> dict[str, Any]:
    """The report's figures: ``closures``, ``false_closures`` (solved wrong), ``false_claims`` (wrong
    matches), the largest corrected and claimed errors (m; None without closures) and the false
    ones' keyframes (older, newer)."""
    return {
        "closures": len(errors),
        "false_closures": sum(e.false for e in errors),
        "false_claims": sum(e.false_claim for e in errors),
        "closure_max_error_m": round(max(e.position_m for e in errors), 4) if errors else None,
        "closure_max_claim_error_m": round(max(e.claimed_position_m for e in errors), 4) if errors else None,
        "false_closure_keyframes": [[e.source, e.target] for e in errors if e.false],
    }
