"""Read the SDF subset Gazebo worlds use into plain data (shapes with world poses).

Supported: ``<world>`` with ``<physics><max_step_size>`` and ``<gravity>``;
``<model>`` (static or not, nested) with ``<pose>``, ``<link>`` with ``<pose>``,
``<inertial><mass>`` and ``<collision>`` (``<pose>``, ``<geometry>`` box, cylinder,
sphere, capsule, ellipsoid, plane, mesh with ``<uri>`` and ``<scale>``,
``<surface><friction><ode>`` ``<mu>``/``<mu2>``, combined as Gazebo combines them:
:mod:`pppbot_sim.contacts`); ``<include>`` with ``<name>``, ``<pose>``,
``<static>``; URIs (``model://`` through ``GZ_SIM_RESOURCE_PATH``, ``IGN_GAZEBO_RESOURCE_PATH``
and ``worlds/models/``, ``package://``, ``file://``, paths, Fuel URLs) as
:mod:`pppbot_sim.uris` resolves them. Poses follow SDF 1.7's frame semantics
(:mod:`pppbot_sim.sdf_frames`): ``<frame name attached_to>``, ``relative_to`` on the poses of
links, collisions, models, includes, joints and frames, ``__model__``, an empty ``<pose/>`` as
the identity in its frame. Poses compose
world ∘ model ∘ nested model ∘ link ∘ collision, each ``x y z roll pitch yaw``
(fixed axes, as Gazebo) or ``degrees="true"``.

A saved world's ``<state>`` puts models, free links and joints where Gazebo classic puts them
at load (:mod:`pppbot_sim.sdf_state`). Links of models that are not static are bodies with
their ``<inertial>`` (SDF's defaults
where it says nothing: 1 kg, inertia 1 kg·m² about each axis, as Gazebo takes them;
``<inertial auto="true">`` from the collisions at 1000 kg/m³, scaled to its ``<mass>``).
Their ``<joint>`` elements join them (:mod:`pppbot_sim.sdf_joints`); a link that no joint holds
is free. A model's ``<plugin>`` elements are kept for the simulator (Gazebo's DiffDrive);
world ``<plugin>`` elements (Gazebo's system plugins), ``<gui>`` and the lights of models are
skipped and summed up in one info line; the world's ``<light>`` elements and ``<scene><ambient>``
light the cameras' images (:mod:`pppbot_sim.sdf_lights`); other elements that carry no collision (visuals, scene,
...) are known and ignored; anything else is reported by name and line in ``World.warnings``.
"""
from __future__ import annotations

import math
import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from lxml import etree
from transforms3d.axangles import axangle2mat
from transforms3d.quaternions import quat2mat

from pppbot_common.xml_files import XmlFileError, parse_xml
from pppbot_description.kinematics import rpy_matrix
from pppbot_sim.contacts import DEFAULT_MU, UNSIMULATED_DEFAULTS, Surface
from pppbot_sim.errors import WorldError
from pppbot_sim.sdf_frames import FrameGraph
from pppbot_sim.sdf_joints import JointKind, ModelJoint, joint_kind, read_axis
from pppbot_sim.sdf_lights import read_lighting
from pppbot_sim.sdf_model import DEFAULT_MASS_KG, Body, ModelPlugin, Shape, World
from pppbot_sim.sdf_state import WorldState, move_free_links, named, read_state
from pppbot_sim.uris import UriError, check_inside, fuel_caches, resolve_uri

SKIPPED = {"gui", "plugin", "light"}
# Elements that carry nothing a collision world needs; ignored without a word.
IGNORED = {
    "visual", "scene", "audio", "audio_source", "audio_sink", "wind", "atmosphere", "spherical_coordinates",
    "magnetic_field", "enable_wind", "allow_auto_disable", "battery", "laser_retro", "max_contacts",
}
SHAPES = {"box", "cylinder", "sphere", "capsule", "ellipsoid", "plane", "mesh"}
MESH_SUFFIXES = {".stl", ".obj", ".dae"}


