"""Joints between the links of a world's models, as Gazebo reads SDF ``<joint>`` elements.

A joint joins a child link to a parent link (or to ``world``). Its frame is posed relative to
the child link unless its ``<pose relative_to>`` says otherwise (SDF 1.7); its ``<axis><xyz>`` is
expressed in the joint frame unless ``expressed_in`` names another frame (``__model__``, a link,
a ``<frame>``), or, in SDF 1.6 and before, ``<use_parent_model_frame>true`` puts it in the model
frame. ``<limit>`` ``lower``/``upper`` (Gazebo's default ±1e16 is no limit), ``effort`` and
``velocity`` (negative: none); ``<dynamics>`` ``damping``, ``friction``, ``spring_reference``,
``spring_stiffness``.

Types: ``revolute`` (a hinge, limited by ``<limit>``), ``continuous`` (a hinge without limits),
``prismatic`` (a slide), ``fixed``, ``ball``, and ``universal``/``revolute2`` (two hinges,
``<axis>`` and ``<axis2>``). ``screw`` and ``gearbox`` are not simulated: the reader names them
once and keeps the child fixed to its parent. Poses and axes here are in the world frame as the
world is loaded; the MuJoCo build turns them into each body's frame.
"""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np
from lxml import etree

from pppbot_sim.errors import WorldError

#: Gazebo's "no limit" for a joint's lower/upper (SDF's default ±1e16).
NO_LIMIT = 1e16


class JointKind(enum.Enum):
    REVOLUTE = "revolute"
    CONTINUOUS = "continuous"
    PRISMATIC = "prismatic"
    FIXED = "fixed"
    BALL = "ball"
    UNIVERSAL = "universal"
    REVOLUTE2 = "revolute2"

    @property
    def axis_count(self) -> int:
        """How many ``<axis>`` elements the type uses."""
        if self in (JointKind.FIXED, JointKind.BALL):
            return 0
        return 2 if self in (JointKind.UNIVERSAL, JointKind.REVOLUTE2) else 1


#: Types SDF has that are not simulated: the child stays fixed to the parent, and the reader says so.
UNSIMULATED = {"screw", "gearbox"}


@dataclass(frozen=True)
class JointAxis:
    """One degree of freedom: its direction (a unit vector in the world frame at load), its limits
    (rad or m; ``inf`` when none), its effort (N·m or N) and velocity limits, and its dynamics."""

    direction: np.ndarray
    lower: float = -math.inf
    upper: float = math.inf
    effort: float = math.inf
    velocity: float = math.inf
    damping: float = 0.0
    friction: float = 0.0
    spring_reference: float = 0.0
    spring_stiffness: float = 0.0

    @property
    def limited(self) -> bool:
        return math.isfinite(self.lower) or math.isfinite(self.upper)


@dataclass(frozen=True)
class ModelJoint:
    """A joint of a world model: scoped names (``model::joint``, ``model::link``; ``world``), the
    joint frame's origin in the world (m), and its axes."""

    name: str
    kind: JointKind
    parent: str
    child: str
    anchor: np.ndarray
    axes: tuple[JointAxis, ...]
    where: str  # file:line, for messages


class SdfText(Protocol):
    """What joint reading needs of the world reader: numbers from elements, and errors and
    warnings that name the file and line."""

    def floats(self, element: etree._Element, count: int | tuple[int, ...], file: Path) -> list[float]:
        """``count`` finite numbers from ``element``'s text."""

    def number(self, parent: etree._Element, tag: str, default: float | None, file: Path) -> float:
        """The number in ``parent``'s ``<tag>``, or ``default``."""

    def fail(self, element: etree._Element | None, message: str, file: Path | None = None) -> WorldError:
        """An error naming the file and ``element``'s line."""


def joint_kind(element: etree._Element, reader: SdfText, file: Path) -> JointKind | None:
    """The joint's type; None for a type that SDF has but that is not simulated.

    Raises:
        WorldError: no type, or one SDF does not have.
    """
    kind = element.get("type", "")
    if kind in UNSIMULATED:
        return None
    try:
        return JointKind(kind)
    except ValueError:
        allowed = ", ".join([k.value for k in JointKind] + sorted(UNSIMULATED))
        raise reader.fail(element, f"joint '{element.get('name')}' has type '{kind}' (SDF's types: {allowed})",
                          file) from None


def read_axis(axis: etree._Element | None, rotation: np.ndarray, reader: SdfText, file: Path,
              joint: str) -> JointAxis:
    """An ``<axis>``/``<axis2>`` whose ``<xyz>`` is expressed in the frame with world ``rotation``
    (3×3); no element is SDF's default, z.

    Raises:
        WorldError: a zero axis, lower above upper, a bad number.
    """
    if axis is None:
        return JointAxis(rotation @ np.array([0.0, 0.0, 1.0]))
    xyz_el = axis.find("xyz")
    xyz = np.array(reader.floats(xyz_el, 3, file) if xyz_el is not None else [0.0, 0.0, 1.0])
    norm = float(np.linalg.norm(xyz))
    if norm < 1e-12:
        raise reader.fail(xyz_el, f"joint '{joint}': <axis><xyz> must not be 0 0 0", file)
    values: dict[str, float] = {}
    limit = axis.find("limit")
    if limit is not None:
        lower = reader.number(limit, "lower", -NO_LIMIT, file)
        upper = reader.number(limit, "upper", NO_LIMIT, file)
        if lower > upper:
            raise reader.fail(limit, f"joint '{joint}': <limit> lower {lower} is above upper {upper}", file)
        values["lower"] = lower if lower > -NO_LIMIT else -math.inf
        values["upper"] = upper if upper < NO_LIMIT else math.inf
        for tag in ("effort", "velocity"):
            value = reader.number(limit, tag, -1.0, file)
            values[tag] = value if value >= 0 else math.inf
    dynamics = axis.find("dynamics")
    if dynamics is not None:
        for tag in ("damping", "friction", "spring_stiffness"):
            value = reader.number(dynamics, tag, 0.0, file)
            if value < 0:
                raise reader.fail(dynamics.find(tag), f"joint '{joint}': <{tag}> {value} must not be negative", file)
            values[tag] = value
        values["spring_reference"] = reader.number(dynamics, "spring_reference", 0.0, file)
    return JointAxis(rotation @ (xyz / norm), **values)
