"""Build MuJoCo models with MjSpec: a world (from SDF data or an MJCF file) and a URDF robot.

The robot is converted here rather than by MuJoCo's URDF import, which fuses
fixed links away with their frames and makes the base static. Here the root link
gets a free joint at the spawn pose; links on fixed joints become child bodies
that MuJoCo fuses into their parent (``fusestatic``) while each keeps a site
named after its link, so sensors and TF frames stay addressable; continuous and
revolute joints become hinges, prismatic ones slides; joints of the
``<ros2_control>`` block with a velocity command interface get a velocity servo
limited to its min/max. Robot geoms live in geom group :data:`ROBOT_GROUP`, which
the lidar and ground-truth maps leave out.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np
from transforms3d.quaternions import mat2quat

from pppbot_description.kinematics import rpy_quaternion
from pppbot_description.urdf_model import Geometry, Joint, JointType, Origin, RobotModel
from pppbot_sim.contacts import DEFAULT_MU, UNSIMULATED_DEFAULTS, URDF_UNSIMULATED, Surface, friction_priorities
from pppbot_sim.errors import SpawnError, WorldError
from pppbot_sim.meshes import load_mesh
from pppbot_sim.sdf_joints import JointKind, ModelJoint
from pppbot_sim.sdf_lights import add_lighting
from pppbot_sim.sdf_model import Body, Shape, World
from pppbot_sim.sdf_world import resource_paths
from pppbot_sim.uris import UriError, resolve_uri

ROBOT_GROUP = 3
_mesh_ids = itertools.count()


@dataclass(frozen=True)
class SpawnPose:
    """Where the robot's root link starts, in the world frame (m, rad)."""

    x: float = 0.0
    y: float = 0.0
    z: float = 0.05  # NaN: resting on whatever lies beneath (x, y)
    yaw: float = 0.0

    def validate(self) -> None:
        for name in ("x", "y", "z", "yaw"):
            value = getattr(self, name)
            if not (math.isfinite(value) or (name == "z" and math.isnan(value))):
                raise SpawnError(f"spawn {name} = {value}: must be a finite number" + (" (or nan: resting on the "
                                                                                      "ground)" if name == "z" else ""))


@dataclass(frozen=True)
class WheelDrive:
    """How wheel velocity servos behave (MuJoCo actuator and joint settings)."""

    kv: float = 2.0  # N·m per rad/s of velocity error
    armature: float = 0.001  # kg·m², added rotor inertia: keeps the stiff servo stable
    damping: float = 0.0


@dataclass
class RobotHandles:
    """Names in the compiled model that belong to the robot."""

    name: str
    root_body: str
    free_joint: str
    sites: dict[str, str] = field(default_factory=dict)  # link → site
    surfaces: dict[str, Surface] = field(default_factory=dict)  # link → its friction
    warnings: list[str] = field(default_factory=list)  # what of the description is not simulated
    wheel_joints: list[str] = field(default_factory=list)  # joint names with a velocity servo
    actuators: dict[str, str] = field(default_factory=dict)  # joint → actuator
    velocity_limits: dict[str, tuple[float, float]] = field(default_factory=dict)
    moving_joints: list[str] = field(default_factory=list)


def quat_wxyz(matrix: np.ndarray) -> list[float]:
    return [float(v) for v in mat2quat(matrix)]


def rpy_quat_wxyz(roll: float, pitch: float, yaw: float) -> list[float]:
    """URDF/SDF rpy as MuJoCo's quaternion (w, x, y, z)."""
    return [float(v) for v in rpy_quaternion(roll, pitch, yaw)]