@dataclass(frozen=True)
class ScopedModel:
    """A model to read: its element and file, its name in its scope, its ``<static>`` override."""

    element: etree._Element
    file: Path
    name: str
    static: bool | None


def z_onto(direction: np.ndarray) -> np.ndarray:
    """The shortest rotation taking +z onto ``direction`` (nonzero), as a matrix."""
    n = np.asarray(direction, dtype=float) / np.linalg.norm(direction)
    axis = np.cross([0.0, 0.0, 1.0], n)
    sin = float(np.linalg.norm(axis))
    if sin < 1e-12:  # along z already, or against it: half a turn about x
        return np.eye(3) if n[2] > 0 else np.diag([1.0, -1.0, -1.0])
    return axangle2mat(axis / sin, math.atan2(sin, float(n[2])), is_normalized=True)


def pose_matrix(xyz: Iterable[float], rpy: Iterable[float]) -> np.ndarray:
    t = np.eye(4)
    roll, pitch, yaw = rpy
    t[:3, :3] = rpy_matrix(roll, pitch, yaw)
    t[:3, 3] = list(xyz)
    return t


def resource_paths(extra: Iterable[Path] = ()) -> list[Path]:
    """Where ``model://`` URIs are looked up, in order."""
    paths = [Path(p) for p in extra]
    for var in ("GZ_SIM_RESOURCE_PATH", "IGN_GAZEBO_RESOURCE_PATH"):
        paths += [Path(p) for p in os.environ.get(var, "").split(os.pathsep) if p]
    return paths


