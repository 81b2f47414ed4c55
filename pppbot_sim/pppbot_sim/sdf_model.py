"""What a Gazebo world reads into (:func:`pppbot_sim.sdf_world.read_sdf_world`): plain data, no XML
reading here. Static collision shapes with world poses, the bodies of models that are not static
with their inertials, joints, the models' plugins, the lighting and what was skipped or warned about."""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from lxml import etree

from pppbot_sim.contacts import Surface
from pppbot_sim.sdf_joints import ModelJoint
from pppbot_sim.sdf_lights import Lighting


@dataclass(frozen=True)
class Shape:
    """A collision shape; ``pose`` is 4×4, in the world (static) or in its body's frame."""

    name: str
    kind: str
    #: box (x, y, z) full extents; cylinder/capsule (radius, length); sphere (radius,);
    #: ellipsoid (rx, ry, rz); plane (size_x, size_y); mesh: empty
    size: tuple[float, ...]
    pose: np.ndarray = field(compare=False)
    mesh: Path | None = None
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    surface: Surface = Surface()


#: SDF's inertial where a link has none: 1 kg, 1 kg·m² about each axis (what Gazebo simulates).
DEFAULT_MASS_KG = 1.0
DEFAULT_INERTIA = (1.0, 0.0, 0.0, 1.0, 0.0, 1.0)


@dataclass
class Body:
    """A link of a model that is not static: a body in the simulation, free unless a joint holds it."""

    name: str
    pose: np.ndarray
    shapes: list[Shape]
    mass: float = DEFAULT_MASS_KG
    #: ixx, ixy, ixz, iyy, iyz, izz about the centre of mass; None: from the shapes (``auto``)
    inertia: tuple[float, float, float, float, float, float] | None = DEFAULT_INERTIA
    #: centre of mass pose in the link frame (4×4)
    inertial_pose: np.ndarray | None = None


@dataclass(frozen=True)
class ModelPlugin:
    """A ``<plugin>`` of a model, kept for the simulator; ``canonical_link`` is the model's first
    link (or its ``canonical_link``), unscoped."""

    model: str
    element: etree._Element
    file: Path
    canonical_link: str

    def where(self, element: etree._Element | None = None) -> str:
        line = (element if element is not None else self.element).sourceline
        return f"{self.file}:{line}"


@dataclass
class World:
    name: str
    source: Path
    step_size_s: float = 0.001
    gravity: tuple[float, float, float] = (0.0, 0.0, -9.81)
    static_shapes: list[Shape] = field(default_factory=list)
    bodies: list[Body] = field(default_factory=list)
    joints: list[ModelJoint] = field(default_factory=list)
    #: joint → {axis: angle (rad) or position (m)} from the world's <state>
    joint_positions: dict[str, dict[int, float]] = field(default_factory=dict)
    plugins: list[ModelPlugin] = field(default_factory=list)
    lighting: Lighting = field(default_factory=Lighting)  # for the cameras only
    warnings: list[str] = field(default_factory=list)
    skipped: Counter[str] = field(default_factory=Counter)

    def skipped_summary(self) -> str:
        """One line naming what was skipped, e.g. 'skipped gui, light ×2, plugin ×3'."""
        if not self.skipped:
            return ""
        parts = [name if n == 1 else f"{name} ×{n}" for name, n in sorted(self.skipped.items())]
        return "skipped " + ", ".join(parts)
