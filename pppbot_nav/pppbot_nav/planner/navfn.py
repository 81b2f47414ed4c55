"""Nav2's NavFn planner (``nav2_navfn_planner/NavfnPlanner``): a navigation function on the costmap.

What it computes, as NavFn does:

* **Cost translation** (``NavFn::setCostmap``): a cell of cost ``c`` ≤ 252 weighs
  ``⌊COST_NEUTRAL + COST_FACTOR·c⌋`` = ``⌊50 + 0.8·c⌋`` (50 … 251); inscribed and lethal cells are
  obstacles (``COST_OBS`` 254); an unknown cell weighs 253 with ``allow_unknown``, else it is an
  obstacle; the outermost ring of cells is always an obstacle (``setupNavFn``). The robot's own
  cell is cleared to free first (``clearRobotCell``).
* **Potential propagation** from the robot's cell (navfn_planner hands NavFn the robot as its
  "goal" and the goal as its "start", so the potential is a cost-to-come and the tolerance search
  can read it round the goal). A cell of weight ``h`` whose lowest horizontal and lowest vertical
  neighbours are ``a`` ≤ ``b`` takes ``a + h`` when ``b − a ≥ h``, else ``a + h·(−0.2301·d² +
  0.5307·d + 0.7040)`` with ``d = (b − a)/h`` (a quadratic fit of the two-neighbour eikonal
  update). Cells wait in threshold buckets: a cell whose new potential (plus, with
  ``use_astar``, ``50 ×`` its distance in cells to the goal) is below the threshold queues its
  neighbours for the next cycle, else for the overflow; when a cycle leaves nothing below the
  threshold, it rises by ``2·COST_NEUTRAL`` and the whole overflow runs. A neighbour is queued
  when its potential exceeds the cell's by more than ``weight/√2``. Both orders stop once the
  goal has a potential (``calcNavFnDijkstra(atStart=true)``), or after ``max(nx·ny/20, nx + ny)``
  cycles. The buckets order the wave only roughly (a wave through costly cells runs ahead, one
  cell per threshold rise), so the first potential to reach the goal may come the costlier way:
  with inflation, paths cost up to 1.37 times the 8-connected optimum (measured on 134 maps, as
  with NavFn's own order), while where free cells cost alike they are within 0.5 % of it or
  shorter (any-angle).
* **Path** (``NavFn::calcPath``): from the goal cell, steps of 0.5 cell down the bilinearly
  interpolated, normalised potential gradient; where a cell of the 3×3 block has no potential, or
  the path oscillates, it steps to the lowest 8-neighbour instead; it ends on reaching a cell
  of potential below ``COST_NEUTRAL`` (the robot's cell), after ``4·max(nx, ny)`` steps at most.
  The last point is the goal (``smoothApproachToGoal``).
* **Tolerance** (``makePlan``): a goal without potential is replaced by the point of the square
  ``goal ± tolerance`` (sampled every resolution) nearest the goal that has one.

Where it differs from Nav2:

* the cells of one cycle are updated together, in two sweeps, the second reading the first's
  potentials (NavFn updates them one after another, each reading those updated before it),
  and a neighbour is queued if its potential after the sweeps exceeds the cell's by more than
  ``weight/√2``. Measured against a one-after-another port on 40 maps (60 and 120 cells a
  side): 0.89 … 1.02 times NavFn's cycles, every cell of a full Dijkstra-order flood within
  7.6 %, the goal's potential within 4 % in Dijkstra order and 3 % in A* order but on one map
  (14 %: which wave reaches the goal first is sensitive to the order). The 10,000-cell cap on
  each bucket is not kept (NavFn silently drops cells queued past it);
* a point's cell is ``floor`` and a cell's point its centre, as the costmap lays them out;
  NavFn rounds and drops the half cell, which shifts its paths half a cell towards the origin;
* the first point is the start itself (NavFn gives its cell);
* a start on a lethal cell raises StartOccupied (NavFn clears the robot's cell and plans out of
  it, as it does here from the inscribed zone, if a neighbour can be entered); GoalOccupied is raised when the goal
  and every cell of the tolerance square are obstacles (NavFn raises it for a lethal goal with
  tolerance 0 only, NoValidPath otherwise); a goal whose tolerance square the start's region
  does not reach fails at once (NavFn floods the region first, to the same end);
* ``max_planning_time`` is pppbot's (NavFn has no time limit); ``use_final_approach_orientation``
  is the node's concern (orientations), accepted here only;
* ``Plan.cost`` is the potential at the planned-to cell (NavFn's ``getLastPathCost``), in its
  units: 50 per free cell.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from pppbot_common.params import ParameterError, check_finite_range
from pppbot_nav.costmap.costs import INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE, NO_INFORMATION
from pppbot_nav.costmap.grid import Costmap
from pppbot_nav.planner.errors import (
    GoalOccupied,
    GoalOutsideMap,
    NoValidPath,
    PlannerTimedOut,
    StartOccupied,
    StartOutsideMap,
)
from pppbot_nav.planner.grid_astar import Plan

COST_NEUTRAL = 50
COST_FACTOR = 0.8
#: NavFn's obstacle weight; a cell of this weight or more is never entered.
COST_OBS = 254
#: The potential of a cell not reached.
POT_HIGH = 1.0e10
#: How much the bucket threshold rises when a bucket is done (NavFn's ``priInc``).
PRIORITY_INCREMENT = 2 * COST_NEUTRAL
#: The gradient-descent step (cells).
PATH_STEP = 0.5
INV_SQRT2 = 0.707106781
#: Sweeps over a cycle's cells (see the module doc).
SWEEPS = 2
#: Cycles between two looks at the clock.
CLOCK_INTERVAL = 32


@dataclass(frozen=True)
class NavfnSettings:
    tolerance: float = 0.5  # m: half the side of the square searched round an unreachable goal
    use_astar: bool = False
    allow_unknown: bool = True
    use_final_approach_orientation: bool = False  # the node's: orientations are not the core's
    max_planning_time: float = 2.0  # s: pppbot's, NavFn has none

    def validate(self) -> None:
        """Raises ParameterError naming a bad value."""
        check_finite_range("tolerance", self.tolerance, 0.0, 100.0)
        check_finite_range("max_planning_time", self.max_planning_time, 0.0, 3600.0, low_open=True)
        for name in ("use_astar", "allow_unknown", "use_final_approach_orientation"):
            if not isinstance(getattr(self, name), bool):
                raise ParameterError(name, getattr(self, name), "must be true or false")


def navfn_costs(costs: np.ndarray, allow_unknown: bool) -> np.ndarray:
    """NavFn's cell weights (int32, same shape) of costmap costs: 50 … 251, 253 for unknown
    (with ``allow_unknown``), ``COST_OBS`` for obstacles and the border ring."""
    c = np.asarray(costs, dtype=np.uint8)
    weights = np.full(c.shape, COST_OBS, dtype=np.int32)
    free = c < INSCRIBED_INFLATED_OBSTACLE
    weights[free] = np.minimum(np.floor(COST_NEUTRAL + COST_FACTOR * c[free]), COST_OBS - 1).astype(np.int32)
    if allow_unknown:
        weights[c == NO_INFORMATION] = COST_OBS - 1
    weights[0, :] = weights[-1, :] = weights[:, 0] = weights[:, -1] = COST_OBS
    return weights


def _quadratic_update(nb: np.ndarray, hf: np.ndarray) -> np.ndarray:
    """The planar-wave potential of cells from their 4-neighbours' (k, 4: left, right, down, up)."""
    tc = np.minimum(nb[:, 0], nb[:, 1])
    ta = np.minimum(nb[:, 2], nb[:, 3])
    low = np.minimum(ta, tc)
    div = np.minimum(np.abs(tc - ta) / hf, 1.0)
    interpolated = low + hf * ((-0.2301 * div + 0.5307) * div + 0.7040)
    return np.where(np.abs(tc - ta) >= hf, low + hf, interpolated)


