"""A saved world's ``<state>``, as Gazebo classic applies it at load.

Gazebo classic writes ``<world><state>`` into every world it saves: each model's pose in the
world as it was at that moment, its links' poses, its joints' angles (nested models nested).
At load it puts the models there, over the poses of their ``<model>`` blocks. pppbot does the
same: a model's ``<state>`` pose replaces its own (its links, static or not, move with it); a
link that no joint holds is put at its ``<state>`` pose (the links its joints hold move with
it); a joint takes its ``<angle axis="0|1">``. A held link's own ``<state>`` pose is implied by
its joints' angles and is not applied twice. ``<insertions>`` and ``<deletions>`` (models
added or removed while Gazebo ran) are named once, not applied.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from lxml import etree

from pppbot_sim.sdf_joints import ModelJoint


@dataclass
class WorldState:
    """Poses (4×4, in the world) of models and links and angles of joints, by scoped name."""

    models: dict[str, np.ndarray] = field(default_factory=dict)
    links: dict[str, np.ndarray] = field(default_factory=dict)
    joints: dict[str, dict[int, float]] = field(default_factory=dict)
    ignored: list[etree._Element] = field(default_factory=list)


def read_state(state: etree._Element, pose_of: Callable[[etree._Element], np.ndarray],
               angle_of: Callable[[etree._Element], float]) -> WorldState:
    """The ``<state>`` element's models, links and joints; ``pose_of(model_or_link)`` reads an
    element's ``<pose>``, ``angle_of(angle)`` an ``<angle>``."""
    found = WorldState()

    def model(element: etree._Element, prefix: str) -> None:
        name = f"{prefix}{element.get('name', '')}"
        if element.find("pose") is not None:
            found.models[name] = pose_of(element)
        for link in element.findall("link"):
            if link.find("pose") is not None:
                found.links[f"{name}::{link.get('name', '')}"] = pose_of(link)
        for joint in element.findall("joint"):
            found.joints[f"{name}::{joint.get('name', '')}"] = {
                int(angle.get("axis", "0")): angle_of(angle) for angle in joint.findall("angle")}
        for nested in element.findall("model"):
            model(nested, f"{name}::")

    for child in state:
        if child.tag == "model":
            model(child, "")
        elif child.tag in ("insertions", "deletions"):
            found.ignored.append(child)
    return found


def move_free_links(bodies: list[Any], joints: list[ModelJoint], links: dict[str, np.ndarray]) -> list[ModelJoint]:
    """Put each body that no joint holds at its ``<state>`` pose in ``links``, with the bodies its
    joints hold (and their joints' anchors and axes) moved alike; returns the joints as moved.
    ``bodies``: objects with ``name`` and ``pose`` (4×4), changed in place."""
    held = {j.child: j for j in joints}
    below: dict[str, list[str]] = {}
    for joint in joints:
        below.setdefault(joint.parent, []).append(joint.child)
    by_name = {body.name: body for body in bodies}
    moved_joints = {j.name: j for j in joints}
    for body in bodies:
        if body.name in held or body.name not in links:
            continue
        delta = links[body.name] @ np.linalg.inv(body.pose)
        stack = [body.name]
        while stack:
            name = stack.pop()
            if name in by_name:
                by_name[name].pose = delta @ by_name[name].pose
            for child in below.get(name, []):
                joint = moved_joints[held[child].name]
                moved_joints[joint.name] = _moved_joint(joint, delta)
                stack.append(child)
    return [moved_joints[j.name] for j in joints]


def _moved_joint(joint: ModelJoint, delta: np.ndarray) -> ModelJoint:
    axes = tuple(dataclasses.replace(axis, direction=delta[:3, :3] @ axis.direction) for axis in joint.axes)
    return dataclasses.replace(joint, anchor=(delta @ np.append(joint.anchor, 1.0))[:3], axes=axes)


def named(element: etree._Element, file: Path) -> str:
    """The line that names an ignored ``<insertions>``/``<deletions>``."""
    done = {"insertions": "inserted", "deletions": "deleted"}[element.tag]
    return f"{file}:{element.sourceline}: <state><{element.tag}> (models {done} while Gazebo ran) is not applied"