# -------------------------------------------------------------------- world
def _add_shape(spec: mujoco.MjSpec, body: mujoco.MjsBody, shape: Shape, group: int = 0) -> None:
    pos = shape.pose[:3, 3]
    quat = quat_wxyz(shape.pose[:3, :3])
    friction = [shape.surface.isotropic, 0.005, 0.0001]
    if shape.kind == "mesh":
        if shape.mesh is None:
            raise WorldError(f"collision '{shape.name}': mesh without a file")
        vertices, faces = load_mesh(shape.mesh, shape.scale)
        mesh_name = f"mesh{next(_mesh_ids)}_{shape.mesh.stem}"
        spec.add_mesh(name=mesh_name, uservert=vertices.ravel().tolist(), userface=faces.ravel().tolist())
        body.add_geom(name=shape.name, type=mujoco.mjtGeom.mjGEOM_MESH, meshname=mesh_name,
                      pos=pos, quat=quat, friction=friction, group=group)
        return
    geom_type, size = _primitive(shape)
    body.add_geom(name=shape.name, type=geom_type, size=size, pos=pos, quat=quat, friction=friction, group=group)


def _primitive(shape: Shape) -> tuple[mujoco.mjtGeom, list[float]]:
    """MuJoCo type and size (half extents, half lengths) of a primitive SDF shape."""
    s = shape.size
    G = mujoco.mjtGeom
    if shape.kind == "box":
        return G.mjGEOM_BOX, [v / 2 for v in s]
    if shape.kind == "cylinder":
        return G.mjGEOM_CYLINDER, [s[0], s[1] / 2, 0.0]
    if shape.kind == "capsule":
        return G.mjGEOM_CAPSULE, [s[0], s[1] / 2, 0.0]
    if shape.kind == "sphere":
        return G.mjGEOM_SPHERE, [s[0], 0.0, 0.0]
    if shape.kind == "ellipsoid":
        return G.mjGEOM_ELLIPSOID, list(s)
    if shape.kind == "plane":
        return G.mjGEOM_PLANE, [s[0] / 2, s[1] / 2, 1.0]
    raise WorldError(f"collision '{shape.name}': no MuJoCo primitive for '{shape.kind}'")


def world_spec(world: World) -> mujoco.MjSpec:
    """A MuJoCo spec of an SDF world: static shapes in the world body; each link of a model that
    is not static a body, nested in its joint's parent (free when no joint holds it)."""
    spec = mujoco.MjSpec()
    spec.modelname = world.name
    spec.option.timestep = world.step_size_s
    spec.option.gravity = list(world.gravity)
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.compiler.degree = False  # SDF's angles are radians
    for shape in world.static_shapes:
        _add_shape(spec, spec.worldbody, shape)
    add_lighting(spec, world.lighting)
    held = {joint.child: joint for joint in world.joints}
    children: dict[str, list[Body]] = {}
    for body in world.bodies:
        parent = held[body.name].parent if body.name in held else "world"
        children.setdefault(parent, []).append(body)
    stack: list[tuple[mujoco.MjsBody, np.ndarray, Body]] = [
        (spec.worldbody, np.eye(4), body) for body in reversed(children.get("world", []))]
    while stack:
        parent_spec, parent_pose, body = stack.pop()
        local = np.linalg.inv(parent_pose) @ body.pose
        b = parent_spec.add_body(name=body.name, pos=local[:3, 3], quat=quat_wxyz(local[:3, :3]))
        if body.name in held:
            _add_model_joint(b, held[body.name], body.pose)
        else:
            b.add_freejoint(name=f"{body.name}::free")
        for shape in body.shapes:
            _add_shape(spec, b, shape)
        _set_inertia(b, body)
        stack.extend((b, body.pose, child) for child in reversed(children.get(body.name, [])))
    return spec


def _set_inertia(b: mujoco.MjsBody, body: Body) -> None:
    """The link's mass and inertia; without an inertia matrix (``auto``), from its shapes, scaled to its mass."""
    if body.inertia is not None:
        ixx, ixy, ixz, iyy, iyz, izz = body.inertia
        com = body.inertial_pose if body.inertial_pose is not None else np.eye(4)
        b.explicitinertial = True
        b.mass = body.mass
        b.ipos = com[:3, 3]
        b.iquat = quat_wxyz(com[:3, :3])
        b.fullinertia = [ixx, iyy, izz, ixy, ixz, iyz]
        return
    volume_mass = sum(1000.0 * _shape_volume(s) for s in body.shapes) or 1.0
    for geom in b.geoms:
        geom.density = 1000.0 * body.mass / volume_mass


