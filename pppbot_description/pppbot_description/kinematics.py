"""Joint transforms of a URDF tree: what robot_state_publisher publishes on /tf and /tf_static.

A joint's transform takes child-frame coordinates to parent-frame coordinates:
``T = T_origin · T_motion(q)``, with ``T_motion`` a rotation of ``q`` rad about
the joint axis (revolute, continuous) or a shift of ``q`` m along it (prismatic).
A :class:`FrameTransform`'s rotation is a quaternion ``(x, y, z, w)``, the messages' order;
inside, transforms3d's ``(w, x, y, z)``; :meth:`KinematicTree.link_poses` gives matrices.
"""
from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np
from transforms3d.euler import euler2mat, euler2quat
from transforms3d.quaternions import axangle2quat, qmult, quat2mat, rotate_vector

from pppbot_description.urdf_model import Joint, JointType, Origin, RobotModel

Quaternion = tuple[float, float, float, float]
Vector3 = tuple[float, float, float]


@dataclass(frozen=True)
class FrameTransform:
    parent: str
    child: str
    translation: Vector3
    rotation: Quaternion


#: URDF's and SDF's rpy in transforms3d's terms: roll about x, then pitch about y, then yaw
#: about z, all fixed ("static") axes.
RPY_AXES = "sxyz"


def rpy_quaternion(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """URDF/SDF rpy as a quaternion (w, x, y, z): transforms3d's and MuJoCo's order, not the
    messages'."""
    return euler2quat(roll, pitch, yaw, RPY_AXES)


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """URDF/SDF rpy as a 3×3 rotation matrix."""
    return euler2mat(roll, pitch, yaw, RPY_AXES)


def origin_rotation(origin: Origin) -> np.ndarray:
    """A URDF origin's rotation as a quaternion (w, x, y, z)."""
    return rpy_quaternion(*origin.rpy)


def _as_tuple3(v: np.ndarray) -> Vector3:
    return (float(v[0]), float(v[1]), float(v[2]))


def _as_quaternion(wxyz: np.ndarray) -> Quaternion:
    w, x, y, z = wxyz
    return (float(x), float(y), float(z), float(w))


def joint_transform(joint: Joint, position: float = 0.0, frame_prefix: str = "") -> FrameTransform:
    """The parent ← child transform of ``joint`` at ``position`` (rad or m)."""
    rotation = origin_rotation(joint.origin)
    translation = np.asarray(joint.origin.xyz, dtype=float)
    motion = np.asarray(joint.axis, dtype=float) * position
    if joint.type in (JointType.REVOLUTE, JointType.CONTINUOUS):
        angle = float(np.linalg.norm(motion))
        if angle > 0.0:
            rotation = qmult(rotation, axangle2quat(motion / angle, angle, is_normalized=True))
    elif joint.type is JointType.PRISMATIC:
        translation = translation + rotate_vector(motion, rotation)
    return FrameTransform(frame_prefix + joint.parent, frame_prefix + joint.child,
                          _as_tuple3(translation), _as_quaternion(rotation))


class KinematicTree:
    """The fixed and moving joints of a robot model, ready to turn positions into transforms."""

    def __init__(self, model: RobotModel, frame_prefix: str = "") -> None:
        self.model = model
        self.frame_prefix = frame_prefix
        self.fixed_joints = [j for j in model.walk() if j.type is JointType.FIXED]
        self.moving_joints = {j.name: j for j in model.walk() if j.type.moves}
        self.ignored_joints = {j.name for j in model.walk() if not j.type.moves and j.type is not JointType.FIXED}

    def fixed_transforms(self) -> list[FrameTransform]:
        """Every fixed joint's transform (for /tf_static)."""
        return [joint_transform(j, 0.0, self.frame_prefix) for j in self.fixed_joints]

    def unknown_names(self, names: Iterable[str]) -> list[str]:
        """Names that are no joint of the model."""
        return [n for n in names if n not in self.model.joints]

    def moving_transforms(self, positions: Mapping[str, float]) -> list[FrameTransform]:
        """Transforms of the moving joints that ``positions`` determines (directly or by mimic).

        Names that are not moving joints and non-finite positions are skipped.
        """
        out = []
        for name, joint in self.moving_joints.items():
            position = positions.get(name)
            if position is None and joint.mimic is not None and joint.mimic.joint in positions:
                position = joint.mimic.multiplier * positions[joint.mimic.joint] + joint.mimic.offset
            if position is None or not math.isfinite(position):
                continue
            out.append(joint_transform(joint, position, self.frame_prefix))
        return out

    def link_poses(self, positions: Mapping[str, float] | None = None) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Each link's pose in the root frame (translation, 3×3 rotation matrix); unset joints at 0."""
        positions = positions or {}
        poses: dict[str, tuple[np.ndarray, np.ndarray]] = {self.model.root: (np.zeros(3), np.eye(3))}
        for joint in self.model.walk():
            q = positions.get(joint.name, 0.0) if joint.type.moves else 0.0
            t = joint_transform(joint, q)
            parent_t, parent_r = poses[joint.parent]
            x, y, z, w = t.rotation
            poses[joint.child] = (parent_t + parent_r @ np.asarray(t.translation), parent_r @ quat2mat([w, x, y, z]))
        return poses
