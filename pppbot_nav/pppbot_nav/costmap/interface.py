"""What a costmap layer plugin is: the Protocols a costmap asks of an entry point in the
``pppbot_nav.costmap_layers`` group (:mod:`pppbot_nav.plugins`), Nav2's ``nav2_costmap_2d::Layer``.

An entry point names a **parameters class** (:class:`LayerPlugin`): a frozen dataclass whose fields
are the layer's parameters, declared under ``<layer name>.`` (``enabled`` among them, by Nav2's
convention), with ``validate()`` and ``make(context)``. The layer it makes is asked to
``update`` the master costmap in the order of the costmap's ``plugins``, each time the costmap
is rebuilt. ``LIVE_PARAMETERS`` names what may change while the costmap runs (set as attributes
of the running layer; None: all; absent: none).
"""
from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass
from typing import ClassVar, Protocol

from pppbot_nav.costmap.grid import Costmap


@dataclass(frozen=True)
class LayerContext:
    """What the costmap gives each layer it makes: its own parameters a layer reads (Nav2's layers
    read them from the costmap's node)."""

    name: str  # the layer's name in ``plugins``
    global_frame: str
    track_unknown_space: bool
    lethal_cost_threshold: int
    robot_radius: float  # m, the inscribed radius (the footprint's, if one is given)


class Layer(Protocol):
    plugin: str
    enabled: bool

    def update(self, master: Costmap) -> None:
        """Apply this layer's costs onto ``master``."""


class LayerPlugin(Protocol):
    """An entry point of ``pppbot_nav.costmap_layers``."""

    LIVE_PARAMETERS: ClassVar[Collection[str] | None]

    def validate(self) -> None: ...

    def make(self, context: LayerContext) -> Layer: ...


class FilterPlugin(Protocol):
    """An entry point of ``pppbot_nav.costmap_filters``: a costmap filter named in ``filters``
    (Nav2's KeepoutFilter, SpeedFilter: :mod:`pppbot_nav.costmap.filters`), applied after the layers."""

    LIVE_PARAMETERS: ClassVar[Collection[str] | None]

    def validate(self) -> None: ...

    def make(self, context: LayerContext) -> object: ...