class _Reader:
    def __init__(self, source: Path, search: list[Path]) -> None:
        self.source = source
        self.search = search
        self.world = World(name=source.stem, source=source)
        self.including: list[str] = []
        self.link_poses: dict[str, np.ndarray] = {}  # every link's world pose, by scoped name
        self.static_links: set[str] = set()
        self.canonical: dict[str, str] = {}  # model → its canonical link, scoped names
        self.named_surfaces: set[str] = set()  # unsimulated surface settings already named
        self.state = WorldState()  # the world's <state>, when it has one

    # ---------------------------------------------------------------- helpers
    def fail(self, element: etree._Element | None, message: str, file: Path | None = None) -> WorldError:
        where = str(file or self.source)
        if element is not None and element.sourceline:
            where += f":{element.sourceline}"
        return WorldError(f"{where}: {message}")

    def warn(self, element: etree._Element, message: str, file: Path) -> None:
        self.world.warnings.append(f"{file}:{element.sourceline}: {message}")

    def floats(self, element: etree._Element, count: int | tuple[int, ...], file: Path) -> list[float]:
        counts = (count,) if isinstance(count, int) else count
        try:
            values = [float(v) for v in (element.text or "").split()]
        except ValueError:
            values = []
        if len(values) not in counts or not all(np.isfinite(values)):
            raise self.fail(element, f"<{element.tag}> needs {' or '.join(map(str, counts))} numbers, "
                                     f"not '{(element.text or '').strip()}'", file)
        return values

    def number(self, parent: etree._Element, tag: str, default: float | None, file: Path) -> float:
        element = parent.find(tag)
        if element is None:
            if default is None:
                raise self.fail(parent, f"<{parent.tag}> needs <{tag}>", file)
            return default
        return self.floats(element, 1, file)[0]

    def placed_pose(self, parent: etree._Element, file: Path) -> tuple[str | None, np.ndarray]:
        """``parent``'s ``<pose>``: its ``relative_to`` (None without one) and its 4×4 matrix. An
        empty ``<pose/>`` is the identity (in its ``relative_to`` frame), as in SDF 1.7."""
        element = parent.find("pose")
        if element is None:
            return None, np.eye(4)
        relative = element.get("relative_to") or None
        if not (element.text or "").strip():
            return relative, np.eye(4)
        values = self.floats(element, (6, 7), file)
        if len(values) == 7 or element.get("rotation_format") == "quat_xyzw":
            if len(values) != 7 or not np.linalg.norm(values[3:7]) > 1e-6:  # quat2mat reads ~0 as identity
                raise self.fail(element, f"<pose rotation_format='quat_xyzw'> needs x y z qx qy qz qw with a "
                                         f"nonzero quaternion, not '{(element.text or '').strip()}'", file)
            qx, qy, qz, qw = values[3:7]
            t = np.eye(4)
            t[:3, :3] = quat2mat([qw, qx, qy, qz])
            t[:3, 3] = values[:3]
            return relative, t
        rpy = np.radians(values[3:]) if element.get("degrees") == "true" else values[3:]
        return relative, pose_matrix(values[:3], rpy)

    def pose(self, parent: etree._Element, file: Path) -> np.ndarray:
        """A ``<pose>`` that is always in its parent's frame (``<inertial>``)."""
        return self.placed_pose(parent, file)[1]

    def note_unknown(self, element: etree._Element, allowed: set[str], file: Path) -> None:
        for child in element:
            if not isinstance(child.tag, str) or child.tag in allowed:
                continue
            if child.tag in SKIPPED:
                self.world.skipped[child.tag] += 1
            elif child.tag not in IGNORED:
                self.warn(child, f"unsupported element <{child.tag}> in <{element.tag}> ignored", file)

    # --------------------------------------------------------------- resolving
    def resolve(self, uri: str, element: etree._Element, file: Path) -> Path:
        """The path a ``<uri>`` names (:mod:`pppbot_sim.uris`); a warning when it had to be guessed."""
        try:
            path, warning = resolve_uri(uri, file.parent, self.search, fuel_caches(), within=[self.source.parent])
        except UriError as exc:
            raise self.fail(element, str(exc), file) from exc
        if warning is not None:
            self.warn(element, warning, file)
        return path

    def model_directory(self, uri: str, element: etree._Element, file: Path) -> Path:
        path = self.resolve(uri, element, file)
        if path.is_dir():
            return path
        raise self.fail(element, f"<uri>{uri}</uri>: no such model directory {path}", file)

    def mesh_path(self, uri: str, element: etree._Element, file: Path) -> Path:
        path = self.resolve(uri, element, file)
        if not path.is_file():
            raise self.fail(element, f"mesh file not found: {uri} (looked at {path})", file)
        if path.suffix.lower() not in MESH_SUFFIXES:
            raise self.fail(element, f"mesh {path.name}: format {path.suffix} not supported (STL, OBJ, DAE)", file)
        return path

    # ----------------------------------------------------------------- reading
    def read_world(self, root: etree._Element) -> World:
        world_el = root.find("world") if root.tag == "sdf" else None
        if world_el is None:
            raise self.fail(root, "expected <sdf><world>...</world></sdf>")
        self.world.name = world_el.get("name") or self.source.stem
        self.note_unknown(world_el, {"physics", "gravity", "model", "include", "frame", "state", "light"},
                          self.source)
        self.world.lighting = read_lighting(world_el, lambda e: self.pose(e, self.source),
                                            lambda e, n: self.floats(e, n, self.source))
        state_el = world_el.find("state")
        if state_el is not None:
            self.state = read_state(state_el, lambda e: self.pose(e, self.source),
                                    lambda e: self.floats(e, 1, self.source)[0])
            self.world.warnings += [named(e, self.source) for e in self.state.ignored]
        physics = world_el.find("physics")
        if physics is not None:
            step = self.number(physics, "max_step_size", 0.001, self.source)
            if not 0 < step <= 0.1:
                raise self.fail(physics.find("max_step_size"), f"max_step_size {step} s must be in (0, 0.1]")
            self.world.step_size_s = step
        gravity = world_el.find("gravity")
        if gravity is not None:
            g = self.floats(gravity, 3, self.source)
            self.world.gravity = (g[0], g[1], g[2])
        graph = FrameGraph("world", f"world '{self.world.name}'")
        models = self.scope_models(world_el, self.source, graph, "world")
        for model in models:
            self.read_model(model, self.state.models.get(model.name, graph.resolve(model.name)), prefix="")
        self.world.joints = move_free_links(self.world.bodies, self.world.joints, self.state.links)
        known = {j.name for j in self.world.joints}
        self.world.joint_positions = {name: angles for name, angles in self.state.joints.items() if name in known}
        # A free link with nothing to collide would only fall for ever.
        kept = {j.child for j in self.world.joints} | {j.parent for j in self.world.joints}
        self.world.bodies = [b for b in self.world.bodies if b.shapes or b.name in kept]
        return self.world

    def scope_models(self, scope: etree._Element, file: Path, graph: FrameGraph, root: str) -> list[ScopedModel]:
        """Put ``scope``'s models, includes and ``<frame>`` elements in ``graph``; the models to read."""
        models: list[ScopedModel] = []
        for child in scope:
            if child.tag == "model":
                models.append(ScopedModel(child, file, child.get("name") or "model", None))
                relative, pose = self.placed_pose(child, file)
            elif child.tag == "include":
                models.append(self.include_target(child, file))
                # An <include>'s pose replaces the model's own pose (Gazebo's rule).
                source = child if child.find("pose") is not None else models[-1].element
                relative, pose = self.placed_pose(source, file if source is child else models[-1].file)
            elif child.tag == "frame":
                attached = child.get("attached_to") or root
                relative, pose = self.placed_pose(child, file)
                graph.add(self.frame_name(child, file), relative or attached, pose, file, child.sourceline)
                continue
            else:
                continue
            graph.add(models[-1].name, relative or root, pose, file, child.sourceline)
        return models

    def frame_name(self, element: etree._Element, file: Path) -> str:
        name = element.get("name")
        if not name:
            raise self.fail(element, f"<{element.tag}> needs a name", file)
        return name

    def include_target(self, element: etree._Element, file: Path) -> ScopedModel:
        """The model an ``<include>`` brings in, with its ``<name>`` and ``<static>``."""
        uri_el = element.find("uri")
        if uri_el is None or not (uri_el.text or "").strip():
            raise self.fail(element, "<include> needs a <uri>", file)
        directory = self.model_directory(uri_el.text.strip(), uri_el, file)
        model_file = self.model_file(directory, uri_el, file)
        if str(model_file) in self.including:
            raise self.fail(element, f"{model_file} includes itself", file)
        try:
            root = parse_xml(model_file)
        except XmlFileError as exc:
            raise WorldError(str(exc)) from exc
        model = root.find("model") if root.tag == "sdf" else (root if root.tag == "model" else None)
        if model is None:
            raise self.fail(root, "expected <sdf><model>", model_file)
        name_el, static_el = element.find("name"), element.find("static")
        name = (name_el.text or "").strip() if name_el is not None else model.get("name", directory.name)
        static = None if static_el is None else (static_el.text or "").strip() in ("1", "true")
        return ScopedModel(model, model_file, name, static)

    def model_file(self, directory: Path, element: etree._Element, file: Path) -> Path:
        config = directory / "model.config"
        if config.is_file():
            self.inside(config, element, file)
            try:
                sdf = parse_xml(config).find("sdf")
            except XmlFileError as exc:
                raise WorldError(str(exc)) from exc
            if sdf is not None and (sdf.text or "").strip():
                named = directory / sdf.text.strip()
                if not named.is_file():
                    raise self.fail(sdf, f"<sdf>{sdf.text.strip()}</sdf>: no such file in {directory}", config)
                return self.inside(named, element, file)
        if (directory / "model.sdf").is_file():
            return self.inside(directory / "model.sdf", element, file)
        raise self.fail(element, f"model directory {directory} has no model.config or model.sdf", file)

    def inside(self, path: Path, element: etree._Element, file: Path) -> Path:
        """``path``, when it lies where this world may read (:func:`pppbot_sim.uris.check_inside`)."""
        try:
            check_inside(path, str(path), [self.source.parent, *self.search, *fuel_caches()])
        except UriError as exc:
            raise self.fail(element, str(exc), file) from exc
        return path

    def read_model(self, scoped: ScopedModel, pose: np.ndarray, prefix: str, parent_static: bool = False) -> None:
        """A model whose frame is at ``pose`` in the world: its frames, links, nested models, joints
        and plugins."""
        model, file = scoped.element, scoped.file
        full = f"{prefix}{scoped.name}"
        static = scoped.static
        if static is None:
            static_el = model.find("static")
            static = parent_static or (static_el is not None and (static_el.text or "").strip() in ("1", "true"))
        self.including.append(str(file))
        self.note_unknown(model, {"link", "model", "include", "joint", "static", "pose", "frame", "plugin"}, file)
        graph = FrameGraph("__model__", f"model '{full}'")
        links = [child for child in model if child.tag == "link"]
        for link in links:
            relative, link_pose = self.placed_pose(link, file)
            graph.add(self.frame_name(link, file), relative or "__model__", link_pose, file, link.sourceline)
        joints = model.findall("joint")
        for joint in joints:
            child_el = joint.find("child")
            relative, joint_pose = self.placed_pose(joint, file)
            default = (child_el.text or "").strip() if child_el is not None else "__model__"
            graph.add(self.frame_name(joint, file), relative or default, joint_pose, file, joint.sourceline)
        nested = self.scope_models(model, file, graph, "__model__")
        for link in links:
            self.read_link(link, pose, graph, file, full, static)
        for child in nested:
            self.read_model(child, self.state.models.get(f"{full}::{child.name}", pose @ graph.resolve(child.name)),
                            f"{full}::", static)
        canonical = model.get("canonical_link") or (links[0].get("name") if links else None)
        if canonical is not None:
            self.canonical[full] = f"{full}::{canonical}"
        elif nested and f"{full}::{nested[0].name}" in self.canonical:
            self.canonical[full] = self.canonical[f"{full}::{nested[0].name}"]
        if not static:
            for joint in joints:
                self.read_joint(joint, file, full, pose, graph)
        for plugin in model.findall("plugin"):
            link = self.canonical.get(full, f"{full}::").removeprefix(f"{full}::")
            self.world.plugins.append(ModelPlugin(full, plugin, file, link))
        self.including.pop()

    def joint_end(self, joint: etree._Element, tag: str, file: Path, model: str) -> str:
        """A joint's ``<parent>``/``<child>`` as a scoped link name, or ``world``."""
        element = joint.find(tag)
        name = (element.text or "").strip() if element is not None else ""
        if not name:
            raise self.fail(joint, f"joint '{joint.get('name')}' needs a <{tag}>", file)
        if name == "world":
            return name
        scoped = f"{model}::{name}"
        if scoped in self.link_poses:
            return scoped
        if scoped in self.canonical:  # a nested model: its canonical link
            return self.canonical[scoped]
        links = sorted(n.removeprefix(f"{model}::") for n in self.link_poses if n.startswith(f"{model}::"))
        raise self.fail(element, f"joint '{joint.get('name')}' of model '{model}': no link '{name}' "
                                 f"(links: {', '.join(links) or 'none'}, or world)", file)

    def read_joint(self, joint: etree._Element, file: Path, model: str, model_pose: np.ndarray,
                   graph: FrameGraph) -> None:
        """A joint of a model that is not static, as a :class:`ModelJoint` in world coordinates."""
        name = f"{model}::{joint.get('name')}"
        kind = joint_kind(joint, self, file)
        parent, child = self.joint_end(joint, "parent", file, model), self.joint_end(joint, "child", file, model)
        where = f"{file}:{joint.sourceline}"
        if kind is None:
            self.warn(joint, f"joint '{name}' of type {joint.get('type')} is not simulated: its child link "
                             f"'{child}' is held fixed to '{parent}'", file)
            kind = JointKind.FIXED
        if child in self.static_links:
            return  # a static link does not move, whatever holds it
        if parent in self.static_links:
            parent = "world"
        if child == parent:
            raise self.fail(joint, f"joint '{name}' joins link '{child}' to itself", file)
        held = {j.child: j for j in self.world.joints}
        if child in held:
            self.warn(joint, f"joint '{name}' ignored: link '{child}' is already the child of joint "
                             f"'{held[child].name}' (kinematic loops are not simulated)", file)
            return
        up = parent
        while up in held:
            up = held[up].parent
            if up == child:
                self.warn(joint, f"joint '{name}' ignored: it would close a kinematic loop through '{child}' "
                                 "(loops are not simulated)", file)
                return
        relative, raw = self.placed_pose(joint, file)
        frame = model_pose @ graph.resolve(joint.get("name", ""), f"{where}: ") if relative \
            else self.link_poses[child] @ raw
        axes = []
        for tag in ("axis", "axis2")[:kind.axis_count]:
            element = joint.find(tag)
            rotation = frame[:3, :3]
            xyz = element.find("xyz") if element is not None else None
            expressed = xyz.get("expressed_in") if xyz is not None else None
            legacy = element is not None and (element.findtext("use_parent_model_frame") or "").strip() in ("1", "true")
            if expressed == "__model__" or (expressed is None and legacy):
                rotation = model_pose[:3, :3]
            elif expressed and xyz is not None:
                rotation = (model_pose @ graph.resolve(expressed, f"{file}:{xyz.sourceline}: "))[:3, :3]
            axes.append(read_axis(element, rotation, self, file, name))
        self.world.joints.append(ModelJoint(name, kind, parent, child, frame[:3, 3].copy(), tuple(axes), where))

    def read_link(self, link: etree._Element, model_pose: np.ndarray, graph: FrameGraph, file: Path,
                  model: str, static: bool) -> None:
        link_name = link.get("name", "link")
        name = f"{model}::{link_name}"
        in_model = graph.resolve(link_name)
        pose = model_pose @ in_model
        self.note_unknown(link, {"collision", "pose", "inertial", "sensor"}, file)
        for sensor in link.findall("sensor"):
            self.warn(sensor, f"sensor '{sensor.get('name')}' of link '{name}' is not simulated "
                              "(only the robot's sensors are)", file)
        shapes = []
        for collision in link.findall("collision"):
            relative, raw = self.placed_pose(collision, file)
            if relative is None or relative == link_name:
                in_link = raw
            else:
                asked = f"{file}:{collision.sourceline}: "
                in_link = np.linalg.inv(in_model) @ graph.resolve(relative, asked) @ raw
            shapes.append(self.read_collision(collision, file, name, in_link))
        self.link_poses[name] = pose
        if static:
            self.static_links.add(name)
            for s in shapes:
                self.world.static_shapes.append(Shape(s.name, s.kind, s.size, pose @ s.pose, s.mesh,
                                                      s.scale, s.surface))
            return
        body = Body(name, pose, shapes)
        inertial = link.find("inertial")
        if inertial is not None:
            body.mass = self.number(inertial, "mass", DEFAULT_MASS_KG, file)
            if body.mass <= 0:
                raise self.fail(inertial.find("mass"), f"link '{name}' has mass {body.mass}; it must be positive", file)
            body.inertial_pose = self.pose(inertial, file)
            matrix = inertial.find("inertia")
            if inertial.get("auto") in ("true", "1"):
                body.inertia = None
            elif matrix is not None:
                values = tuple(self.number(matrix, k, 1.0 if k in ("ixx", "iyy", "izz") else 0.0, file)
                               for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"))
                full = np.array([[values[0], values[1], values[2]], [values[1], values[3], values[4]],
                                 [values[2], values[4], values[5]]])
                if np.linalg.eigvalsh(full).min() <= 0:
                    raise self.fail(matrix, f"link '{name}': the inertia matrix must be positive definite", file)
                body.inertia = (values[0], values[1], values[2], values[3], values[4], values[5])
        self.world.bodies.append(body)

    def read_collision(self, collision: etree._Element, file: Path, link: str, pose: np.ndarray) -> Shape:
        name = f"{link}::{collision.get('name', 'collision')}"
        self.note_unknown(collision, {"geometry", "pose", "surface"}, file)
        geometry = collision.find("geometry")
        if geometry is None or len(geometry) == 0:
            raise self.fail(collision, f"collision '{name}' needs a <geometry>", file)
        g = geometry[0]
        surface = self.read_surface(collision, file, name)
        if g.tag == "box":
            size = tuple(self.floats(self.child(g, "size", file), 3, file))
        elif g.tag in ("cylinder", "capsule"):
            size = (self.number(g, "radius", None, file), self.number(g, "length", None, file))
        elif g.tag == "sphere":
            size = (self.number(g, "radius", None, file),)
        elif g.tag == "ellipsoid":
            size = tuple(self.floats(self.child(g, "radii", file), 3, file))
        elif g.tag == "plane":
            normal_el = g.find("normal")
            normal = np.array(self.floats(normal_el, 3, file) if normal_el is not None else [0.0, 0.0, 1.0])
            size_el = g.find("size")
            size = tuple(self.floats(size_el, 2, file)) if size_el is not None else (100.0, 100.0)
            if not np.linalg.norm(normal) > 0.0:
                raise self.fail(normal_el if normal_el is not None else g, "<plane><normal> must not be 0 0 0", file)
            turn = np.eye(4)
            turn[:3, :3] = z_onto(normal)
            pose = pose @ turn
        elif g.tag == "mesh":
            uri = self.child(g, "uri", file)
            scale_el = g.find("scale")
            scale = self.floats(scale_el, 3, file) if scale_el is not None else [1.0, 1.0, 1.0]
            return Shape(name, "mesh", (), pose, self.mesh_path((uri.text or "").strip(), uri, file),
                         (scale[0], scale[1], scale[2]), surface)
        else:
            raise self.fail(g, f"collision '{name}': geometry <{g.tag}> is not supported "
                               f"(supported: {', '.join(sorted(SHAPES))})", file)
        if any(v <= 0 for v in size):
            raise self.fail(g, f"collision '{name}': <{g.tag}> sizes must be positive, not {size}", file)
        return Shape(name, g.tag, tuple(float(v) for v in size), pose, surface=surface)

    def read_surface(self, collision: etree._Element, file: Path, name: str) -> Surface:
        """A collision's ``<surface>`` friction; contact settings pppbot does not simulate, set away
        from SDF's defaults, are named once.

        Raises:
            WorldError: a coefficient that is not a number or is negative.
        """
        surface = collision.find("surface")
        if surface is None:
            return Surface()
        values = []
        for tag in ("mu", "mu2"):
            element = surface.find(f"friction/ode/{tag}")
            value = DEFAULT_MU if element is None else self.floats(element, 1, file)[0]
            if value < 0:
                raise self.fail(element, f"collision '{name}': <{tag}> {value} must not be negative", file)
            values.append(value)
        for path, default in UNSIMULATED_DEFAULTS.items():
            element = surface.find(path)
            if element is not None and (element.text or "").strip():
                value = self.floats(element, 1, file)[0]
                if value != default and path not in self.named_surfaces:
                    self.named_surfaces.add(path)
                    self.warn(element, f"<surface><{path.replace('/', '><')}> {value:g} of collision '{name}' is not "
                                       f"simulated (SDF's default {default:g} is; MuJoCo's contacts have no such "
                                       "setting)", file)
        return Surface(values[0], values[1])

    def child(self, parent: etree._Element, tag: str, file: Path) -> etree._Element:
        element = parent.find(tag)
        if element is None:
            raise self.fail(parent, f"<{parent.tag}> needs <{tag}>", file)
        return element


def read_sdf_world(path: str | Path, model_paths: Iterable[Path] = ()) -> World:
    """Read an SDF world file.

    Args:
        path: the ``.sdf``/``.world`` file.
        model_paths: directories with models, searched before the environment's
            resource paths (pppbot passes ``worlds/models``).

    Raises:
        WorldError: unreadable or malformed file, unknown model, missing mesh,
            unsupported geometry; the message names the file, line and element.
    """
    source = Path(path)
    if not source.is_file():
        raise WorldError(f"{source}: world file not found")
    try:
        root = parse_xml(source)
    except XmlFileError as exc:
        raise WorldError(str(exc)) from exc
    search = resource_paths([*model_paths, source.parent / "models"])
    return _Reader(source, search).read_world(root)