def _add_model_joint(b: mujoco.MjsBody, joint: ModelJoint, body_pose: np.ndarray) -> None:
    """``joint`` on body ``b`` (its child link, at ``body_pose`` in the world): a hinge, slide,
    ball, two hinges, or nothing for a fixed joint."""
    rotation = body_pose[:3, :3]
    pos = rotation.T @ (joint.anchor - body_pose[:3, 3])
    if joint.kind is JointKind.BALL:
        b.add_joint(name=joint.name, type=mujoco.mjtJoint.mjJNT_BALL, pos=pos)
        return
    kind = mujoco.mjtJoint.mjJNT_SLIDE if joint.kind is JointKind.PRISMATIC else mujoco.mjtJoint.mjJNT_HINGE
    for i, axis in enumerate(joint.axes):
        j = b.add_joint(name=joint.name if i == 0 else f"{joint.name}::axis2", type=kind, pos=pos,
                        axis=rotation.T @ axis.direction, damping=axis.damping, frictionloss=axis.friction,
                        stiffness=axis.spring_stiffness, springref=axis.spring_reference)
        if axis.limited and joint.kind is not JointKind.CONTINUOUS:
            j.limited = mujoco.mjtLimited.mjLIMITED_TRUE
            j.range = [max(axis.lower, -1e10), min(axis.upper, 1e10)]


def add_velocity_servos(spec: mujoco.MjSpec, joints: dict[str, tuple[float, float, float]],
                        drive: WheelDrive) -> dict[str, str]:
    """A velocity servo on each named world joint (its (min, max) velocity in rad/s or m/s and its
    effort limit; inf: none); returns joint → actuator name.

    Raises:
        WorldError: a name that is not a hinge or slide of the world.
    """
    actuators = {}
    for name, (low, high, effort) in joints.items():
        joint = spec.joint(name)
        if joint is None or joint.type not in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE):
            raise WorldError(f"joint '{name}' to drive is not a revolute, continuous or prismatic joint of the world")
        joint.armature = max(joint.armature, drive.armature)
        actuator = spec.add_actuator(name=f"{name}::velocity", target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        actuator.set_to_velocity(kv=drive.kv)
        _limit_servo(actuator, low, high, effort)
        actuators[name] = actuator.name
    return actuators


def _limit_servo(actuator: mujoco.MjsActuator, low: float, high: float, effort: float) -> None:
    if math.isfinite(low) and math.isfinite(high):
        actuator.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
        actuator.ctrlrange = [low, high]
    if math.isfinite(effort):
        actuator.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        actuator.forcerange = [-effort, effort]


def _shape_volume(shape: Shape) -> float:
    s = shape.size
    return {
        "box": lambda: s[0] * s[1] * s[2],
        "cylinder": lambda: math.pi * s[0] ** 2 * s[1],
        "capsule": lambda: math.pi * s[0] ** 2 * (s[1] + 4.0 * s[0] / 3.0),
        "sphere": lambda: 4.0 / 3.0 * math.pi * s[0] ** 3,
        "ellipsoid": lambda: 4.0 / 3.0 * math.pi * s[0] * s[1] * s[2],
    }.get(shape.kind, lambda: 0.001)()


def mjcf_world_spec(path: Path) -> mujoco.MjSpec:
    """A MuJoCo spec from an MJCF file.

    Raises:
        WorldError: MuJoCo cannot parse it.
    """
    try:
        spec = mujoco.MjSpec.from_file(str(path))
    except ValueError as exc:
        raise WorldError(f"{path}: {exc}") from exc
    return spec


# -------------------------------------------------------------------- robot
def _origin_pose(origin: Origin) -> tuple[list[float], list[float]]:
    return list(origin.xyz), rpy_quat_wxyz(*origin.rpy)


def _add_robot_geom(spec: mujoco.MjSpec, body: mujoco.MjsBody, name: str, geometry: Geometry, origin: Origin,
                    surface: Surface) -> None:
    pos, quat = _origin_pose(origin)
    # Priorities come last, from every geom's friction (apply_friction_rule).
    common = {"name": name, "pos": pos, "quat": quat, "group": ROBOT_GROUP, "mass": 0.0, "density": 0.0,
              "friction": [surface.isotropic, 0.005, 0.0001]}
    if geometry.kind == "box":
        body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[v / 2 for v in geometry.size], **common)
    elif geometry.kind == "cylinder":
        body.add_geom(type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[geometry.size[0], geometry.size[1] / 2, 0],
                      **common)
    elif geometry.kind == "sphere":
        body.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[geometry.size[0], 0, 0], **common)
    else:
        try:
            path, _ = resolve_uri(geometry.filename, Path.cwd(), resource_paths())
        except UriError as exc:
            raise SpawnError(f"robot mesh of '{name}': {exc}") from exc
        if not path.is_file():
            raise SpawnError(f"robot mesh '{geometry.filename}' of '{name}' not found (looked at {path})")
        vertices, faces = load_mesh(path, geometry.scale)
        mesh_name = f"mesh{next(_mesh_ids)}_{path.stem}"
        spec.add_mesh(name=mesh_name, uservert=vertices.ravel().tolist(), userface=faces.ravel().tolist())
        body.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=mesh_name, **common)


