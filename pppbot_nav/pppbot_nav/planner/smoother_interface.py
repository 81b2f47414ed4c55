"""What a smoother plugin is: the Protocols the smoother server asks of an entry point in the
``pppbot_nav.smoothers`` group (:mod:`pppbot_nav.plugins`), Nav2's ``nav2_core::Smoother``.

An entry point names a **parameters class** (:class:`SmootherPlugin`): a frozen dataclass whose
fields are the plugin's parameters (declared under ``<name>.`` with their defaults; a field made
with :func:`pppbot_common.params.param` carries its description and ROS name), whose
``validate()`` raises :class:`pppbot_common.params.ParameterError` on a bad value and whose
``make()`` returns the :class:`Smoother`. Nav2's smoother server has no dynamic parameters: a
plugin's are read once, at the server's start.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from pppbot_common.maps import OccupancyGrid


@dataclass(frozen=True)
class SmoothedPath:
    """A smoothed path: one pose per pose given, in the same order and frame."""

    points_xy: np.ndarray  # (N, 2) m
    yaws_rad: np.ndarray  # (N,)
    completed: bool  # False: a collision or an iteration limit stopped the smoothing before it converged


class Smoother(Protocol):
    """Smooths a path on the costmap the server hands it with each path."""

    def smooth(self, points_xy: np.ndarray, yaws_rad: np.ndarray, costmap: OccupancyGrid, *,
               clock_s: Callable[[], float], max_duration_s: float) -> SmoothedPath:
        """The path smoothed.

        Args:
            points_xy: (N, 2) the poses' positions (m, the costmap's frame), N ≥ 1, finite.
            yaws_rad: (N,) the poses' headings.
            costmap: the costmap (a published one, occupancy 0-100) the poses are in.
            clock_s: the time (s) by which ``max_duration_s`` is measured.
            max_duration_s: the time smoothing may take (s).

        Raises:
            pppbot_nav.errors.SmootherTimedOut: it took longer than ``max_duration_s`` (TIMEOUT).
            pppbot_nav.errors.SmootherError: a path it cannot smooth (INVALID_PATH).
        """
        ...


class SmootherPlugin(Protocol):
    """An entry point of ``pppbot_nav.smoothers``: the plugin's parameters, validated, and its smoother."""

    def validate(self) -> None: ...

    def make(self) -> Smoother: ...
