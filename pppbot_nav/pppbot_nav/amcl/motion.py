"""Odometry motion models: how particles move between two odometry poses, with noise.

Nav2's ``nav2_amcl::DifferentialMotionModel`` and ``OmniMotionModel`` (both after
Thrun, Burgard and Fox, *Probabilistic Robotics*, table 5.6, ``sample_motion_model_odometry``),
vectorised over the particles. The odometry step is split into a first turn, a
translation and a second turn; each is perturbed with a zero-mean Gaussian whose
standard deviation grows with the step:

* ``alpha1``: rotation noise from rotation, ``alpha2``: rotation noise from translation,
* ``alpha3``: translation noise from translation, ``alpha4``: translation noise from rotation,
* ``alpha5`` (omni only): strafe noise from translation.

As in Nav2, a turn's noise uses the smaller of the turn and the turn plus π, so
driving backwards is not mistaken for turning around.
"""
from __future__ import annotations

import enum
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from pppbot_common.se2 import wrap_angle, wrap_angles

#: Below this translation (m) the first turn is taken as zero (the heading of a tiny step is noise).
MIN_TRANSLATION_M = 0.01


@dataclass(frozen=True)
class MotionNoise:
    """Nav2's ``alpha1``…``alpha5`` (see the module text); all ≥ 0."""

    alpha1: float = 0.2
    alpha2: float = 0.2
    alpha3: float = 0.2
    alpha4: float = 0.2
    alpha5: float = 0.2


class MotionModel(Protocol):
    def sample(self, particles: np.ndarray, old_odom: np.ndarray, new_odom: np.ndarray,
               rng: np.random.Generator) -> None:
        """Move ``particles`` ((N, 3) x, y, yaw in the map) in place by the odometry step
        ``old_odom → new_odom`` (poses in the odometry frame), with noise drawn from ``rng``."""


def _turn_noise(turn: float) -> float:
    return min(abs(wrap_angle(turn)), abs(wrap_angle(turn - math.pi)))


@dataclass(frozen=True)
class DifferentialMotionModel:
    noise: MotionNoise = MotionNoise()

    def sample(self, particles: np.ndarray, old_odom: np.ndarray, new_odom: np.ndarray,
               rng: np.random.Generator) -> None:
        a = self.noise
        dx, dy = float(new_odom[0] - old_odom[0]), float(new_odom[1] - old_odom[1])
        trans = math.hypot(dx, dy)
        rot1 = 0.0 if trans < MIN_TRANSLATION_M else wrap_angle(math.atan2(dy, dx) - float(old_odom[2]))
        rot2 = wrap_angle(float(new_odom[2] - old_odom[2]) - rot1)
        n1, n2 = _turn_noise(rot1), _turn_noise(rot2)
        n = len(particles)
        rot1_hat = rot1 - rng.normal(0.0, math.sqrt(a.alpha1 * n1 ** 2 + a.alpha2 * trans ** 2), n)
        trans_hat = trans - rng.normal(0.0, math.sqrt(a.alpha3 * trans ** 2 + a.alpha4 * (n1 ** 2 + n2 ** 2)), n)
        rot2_hat = rot2 - rng.normal(0.0, math.sqrt(a.alpha1 * n2 ** 2 + a.alpha2 * trans ** 2), n)
        heading = particles[:, 2] + rot1_hat
        particles[:, 0] += trans_hat * np.cos(heading)
        particles[:, 1] += trans_hat * np.sin(heading)
        particles[:, 2] = wrap_angles(heading + rot2_hat)


@dataclass(frozen=True)
class OmniMotionModel:
    noise: MotionNoise = MotionNoise()

    def sample(self, particles: np.ndarray, old_odom: np.ndarray, new_odom: np.ndarray,
               rng: np.random.Generator) -> None:
        a = self.noise
        dx, dy = float(new_odom[0] - old_odom[0]), float(new_odom[1] - old_odom[1])
        dyaw = wrap_angle(float(new_odom[2] - old_odom[2]))
        trans = math.hypot(dx, dy)
        bearing = math.atan2(dy, dx) - float(old_odom[2])  # direction of travel in the robot's frame
        n = len(particles)
        trans_sigma = math.sqrt(a.alpha3 * trans ** 2 + a.alpha1 * dyaw ** 2)
        rot_sigma = math.sqrt(a.alpha4 * dyaw ** 2 + a.alpha2 * trans ** 2)
        strafe_sigma = math.sqrt(a.alpha1 * dyaw ** 2 + a.alpha5 * trans ** 2)
        heading = particles[:, 2] + bearing
        trans_hat = trans + rng.normal(0.0, trans_sigma, n)
        strafe_hat = rng.normal(0.0, strafe_sigma, n)
        particles[:, 0] += trans_hat * np.cos(heading) + strafe_hat * -np.sin(heading)
        particles[:, 1] += trans_hat * np.sin(heading) + strafe_hat * np.cos(heading)
        particles[:, 2] = wrap_angles(particles[:, 2] + dyaw + rng.normal(0.0, rot_sigma, n))


class RobotModel(enum.Enum):
    """Nav2's ``robot_model_type`` values."""

    DIFFERENTIAL = "nav2_amcl::DifferentialMotionModel"
    OMNI = "nav2_amcl::OmniMotionModel"


def motion_model(kind: RobotModel, noise: MotionNoise) -> MotionModel:
    """The motion model registered under ``kind``."""
    models: dict[RobotModel, Callable[[MotionNoise], MotionModel]] = {
        RobotModel.DIFFERENTIAL: DifferentialMotionModel, RobotModel.OMNI: OmniMotionModel}
    return models[kind](noise)