def _link_body(spec: mujoco.MjSpec, body: mujoco.MjsBody, model: RobotModel, link_name: str,
               handles: RobotHandles, prefix: str) -> None:
    link = model.links[link_name]
    handles.sites[link_name] = f"{prefix}{link_name}"
    body.add_site(name=f"{prefix}{link_name}", pos=[0, 0, 0])
    if link.inertial is not None:
        body.explicitinertial = True
        body.mass = link.inertial.mass
        body.ipos, body.iquat = _origin_pose(link.inertial.origin)
        ixx, ixy, ixz, iyy, iyz, izz = link.inertial.inertia
        body.fullinertia = [ixx, iyy, izz, ixy, ixz, iyz]
    surface = link_surface(model, link_name, handles.warnings)
    if link.collisions:
        handles.surfaces[link_name] = surface
    for i, shape in enumerate(link.collisions):
        _add_robot_geom(spec, body, f"{prefix}{link_name}::collision{i}", shape.geometry, shape.origin, surface)


#: ``<gazebo reference="link">`` settings with no bearing on physics or the sensors.
_GAZEBO_COSMETIC = {"material", "visual", "laserRetro", "provideFeedback", "maxContacts", "fdir1", "sensor"}


def link_surface(model: RobotModel, link: str, warnings: list[str]) -> Surface:
    """A link's friction from its ``<gazebo reference>`` ``mu1``/``mu2`` (SDF's 1 without); the
    settings pppbot does not simulate are added to ``warnings``.

    Raises:
        SpawnError: ``mu1`` or ``mu2`` is not a non-negative number.
    """
    settings = model.gazebo_settings.get(link, {})
    values = []
    for key in ("mu1", "mu2"):
        try:
            value = float(settings.get(key, DEFAULT_MU))
        except ValueError:
            value = -1.0
        if not value >= 0:
            raise SpawnError(f"<gazebo reference='{link}'><{key}> must be a non-negative number, not "
                             f"{settings[key]!r}")
        values.append(value)
    for key, text in settings.items():
        if key in ("mu1", "mu2") or key in _GAZEBO_COSMETIC:
            continue
        sdf = URDF_UNSIMULATED.get(key)
        try:
            unchanged = sdf is not None and float(text) == UNSIMULATED_DEFAULTS[sdf]
        except ValueError:
            unchanged = False
        if not unchanged:
            warnings.append(f"<gazebo reference='{link}'><{key}> {text} of robot '{model.name}' is not simulated")
    return Surface(values[0], values[1])


