"""The particle filter: weights, KLD-adaptive resampling, recovery and clusters (Nav2's ``pf.c``).

* **Sensor update**: each weight is multiplied by its laser likelihood and the weights are
  normalised. The mean unnormalised weight feeds two running averages, ``w_slow`` and
  ``w_fast`` (rates ``recovery_alpha_slow``/``recovery_alpha_fast``); when the fast one falls
  below the slow one the robot is probably not where the particles say, and resampling
  draws a fraction ``1 − w_fast/w_slow`` of particles uniformly over free space
  (Augmented MCL, Thrun et al. table 8.3). Both alphas 0 turn this off.
* **Resampling** draws particles by weight until there are enough for the KLD bound
  (Fox 2003): with ``k`` occupied histogram bins (0.5 m × 0.5 m × 10°), at most ``pf_err``
  divergence from the true posterior needs
  ``n = (k − 1)/(2·pf_err) · (1 − 2/(9(k − 1)) + √(2/(9(k − 1)))·pf_z)³`` particles, kept in
  ``[min_particles, max_particles]``. As in Nav2, ``pf_z`` is the upper standard normal
  quantile itself (Nav2's 0.99 is the quantile of p ≈ 0.16, not a probability of 0.99).
* **Clusters**: particles in neighbouring histogram bins (26-neighbourhood, yaw wrapping
  around) form a cluster; each has a weight, a mean and a covariance. The pose estimate is
  the heaviest cluster's mean, as Nav2's AMCL publishes it.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph

from pppbot_common.se2 import wrap_angles
from pppbot_nav.errors import AmclError

#: Histogram bin size of the KLD bound and the clusters: x, y (m) and yaw (rad), as Nav2's kd-tree.
BIN_SIZE = (0.5, 0.5, math.radians(10.0))
_YAW_BINS = round(2.0 * math.pi / BIN_SIZE[2])  # 36: a whole turn


@dataclass(frozen=True)
class FilterSettings:
    min_particles: int = 500
    max_particles: int = 2000
    pf_err: float = 0.05
    pf_z: float = 0.99
    recovery_alpha_slow: float = 0.0
    recovery_alpha_fast: float = 0.0

    def validate(self) -> None:
        """Raises AmclError naming the first bad value."""
        if not 1 <= self.min_particles <= self.max_particles:
            raise AmclError(f"min_particles ({self.min_particles}) and max_particles ({self.max_particles}) must "
                            "satisfy 1 ≤ min_particles ≤ max_particles", "min_particles")
        if not 0.0 < self.pf_err < 1.0:
            raise AmclError(f"pf_err must be in (0, 1), not {self.pf_err}", "pf_err")
        if not (math.isfinite(self.pf_z) and self.pf_z > 0.0):
            raise AmclError(f"pf_z (a standard normal quantile) must be a positive number, not {self.pf_z}",
                            "pf_z")
        for name in ("recovery_alpha_slow", "recovery_alpha_fast"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise AmclError(f"{name} must be in [0, 1], not {value}", name)


@dataclass(frozen=True)
class Cluster:
    weight: float
    mean: np.ndarray  # x, y, yaw
    covariance: np.ndarray  # 3 × 3: x, y as sampled, yaw's from the mean resultant length


def kld_limit(bins: np.ndarray | int, settings: FilterSettings) -> np.ndarray:
    """Particles the KLD bound asks for with ``bins`` occupied bins (element-wise)."""
    k = np.asarray(bins, dtype=float)
    km1 = np.maximum(k - 1.0, 1.0)
    b = 2.0 / (9.0 * km1)
    n = np.ceil(km1 / (2.0 * settings.pf_err) * (1.0 - b + np.sqrt(b) * settings.pf_z) ** 3)
    n = np.where(k <= 1, settings.max_particles, n)
    return np.clip(n, settings.min_particles, settings.max_particles).astype(int)


def bin_keys(particles: np.ndarray) -> np.ndarray:
    """One int64 per particle naming its histogram bin."""
    ix = np.floor(particles[:, 0] / BIN_SIZE[0]).astype(np.int64)
    iy = np.floor(particles[:, 1] / BIN_SIZE[1]).astype(np.int64)
    it = np.floor(particles[:, 2] / BIN_SIZE[2]).astype(np.int64) % _YAW_BINS
    return _encode(ix, iy, it)


def _encode(ix: np.ndarray, iy: np.ndarray, it: np.ndarray) -> np.ndarray:
    offset = 1 << 20  # bins of ±500 km: any map
    return ((ix + offset) << 26 | (iy + offset)) * _YAW_BINS + it


class ParticleFilter:
    """Particles ((N, 3) x, y, yaw in the map) with normalised ``weights``."""

    def __init__(self, settings: FilterSettings) -> None:
        settings.validate()
        self.settings = settings
        self.particles = np.zeros((0, 3))
        self.weights = np.zeros(0)
        self.w_slow = 0.0
        self.w_fast = 0.0

    def __len__(self) -> int:
        return len(self.particles)

    # --------------------------------------------------------------- initialisation
    def init_gaussian(self, mean: np.ndarray, covariance: np.ndarray, rng: np.random.Generator) -> None:
        """``max_particles`` particles around ``mean`` (x, y, yaw) with the 3 × 3 ``covariance``.

        Raises:
            AmclError: a non-finite mean, or a covariance that is not symmetric positive semi-definite.
        """
        mean, cov = np.asarray(mean, dtype=float), np.asarray(covariance, dtype=float)
        if mean.shape != (3,) or not np.isfinite(mean).all():
            raise AmclError(f"an initial pose must be three finite numbers, not {mean.tolist()}")
        if cov.shape != (3, 3) or not np.isfinite(cov).all() or not np.allclose(cov, cov.T) \
                or np.linalg.eigvalsh(cov).min() < -1e-12:
            raise AmclError(f"an initial pose covariance must be symmetric positive semi-definite, not {cov.tolist()}")
        n = self.settings.max_particles
        particles = rng.multivariate_normal(mean, cov, size=n, method="eigh")
        particles[:, 2] = wrap_angles(particles[:, 2])
        self._reset(particles)

    def init_uniform(self, free_xy: np.ndarray, cell_m: float, rng: np.random.Generator) -> None:
        """``max_particles`` particles spread uniformly over the free cells (centres ``free_xy``, size
        ``cell_m``) with uniform headings: global localization."""
        self._reset(uniform_poses(free_xy, cell_m, self.settings.max_particles, rng))

    def _reset(self, particles: np.ndarray) -> None:
        self.particles = particles
        self.weights = np.full(len(particles), 1.0 / len(particles))
        self.w_slow = self.w_fast = 0.0

    # ------------------------------------------------------------------ updates
    def update_sensor(self, likelihoods: np.ndarray) -> None:
        """Multiply the weights by ``likelihoods`` (N,), normalise, and track ``w_slow``/``w_fast``."""
        weights = self.weights * likelihoods
        total = float(weights.sum())
        if not (total > 0.0 and math.isfinite(total)):
            self.weights = np.full(len(weights), 1.0 / len(weights))
            return
        self.weights = weights / total
        w_avg = total / len(weights)
        s = self.settings
        self.w_slow = w_avg if self.w_slow == 0.0 else self.w_slow + s.recovery_alpha_slow * (w_avg - self.w_slow)
        self.w_fast = w_avg if self.w_fast == 0.0 else self.w_fast + s.recovery_alpha_fast * (w_avg - self.w_fast)

    def random_fraction(self) -> float:
        """The share of particles the next resampling draws at random (Augmented MCL)."""
        if self.w_slow <= 0.0:
            return 0.0
        return max(0.0, 1.0 - self.w_fast / self.w_slow)

    def resample(self, rng: np.random.Generator,
                 random_poses: Callable[[int, np.random.Generator], np.ndarray]) -> None:
        """Draw a new set by weight, as many as the KLD bound asks for; a ``random_fraction``
        of them comes from ``random_poses(count, rng)`` instead."""
        s = self.settings
        candidates = self.particles[rng.choice(len(self.particles), size=s.max_particles, p=self.weights)]
        fraction = self.random_fraction()
        if fraction > 0.0:
            injected = rng.random(s.max_particles) < fraction
            if injected.any():
                candidates[injected] = random_poses(int(injected.sum()), rng)
            self.w_slow = self.w_fast = 0.0
        keys = bin_keys(candidates)
        _, first = np.unique(keys, return_index=True)
        new_bin = np.zeros(len(keys), dtype=bool)
        new_bin[first] = True
        bins_so_far = np.cumsum(new_bin)  # k after taking 1, 2, … candidates
        count = np.arange(1, len(keys) + 1)
        enough = np.flatnonzero(count > kld_limit(bins_so_far, s))
        n = int(enough[0]) + 1 if enough.size else s.max_particles
        self.particles = candidates[:n].copy()
        self.weights = np.full(n, 1.0 / n)

    def replace_some(self, poses: np.ndarray, rng: np.random.Generator) -> None:
        """Put ``poses`` in place of as many particles chosen at random, each with the mean weight."""
        count = min(len(poses), len(self.particles))
        if count == 0:
            return
        chosen = rng.choice(len(self.particles), size=count, replace=False)
        self.particles[chosen] = poses[:count]
        self.weights[chosen] = 1.0 / len(self.weights)
        self.weights /= self.weights.sum()

    # ----------------------------------------------------------------- clusters
    def clusters(self) -> list[Cluster]:
        """The particle clusters, heaviest first."""
        keys = bin_keys(self.particles)
        leaves, leaf_of = np.unique(keys, return_inverse=True)
        it = leaves % _YAW_BINS
        rest = leaves // _YAW_BINS
        offset = 1 << 20
        ix, iy = (rest >> 26) - offset, (rest & ((1 << 26) - 1)) - offset
        rows, cols = [], []
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for dt in (-1, 0, 1):
                    if (dx, dy, dt) <= (0, 0, 0):
                        continue  # each pair once, and not itself
                    neighbour = _encode(ix + dx, iy + dy, (it + dt) % _YAW_BINS)
                    at = np.searchsorted(leaves, neighbour)
                    found = (at < len(leaves)) & (leaves[np.minimum(at, len(leaves) - 1)] == neighbour)
                    rows.append(np.flatnonzero(found))
                    cols.append(at[found])
        r, c = np.concatenate(rows), np.concatenate(cols)
        graph = sparse.coo_matrix((np.ones(len(r)), (r, c)), shape=(len(leaves), len(leaves)))
        _, leaf_cluster = csgraph.connected_components(graph, directed=False)
        return sorted((_cluster(self.particles[m], self.weights[m])
                       for m in _members(leaf_cluster[leaf_of])), key=lambda cl: -cl.weight)

    def estimate(self) -> Cluster:
        """The heaviest cluster."""
        return self.clusters()[0]


def _members(labels: np.ndarray) -> list[np.ndarray]:
    order = np.argsort(labels, kind="stable")
    bounds = np.flatnonzero(np.diff(labels[order])) + 1
    return np.split(order, bounds)


def _cluster(particles: np.ndarray, weights: np.ndarray) -> Cluster:
    total = float(weights.sum())
    w = weights / total if total > 0 else np.full(len(weights), 1.0 / len(weights))
    mx, my = float(w @ particles[:, 0]), float(w @ particles[:, 1])
    c, s = float(w @ np.cos(particles[:, 2])), float(w @ np.sin(particles[:, 2]))
    cov = np.zeros((3, 3))
    dxy = particles[:, :2] - (mx, my)
    cov[:2, :2] = (dxy * w[:, None]).T @ dxy
    cov[2, 2] = -2.0 * math.log(max(math.hypot(c, s), 1e-12))
    return Cluster(total, np.array([mx, my, math.atan2(s, c)]), cov)


def uniform_poses(free_xy: np.ndarray, cell_m: float, count: int, rng: np.random.Generator) -> np.ndarray:
    """``count`` poses uniform over the free cells (centres ``free_xy``, size ``cell_m``) and headings."""
    cells = free_xy[rng.integers(0, len(free_xy), size=count)]
    jitter = rng.uniform(-0.5 * cell_m, 0.5 * cell_m, size=(count, 2))
    return np.column_stack([cells + jitter, rng.uniform(-math.pi, math.pi, size=count)])