def propagate(weights: np.ndarray, source: int, target: int, use_astar: bool,
              out_of_time: Callable[[], bool] = lambda: False) -> np.ndarray:
    """NavFn's potential (flat, float64; ``POT_HIGH`` where not reached) from flat cell ``source``,
    stopping once flat cell ``target`` has one.

    Raises:
        PlannerTimedOut: ``out_of_time()`` said so (asked every ``CLOCK_INTERVAL`` cycles).
    """
    ny, nx = weights.shape
    ns = nx * ny
    cost = weights.ravel().astype(np.float64)
    passable = cost < COST_OBS
    offsets = np.array([-1, 1, -nx, nx], dtype=np.int64)
    pot = np.full(ns, POT_HIGH)
    pending = np.zeros(ns, dtype=bool)
    pot[source] = 0.0
    first = source + offsets
    first = first[(first >= 0) & (first < ns)]
    cur = first[passable[first]]
    pending[cur] = True
    threshold = float(COST_OBS)
    heuristic = np.zeros(0)
    if use_astar:
        rows, cols = np.divmod(np.arange(ns), nx)
        heuristic = np.hypot(cols - target % nx, rows - target // nx) * COST_NEUTRAL
        threshold += float(heuristic[source])
    overflow: list[np.ndarray] = []
    for cycle in range(max(ns // 20, nx + ny)):
        if cur.size == 0:
            break
        if cycle % CLOCK_INTERVAL == 0 and out_of_time():
            raise PlannerTimedOut(f"the navigation function took longer than max_planning_time ({cycle} cycles)")
        pending[cur] = False
        around = cur[:, None] + offsets  # cells in a bucket are passable, so never on the border ring
        hf = cost[cur]
        improved = np.zeros(cur.size, dtype=bool)
        for _ in range(SWEEPS):
            new = _quadratic_update(pot[around], hf)
            better = new < pot[cur]
            pot[cur[better]] = new[better]
            improved |= better
        cells, around = cur[improved], around[improved]
        new, nb = pot[cells], pot[around]
        key = new + heuristic[cells] if use_astar else new
        push = nb > key[:, None] + INV_SQRT2 * cost[around]
        below = (key < threshold)[:, None]
        nxt = _queue(around[push & below], passable, pending)
        overflow.append(_queue(around[push & ~below], passable, pending))
        cur = nxt
        if cur.size == 0:
            threshold += PRIORITY_INCREMENT
            cur = np.concatenate(overflow)
            overflow = []
        if pot[target] < POT_HIGH:
            break
    return pot


def _queue(candidates: np.ndarray, passable: np.ndarray, pending: np.ndarray) -> np.ndarray:
    """The candidates that may be queued (passable, not pending, once each), marked pending."""
    cells = np.unique(candidates)
    cells = cells[passable[cells] & ~pending[cells]]
    pending[cells] = True
    return cells


def _round(v: float) -> int:
    """C's ``round``: halves away from zero."""
    return int(math.floor(v + 0.5)) if v >= 0 else -int(math.floor(-v + 0.5))


class _Gradient:
    """NavFn's ``gradCell``: the normalised downhill potential difference at a cell, cached."""

    def __init__(self, pot: np.ndarray, nx: int) -> None:
        self.pot, self.nx, self.ns = pot, nx, pot.size
        self.cache: dict[int, tuple[float, float]] = {}

    def __call__(self, n: int) -> tuple[float, float]:
        if n in self.cache:
            return self.cache[n]
        if n < self.nx or n >= self.ns - self.nx:
            return 0.0, 0.0
        p, nx = self.pot, self.nx
        cv = p[n]
        dx = dy = 0.0
        if cv >= POT_HIGH:
            dx = -COST_OBS if p[n - 1] < POT_HIGH else (COST_OBS if p[n + 1] < POT_HIGH else 0.0)
            dy = -COST_OBS if p[n - nx] < POT_HIGH else (COST_OBS if p[n + nx] < POT_HIGH else 0.0)
        else:
            dx = (p[n - 1] - cv if p[n - 1] < POT_HIGH else 0.0) + (cv - p[n + 1] if p[n + 1] < POT_HIGH else 0.0)
            dy = (p[n - nx] - cv if p[n - nx] < POT_HIGH else 0.0) + (cv - p[n + nx] if p[n + nx] < POT_HIGH else 0.0)
        norm = math.hypot(dx, dy)
        grad = (float(dx / norm), float(dy / norm)) if norm > 0 else (0.0, 0.0)
        if norm > 0:
            self.cache[n] = grad
        return grad


def descend(pot: np.ndarray, nx: int, start: int, goal: int, max_steps: int) -> np.ndarray | None:
    """NavFn's ``calcPath``: (K, 2) cell coordinates (x = column, y = row) from flat cell ``start``
    down the potential to flat cell ``goal`` (potential 0), or None where it fails."""
    ns = pot.size
    values = pot.tolist()
    grad = _Gradient(pot, nx)
    stc, dx, dy = start, 0.0, 0.0
    xs: list[float] = []
    ys: list[float] = []
    for _ in range(max_steps):
        nearest = min(max(stc + _round(dx) + nx * _round(dy), 0), ns - 1)
        if values[nearest] < COST_NEUTRAL:
            xs.append(goal % nx)
            ys.append(goal // nx)
            return np.column_stack([xs, ys]).astype(float)
        if stc <= nx or stc > ns - nx - 2:  # NavFn: stc < nx or > ns − nx (and then reads past the ends)
            return None
        xs.append(stc % nx + dx)
        ys.append(stc // nx + dy)
        oscillating = len(xs) > 2 and xs[-1] == xs[-3] and ys[-1] == ys[-3]
        block = [stc + r + c for r in (-nx, 0, nx) for c in (-1, 0, 1)]
        if oscillating or any(values[k] >= POT_HIGH for k in block):
            minc, minp = stc, math.trunc(values[stc])  # NavFn keeps the lowest potential as an int
            for k in block:
                if k != stc and values[k] < minp:
                    minc, minp = k, math.trunc(values[k])
            stc, dx, dy = minc, 0.0, 0.0
            if values[stc] >= POT_HIGH:
                return None
            continue
        (g00x, g00y), (g01x, g01y) = grad(stc), grad(stc + 1)
        (g10x, g10y), (g11x, g11y) = grad(stc + nx), grad(stc + nx + 1)
        x = (1.0 - dy) * ((1.0 - dx) * g00x + dx * g01x) + dy * ((1.0 - dx) * g10x + dx * g11x)
        y = (1.0 - dy) * ((1.0 - dx) * g00y + dx * g01y) + dy * ((1.0 - dx) * g10y + dx * g11y)
        if x == 0.0 and y == 0.0:
            return None
        ss = PATH_STEP / math.hypot(x, y)
        dx, dy = dx + x * ss, dy + y * ss
        if dx > 1.0:
            stc, dx = stc + 1, dx - 1.0
        if dx < -1.0:
            stc, dx = stc - 1, dx + 1.0
        if dy > 1.0:
            stc, dy = stc + nx, dy - 1.0
        if dy < -1.0:
            stc, dy = stc - nx, dy + 1.0
    return None


class NavfnPlanner:
    """Plans on the last costmap given; see the module doc."""

    plugin = "nav2_navfn_planner::NavfnPlanner"

    def __init__(self, settings: NavfnSettings | None = None,
                 clock: Callable[[], float] = time.perf_counter) -> None:
        self.settings = settings if settings is not None else NavfnSettings()
        self.settings.validate()
        self._clock = clock
        self.costmap: Costmap | None = None
        self.weights = np.zeros((1, 1), np.int32)
        self.potential = np.zeros(1)

    def set_costmap(self, costmap: Costmap) -> None:
        """Take a new costmap (read at each plan: the robot's cell is cleared then)."""
        self.costmap = costmap

    def _cell(self, xy: tuple[float, float], what: str) -> tuple[int, int]:
        assert self.costmap is not None
        error = StartOutsideMap if what == "start" else GoalOutsideMap
        if not all(math.isfinite(v) for v in xy):
            raise error(f"the {what} {xy} is not a finite point")
        row, col = self.costmap.cell_of(xy[0], xy[1])
        if not self.costmap.inside(row, col):
            c = self.costmap
            raise error(f"the {what} ({xy[0]:.2f}, {xy[1]:.2f}) is outside the costmap "
                        f"(x {c.origin[0]:.2f} … {c.origin[0] + c.width * c.resolution:.2f}, "
                        f"y {c.origin[1]:.2f} … {c.origin[1] + c.height * c.resolution:.2f} in '{c.frame_id}')")
        return int(row), int(col)

    def _square(self, goal_xy: tuple[float, float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The points (N, 2) of the tolerance square that are on the map, and their rows and columns."""
        assert self.costmap is not None
        res, tol = self.costmap.resolution, self.settings.tolerance
        steps = np.arange(int(math.floor(2.0 * tol / res + 1e-9)) + 1) * res - tol
        px, py = np.meshgrid(goal_xy[0] + steps, goal_xy[1] + steps)
        points = np.column_stack([px.ravel(), py.ravel()])
        row, col = self.costmap.cell_of(points[:, 0], points[:, 1])
        ok = self.costmap.inside(row, col)
        return points[ok], row[ok], col[ok]

    def _reachable(self, start: tuple[int, int]) -> np.ndarray:
        """Cells the propagation can reach from ``start``: its passable 4-connected region."""
        labels, _ = ndimage.label(self.weights < COST_OBS)
        h, w = self.weights.shape
        around = [(start[0] + dr, start[1] + dc) for dr, dc in ((0, 1), (0, -1), (1, 0), (-1, 0))]
        ids = {int(labels[r, c]) for r, c in around if 0 <= r < h and 0 <= c < w and labels[r, c] > 0}
        reachable = np.isin(labels, list(ids)) if ids else np.zeros(labels.shape, dtype=bool)
        reachable[start] = True
        return reachable

    def plan(self, start_xy: tuple[float, float], goal_xy: tuple[float, float]) -> Plan:
        """A path from ``start_xy`` to ``goal_xy`` (m, in the costmap's frame).

        Raises:
            StartOutsideMap, GoalOutsideMap: a point off the costmap.
            StartOccupied: the start is on a lethal cell.
            GoalOccupied: the goal and every cell of the tolerance square are obstacles.
            NoValidPath: neither the goal nor any point of its tolerance square can be reached.
            PlannerTimedOut: planning took longer than ``max_planning_time``.
            RuntimeError: no costmap yet.
        """
        if self.costmap is None:
            raise RuntimeError("the planner has no costmap yet")
        t0 = self._clock()
        s, cm = self.settings, self.costmap
        start, goal = self._cell(start_xy, "start"), self._cell(goal_xy, "goal")
        where = f"({start_xy[0]:.2f}, {start_xy[1]:.2f}) to ({goal_xy[0]:.2f}, {goal_xy[1]:.2f})"
        if cm.costs[start] == LETHAL_OBSTACLE:
            raise StartOccupied(f"the start ({start_xy[0]:.2f}, {start_xy[1]:.2f}) is on an obstacle")
        if start_xy == goal_xy:
            return Plan(np.array([start_xy, goal_xy], dtype=float), 0.0, goal_xy, self._clock() - t0)
        costs = cm.costs.copy()
        costs[start] = 0  # clearRobotCell
        self.weights = weights = navfn_costs(costs, s.allow_unknown)
        points, rows, cols = self._square(goal_xy)
        if weights[goal] >= COST_OBS and bool(np.all(weights[rows, cols] >= COST_OBS)):
            raise GoalOccupied(f"the goal ({goal_xy[0]:.2f}, {goal_xy[1]:.2f}) and every cell within "
                               f"{s.tolerance} m of it are obstacles")
        reachable = self._reachable(start)
        if not (reachable[goal] or bool(np.any(reachable[rows, cols]))):
            raise NoValidPath(f"no path from {where}: the goal and its tolerance of {s.tolerance} m are "
                              f"walled off from the start")
        nx = cm.width
        source, target = start[0] * nx + start[1], goal[0] * nx + goal[1]

        def out_of_time() -> bool:
            return self._clock() - t0 > s.max_planning_time

        self.potential = pot = propagate(weights, source, target, s.use_astar, out_of_time)
        end_xy, end = goal_xy, goal
        if pot[target] >= POT_HIGH:
            found = pot[rows * nx + cols] < POT_HIGH
            if not found.any():
                raise NoValidPath(f"no path from {where}: no point within the tolerance of {s.tolerance} m "
                                  f"was reached")
            d2 = np.sum((points - np.asarray(goal_xy)) ** 2, axis=1)
            best = int(np.argmin(np.where(found, d2, np.inf)))
            end_xy, end = (float(points[best, 0]), float(points[best, 1])), (int(rows[best]), int(cols[best]))
        cells = descend(pot, nx, end[0] * nx + end[1], source, 4 * max(nx, cm.height))
        if cells is None:
            raise NoValidPath(f"no path from {where}: the gradient descent on the potential failed")
        xy = np.asarray(cm.origin) + (cells[::-1] + 0.5) * cm.resolution
        xy[0] = start_xy
        if len(xy) >= 2 and np.sum((xy[-1] - xy[-2]) ** 2) > np.sum((np.asarray(end_xy) - xy[-2]) ** 2):
            xy[-1] = end_xy  # smoothApproachToGoal
        else:
            xy = np.vstack([xy, end_xy])
        elapsed = self._clock() - t0
        if elapsed > s.max_planning_time:
            raise PlannerTimedOut(f"planning took {elapsed:.3f} s, more than max_planning_time "
                                  f"{s.max_planning_time} s")
        return Plan(xy, float(pot[end[0] * nx + end[1]]), end_xy, elapsed)