def apply_friction_rule(spec: mujoco.MjSpec) -> None:
    """Every geom's priority from its friction, so that two touching geoms get the smaller of
    their frictions, as Gazebo's ODE gives them (:func:`pppbot_sim.contacts.friction_priorities`)."""
    geoms = list(spec.geoms)
    priorities = friction_priorities(float(g.friction[0]) for g in geoms)
    for geom in geoms:
        geom.priority = priorities[float(geom.friction[0])]


def _add_joint(body: mujoco.MjsBody, joint: Joint, drive: WheelDrive, prefix: str, degrees: bool) -> None:
    """``joint`` on ``body``; ``degrees``: the spec reads angles in degrees (an MJCF world's default)."""
    name = f"{prefix}{joint.name}"
    if joint.type in (JointType.CONTINUOUS, JointType.REVOLUTE):
        j = body.add_joint(name=name, type=mujoco.mjtJoint.mjJNT_HINGE, axis=list(joint.axis),
                           armature=drive.armature, damping=drive.damping)
    else:
        j = body.add_joint(name=name, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=list(joint.axis),
                           armature=drive.armature, damping=drive.damping)
    if joint.type in (JointType.REVOLUTE, JointType.PRISMATIC) and math.isfinite(joint.lower):
        j.limited = mujoco.mjtLimited.mjLIMITED_TRUE
        scale = math.degrees(1.0) if degrees and joint.type is JointType.REVOLUTE else 1.0
        j.range = [joint.lower * scale, joint.upper * scale]


def robot_servos(model: RobotModel,
                 wheel_torques: dict[str, float] | None = None) -> dict[str, tuple[float, float, float]]:
    """The robot's joints with a velocity servo, each with its (min, max) velocity and effort
    limit: those of the ``<ros2_control>`` block with a velocity command interface (its min/max,
    the URDF's effort), and the wheels of a DiffDrive plugin (``wheel_torques``: joint → the
    plugin's torque limit; the URDF's velocity and effort limits).

    Raises:
        SpawnError: a plugin's wheel that the robot does not have.
    """
    servos = {}
    for joint_name, control in model.control_joints.items():
        if "velocity" in control.command_interfaces and joint_name in model.joints:
            low, high = control.command_interfaces["velocity"]
            servos[joint_name] = (low, high, model.joints[joint_name].effort_limit)
    for joint_name, torque in (wheel_torques or {}).items():
        joint = model.joints.get(joint_name)
        if joint is None:
            raise SpawnError(f"the DiffDrive plugin's wheel joint '{joint_name}' is not a joint of robot "
                             f"'{model.name}' (joints: {', '.join(model.joints)})")
        if joint_name not in servos:
            servos[joint_name] = (-joint.velocity_limit, joint.velocity_limit, min(torque, joint.effort_limit))
    return servos


