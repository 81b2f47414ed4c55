"""Contact surfaces as Gazebo combines them, and how pppbot realises that in MuJoCo.

Gazebo's default physics (ODE) gives two touching surfaces the **smaller** of their friction
coefficients: ``mu = min(mu_a, mu_b)`` along the first friction direction (``fdir1``, when a
surface names one) and ``mu2 = min(mu2_a, mu2_b)`` across it; a surface that names none has
SDF's defaults, ``mu = mu2 = 1``. URDF's ``<gazebo reference="link">`` ``<mu1>``/``<mu2>`` are
the link's ``mu``/``mu2`` (Gazebo converts them so). MuJoCo instead takes the *larger* friction
of two geoms unless one has a higher ``priority``, whose friction then wins. So pppbot gives
every geom a priority that falls as its friction rises (:func:`friction_priorities`): of two
touching geoms the one with the smaller friction has the higher priority, and its friction is
the pair's: the minimum, exactly ODE's rule.

MuJoCo's friction is isotropic (one coefficient for both tangent directions, and no ``fdir1``):
a geom's coefficient is the smaller of its ``mu`` and ``mu2``, so a pair gets the smaller of
ODE's combined ``mu`` and ``mu2``. Where those two differ for a pair the robot can meet,
pppbot names the pair once (:func:`anisotropic_pairs`).

Not simulated, named once when a surface sets them away from SDF's defaults:
``<bounce><restitution_coefficient>`` (MuJoCo contacts have no restitution), ``<contact><ode>``
``kp``, ``kd``, ``min_depth``, ``max_vel``, ``soft_cfm``, ``soft_erp`` (ODE's contact softness;
MuJoCo's ``solref``/``solimp`` work differently), ``<friction><torsional>`` and URDF's ``kp``,
``kd``, ``minDepth``, ``maxVel``.
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

#: SDF's (and ODE's) friction when a surface names none.
DEFAULT_MU = 1.0
#: SDF's defaults of the contact settings pppbot does not simulate: a surface that keeps them
#: (Gazebo classic writes them all into a saved world) changes nothing and is not named.
UNSIMULATED_DEFAULTS = {
    "bounce/restitution_coefficient": 0.0,
    "contact/ode/kp": 1e12, "contact/ode/kd": 1.0, "contact/ode/min_depth": 0.0, "contact/ode/max_vel": 0.01,
    "contact/ode/soft_cfm": 0.0, "contact/ode/soft_erp": 0.2,
    "friction/torsional/coefficient": 1.0,
}
#: URDF ``<gazebo reference>`` contact settings (Gazebo's names) and the SDF ones they stand for.
URDF_UNSIMULATED = {"kp": "contact/ode/kp", "kd": "contact/ode/kd", "minDepth": "contact/ode/min_depth",
                    "maxVel": "contact/ode/max_vel"}


@dataclass(frozen=True)
class Surface:
    """A collision's friction as Gazebo reads it: ``mu`` along ``fdir1`` (or ODE's first friction
    direction), ``mu2`` across it."""

    mu: float = DEFAULT_MU
    mu2: float = DEFAULT_MU

    @property
    def isotropic(self) -> float:
        """The coefficient a MuJoCo geom gets: the smaller of the two."""
        return min(self.mu, self.mu2)


def combined(a: Surface, b: Surface) -> Surface:
    """ODE's friction of two touching surfaces: the smaller ``mu`` and the smaller ``mu2``."""
    return Surface(min(a.mu, b.mu), min(a.mu2, b.mu2))


def friction_priorities(frictions: Iterable[float]) -> dict[float, int]:
    """A MuJoCo priority for each friction value: the smallest value gets the highest, so that of
    any two geoms the smaller friction wins, as ODE's minimum does."""
    ordered = sorted(set(frictions), reverse=True)
    return {value: rank for rank, value in enumerate(ordered)}


def anisotropic_pairs(robot: Iterable[tuple[str, Surface]], world: Iterable[tuple[str, Surface]]) -> list[str]:
    """One line for each pair of a robot surface and a world surface whose combined ``mu`` and
    ``mu2`` differ (MuJoCo uses the smaller in both directions); ``(name, surface)`` pairs."""
    world = list(world)
    lines = []
    seen: set[tuple[Surface, Surface]] = set()
    for robot_name, mine in robot:
        for world_name, theirs in world:
            both = combined(mine, theirs)
            if both.mu != both.mu2 and (mine, theirs) not in seen:
                seen.add((mine, theirs))
                lines.append(f"friction of {robot_name} (mu {mine.mu:g}, mu2 {mine.mu2:g}) on {world_name} (mu "
                             f"{theirs.mu:g}, mu2 {theirs.mu2:g}): Gazebo gives mu {both.mu:g} along fdir1 and mu2 "
                             f"{both.mu2:g} across; MuJoCo's friction is the same both ways, so pppbot uses "
                             f"{both.isotropic:g}")
    return lines