def add_robot(spec: mujoco.MjSpec, model: RobotModel, pose: SpawnPose, name: str = "ppp_bot",
              drive: WheelDrive = WheelDrive(),
              servos: dict[str, tuple[float, float, float]] | None = None) -> RobotHandles:
    """Add ``model`` to ``spec`` at ``pose``; return the names it got. ``servos``: the joints with a
    velocity servo (default: :func:`robot_servos` of the model).

    Raises:
        SpawnError: a floating or planar joint, a bad spawn pose, a servo on a joint that does not move.
    """
    pose.validate()
    spec.compiler.fusestatic = True
    prefix = f"{name}/"
    root = model.root
    z = pose.z if math.isfinite(pose.z) else 0.0  # NaN: the simulation puts it down once the world is built
    base = spec.worldbody.add_body(name=f"{prefix}{root}", pos=[pose.x, pose.y, z],
                                   quat=rpy_quat_wxyz(0.0, 0.0, pose.yaw))
    handles = RobotHandles(name=name, root_body=f"{prefix}{root}", free_joint=f"{prefix}free")
    base.add_freejoint(name=handles.free_joint)
    _link_body(spec, base, model, root, handles, prefix)
    stack = [(base, j) for j in reversed(model.children_of(root))]
    while stack:
        parent_body, joint = stack.pop()
        if joint.type in (JointType.FLOATING, JointType.PLANAR):
            raise SpawnError(f"joint '{joint.name}' is {joint.type.value}; the simulator supports fixed, "
                             "continuous, revolute and prismatic joints")
        pos, quat = _origin_pose(joint.origin)
        body = parent_body.add_body(name=f"{prefix}{joint.child}", pos=pos, quat=quat)
        if joint.type is not JointType.FIXED:
            _add_joint(body, joint, drive, prefix, bool(spec.compiler.degree))
            handles.moving_joints.append(joint.name)
        _link_body(spec, body, model, joint.child, handles, prefix)
        stack.extend((body, j) for j in reversed(model.children_of(joint.child)))
    for joint_name, (low, high, effort) in (robot_servos(model) if servos is None else servos).items():
        if joint_name not in handles.moving_joints:
            raise SpawnError(f"joint '{joint_name}' to drive is not a continuous, revolute or prismatic joint of "
                             f"robot '{model.name}'")
        actuator = spec.add_actuator(name=f"{prefix}{joint_name}::velocity", target=f"{prefix}{joint_name}",
                                     trntype=mujoco.mjtTrn.mjTRN_JOINT)
        actuator.set_to_velocity(kv=drive.kv)
        _limit_servo(actuator, low, high, effort)
        handles.wheel_joints.append(joint_name)
        handles.actuators[joint_name] = actuator.name
        handles.velocity_limits[joint_name] = (low, high)
    return handles


def depth_below(model: mujoco.MjModel, data: mujoco.MjData, body: int, group: int = ROBOT_GROUP) -> float:
    """How far the lowest point of the geoms of ``group`` lies below body ``body``'s origin, as
    placed now (after kinematics): the height ``body`` rests at on flat ground (m; 0 without
    geoms). Boxes, spheres, cylinders and capsules exactly; meshes by their vertices."""
    lowest = float(data.xpos[body][2])
    G = mujoco.mjtGeom
    for gid in np.flatnonzero(model.geom_group == group):
        rotation = data.geom_xmat[gid].reshape(3, 3)
        size, kind = model.geom_size[gid], int(model.geom_type[gid])
        if kind == int(G.mjGEOM_MESH):
            mesh = model.geom_dataid[gid]
            start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
            bottom = float((model.mesh_vert[start:start + count] @ rotation.T)[:, 2].min())
        elif kind == int(G.mjGEOM_SPHERE):
            bottom = -size[0]
        elif kind == int(G.mjGEOM_BOX):
            bottom = -float(np.abs(rotation[2]) @ size)
        elif kind in (int(G.mjGEOM_CYLINDER), int(G.mjGEOM_CAPSULE)):
            along = abs(rotation[2, 2])
            radial = size[0] if kind == int(G.mjGEOM_CAPSULE) else size[0] * math.sqrt(max(0.0, 1 - along**2))
            bottom = -(along * size[1] + radial)
        else:
            continue
        lowest = min(lowest, float(data.geom_xpos[gid][2]) + bottom)
    # to the micrometre: what the description's sums give, without their rounding noise
    return round(float(data.xpos[body][2]) - lowest, 6)


def surface_below(model: mujoco.MjModel, data: mujoco.MjData, x: float, y: float) -> float | None:
    """The height of the highest world surface (not the robot's) under (x, y), or None (nothing there)."""
    groups = np.ones(6, dtype=np.uint8)
    groups[ROBOT_GROUP] = 0
    top = 1e4
    hit = np.array([-1], dtype=np.int32)
    distance = mujoco.mj_ray(model, data, np.array([x, y, top]), np.array([0.0, 0.0, -1.0]), groups, 1, -1, hit)
    return None if distance < 0 else top - float(distance)
