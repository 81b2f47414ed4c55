"""A URDF as plain data: links, joints, and the Gazebo and ros2_control extensions.

One parser serves the state publisher (kinematics) and the simulator (geometry,
inertia, sensors, wheel limits). Standard URDF elements follow the URDF spec;
``<gazebo reference="link"><sensor>`` and ``<ros2_control>`` follow Gazebo's and
ros2_control's layouts, so the same file runs in Gazebo.
"""
from __future__ import annotations

import enum
import math
from collections.abc import Iterator
from dataclasses import dataclass, field

from lxml import etree

from pppbot_common.xml_files import XmlFileError, parse_xml
from pppbot_description.errors import DescriptionError

Vector3 = tuple[float, float, float]


class JointType(enum.Enum):
    FIXED = "fixed"
    CONTINUOUS = "continuous"
    REVOLUTE = "revolute"
    PRISMATIC = "prismatic"
    FLOATING = "floating"
    PLANAR = "planar"

    @property
    def moves(self) -> bool:
        """Whether a single joint position drives it (what the state publisher handles)."""
        return self in (JointType.CONTINUOUS, JointType.REVOLUTE, JointType.PRISMATIC)


@dataclass(frozen=True)
class Origin:
    """``<origin xyz rpy>``: translation in m, roll-pitch-yaw about fixed axes in rad."""

    xyz: Vector3 = (0.0, 0.0, 0.0)
    rpy: Vector3 = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Geometry:
    """``box`` (size x y z), ``cylinder`` (radius, length), ``sphere`` (radius) or ``mesh``."""

    kind: str
    size: tuple[float, ...] = ()
    filename: str = ""
    scale: Vector3 = (1.0, 1.0, 1.0)


@dataclass(frozen=True)
class Shape:
    origin: Origin
    geometry: Geometry
    rgba: tuple[float, float, float, float] | None = None


@dataclass(frozen=True)
class Inertial:
    mass: float
    origin: Origin
    #: ixx, ixy, ixz, iyy, iyz, izz in kg·m²
    inertia: tuple[float, float, float, float, float, float]

    def matrix(self) -> tuple[Vector3, Vector3, Vector3]:
        ixx, ixy, ixz, iyy, iyz, izz = self.inertia
        return ((ixx, ixy, ixz), (ixy, iyy, iyz), (ixz, iyz, izz))


@dataclass(frozen=True)
class Link:
    name: str
    inertial: Inertial | None = None
    visuals: tuple[Shape, ...] = ()
    collisions: tuple[Shape, ...] = ()


@dataclass(frozen=True)
class Mimic:
    joint: str
    multiplier: float = 1.0
    offset: float = 0.0


@dataclass(frozen=True)
class Joint:
    name: str
    type: JointType
    parent: str
    child: str
    origin: Origin = Origin()
    axis: Vector3 = (1.0, 0.0, 0.0)
    lower: float = -math.inf
    upper: float = math.inf
    velocity_limit: float = math.inf
    effort_limit: float = math.inf
    mimic: Mimic | None = None


@dataclass(frozen=True)
class Sensor:
    """A ``<gazebo reference="link"><sensor>`` tag; ``find_*`` read its sub-elements."""

    name: str
    type: str
    link: str
    element: etree._Element = field(compare=False, repr=False)

    def find_text(self, path: str, default: str | None = None) -> str | None:
        found = self.element.find(path)
        if found is None or found.text is None:
            return default
        return found.text.strip()

    def find_float(self, path: str, default: float) -> float:
        """The number at ``path`` (e.g. ``lidar/scan/horizontal/samples``), or ``default``.

        Raises:
            DescriptionError: the element exists but is not a number.
        """
        text = self.find_text(path)
        if text is None:
            return default
        try:
            return float(text)
        except ValueError:
            element = self.element.find(path)
            line = element.sourceline if element is not None else "?"
            raise DescriptionError(
                f"line {line}: <{path}> of sensor '{self.name}' must be a number, not '{text}'"
            ) from None

    @property
    def update_rate_hz(self) -> float:
        return self.find_float("update_rate", 0.0)

    @property
    def topic(self) -> str:
        return self.find_text("topic", self.name) or self.name

    @property
    def frame_id(self) -> str:
        return self.find_text("gz_frame_id") or self.find_text("frame_id") or self.link


@dataclass(frozen=True)
class ControlJoint:
    """A joint of a ``<ros2_control>`` block: command interfaces with limits, state interfaces."""

    name: str
    command_interfaces: dict[str, tuple[float, float]]
    state_interfaces: tuple[str, ...]


@dataclass(frozen=True)
class GazeboPlugin:
    """A robot-wide ``<gazebo><plugin filename="..." name="...">`` tag and its settings
    (each child element's text, by tag: gz_ros2_control's ``<parameters>``, DiffDrive's
    ``<wheel_separation>``, ...)."""

    filename: str
    name: str
    settings: dict[str, str] = field(default_factory=dict)
    #: the element itself (repeated tags such as DiffDrive's ``<left_joint>``), and the file it is in
    element: etree._Element | None = field(default=None, compare=False, repr=False)
    source: str = ""

    def where(self, element: etree._Element | None = None) -> str:
        """``source:line`` of ``element`` (default: the plugin element), for messages."""
        shown = element if element is not None else self.element
        return f"{self.source}:{shown.sourceline}" if shown is not None else self.source


@dataclass(frozen=True)
class RobotModel:
    name: str
    links: dict[str, Link]
    joints: dict[str, Joint]
    sensors: tuple[Sensor, ...] = ()
    control_joints: dict[str, ControlJoint] = field(default_factory=dict)
    #: ``<gazebo reference="link">`` scalar settings such as mu1, mu2, material
    gazebo_settings: dict[str, dict[str, str]] = field(default_factory=dict)
    #: ``<gazebo><plugin>`` tags without a reference (system plugins of the model)
    plugins: tuple[GazeboPlugin, ...] = ()

    @property
    def root(self) -> str:
        children = {j.child for j in self.joints.values()}
        (root,) = [name for name in self.links if name not in children]
        return root

    def children_of(self, link: str) -> list[Joint]:
        return [j for j in self.joints.values() if j.parent == link]

    def walk(self) -> Iterator[Joint]:
        """Joints in depth-first order from the root."""
        stack = list(reversed(self.children_of(self.root)))
        while stack:
            joint = stack.pop()
            yield joint
            stack.extend(reversed(self.children_of(joint.child)))

    def sensors_of_type(self, *types: str) -> list[Sensor]:
        return [s for s in self.sensors if s.type in types]


# ---------------------------------------------------------------------- parsing
def _fail(element: etree._Element | None, message: str, source: str) -> DescriptionError:
    line = f":{element.sourceline}" if element is not None and element.sourceline else ""
    return DescriptionError(f"{source}{line}: {message}")


def _floats(element: etree._Element, attribute: str, count: int, default: tuple[float, ...] | None,
            source: str) -> tuple[float, ...]:
    text = element.get(attribute)
    if text is None:
        if default is None:
            raise _fail(element, f"<{element.tag}> needs attribute '{attribute}'", source)
        return default
    try:
        values = tuple(float(v) for v in text.split())
    except ValueError:
        raise _fail(element, f"<{element.tag} {attribute}='{text}'>: not numbers", source) from None
    if len(values) != count or not all(math.isfinite(v) for v in values):
        raise _fail(element, f"<{element.tag} {attribute}='{text}'>: expected {count} finite number(s)", source)
    return values


def _origin(parent: etree._Element, source: str) -> Origin:
    element = parent.find("origin")
    if element is None:
        return Origin()
    xyz = _floats(element, "xyz", 3, (0.0, 0.0, 0.0), source)
    rpy = _floats(element, "rpy", 3, (0.0, 0.0, 0.0), source)
    return Origin(xyz=(xyz[0], xyz[1], xyz[2]), rpy=(rpy[0], rpy[1], rpy[2]))


def _geometry(shape: etree._Element, source: str) -> Geometry:
    holder = shape.find("geometry")
    if holder is None or len(holder) == 0:
        raise _fail(shape, f"<{shape.tag}> needs a <geometry> with a shape", source)
    g = holder[0]
    if g.tag == "box":
        return Geometry("box", _floats(g, "size", 3, None, source))
    if g.tag == "cylinder":
        return Geometry("cylinder", _floats(g, "radius", 1, None, source) + _floats(g, "length", 1, None, source))
    if g.tag == "sphere":
        return Geometry("sphere", _floats(g, "radius", 1, None, source))
    if g.tag == "mesh":
        filename = g.get("filename")
        if not filename:
            raise _fail(g, "<mesh> needs a filename", source)
        s = _floats(g, "scale", 3, (1.0, 1.0, 1.0), source)
        return Geometry("mesh", filename=filename, scale=(s[0], s[1], s[2]))
    raise _fail(g, f"unknown geometry <{g.tag}> (allowed: box, cylinder, sphere, mesh)", source)


def _shapes(link: etree._Element, tag: str, colours: dict[str, tuple[float, ...]], source: str) -> tuple[Shape, ...]:
    shapes = []
    for element in link.findall(tag):
        rgba = None
        material = element.find("material")
        if material is not None:
            colour = material.find("color")
            if colour is not None:
                rgba = _floats(colour, "rgba", 4, None, source)
            elif material.get("name") in colours:
                rgba = colours[material.get("name", "")]
        shapes.append(Shape(_origin(element, source), _geometry(element, source),
                            None if rgba is None else (rgba[0], rgba[1], rgba[2], rgba[3])))
    return tuple(shapes)


def _inertial(link: etree._Element, source: str) -> Inertial | None:
    element = link.find("inertial")
    if element is None:
        return None
    mass_el, inertia_el = element.find("mass"), element.find("inertia")
    if mass_el is None or inertia_el is None:
        raise _fail(element, f"<inertial> of link '{link.get('name')}' needs <mass> and <inertia>", source)
    (mass,) = _floats(mass_el, "value", 1, None, source)
    values = tuple(_floats(inertia_el, k, 1, None, source)[0] for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"))
    return Inertial(mass, _origin(element, source),
                    (values[0], values[1], values[2], values[3], values[4], values[5]))


def _joint(element: etree._Element, source: str) -> Joint:
    name = element.get("name")
    kind = element.get("type")
    if not name:
        raise _fail(element, "<joint> needs a name", source)
    try:
        joint_type = JointType(kind)
    except ValueError:
        allowed = ", ".join(t.value for t in JointType)
        raise _fail(element, f"joint '{name}' has type '{kind}' (allowed: {allowed})", source) from None
    parent, child = element.find("parent"), element.find("child")
    if parent is None or child is None or not parent.get("link") or not child.get("link"):
        raise _fail(element, f"joint '{name}' needs <parent link> and <child link>", source)
    axis_el = element.find("axis")
    axis = (1.0, 0.0, 0.0) if axis_el is None else _floats(axis_el, "xyz", 3, None, source)
    norm = math.sqrt(sum(a * a for a in axis))
    if joint_type.moves and norm < 1e-9:
        raise _fail(axis_el, f"joint '{name}' has a zero axis", source)
    axis = tuple(a / norm for a in axis) if norm > 0 else axis
    limit = element.find("limit")
    lower, upper = -math.inf, math.inf
    velocity = effort = math.inf
    if limit is not None:
        velocity = _floats(limit, "velocity", 1, (math.inf,), source)[0]
        effort = _floats(limit, "effort", 1, (math.inf,), source)[0]
        if joint_type in (JointType.REVOLUTE, JointType.PRISMATIC):
            lower = _floats(limit, "lower", 1, (0.0,), source)[0]
            upper = _floats(limit, "upper", 1, (0.0,), source)[0]
            if lower > upper:
                raise _fail(limit, f"joint '{name}': lower limit {lower} > upper {upper}", source)
    mimic_el = element.find("mimic")
    mimic = None
    if mimic_el is not None:
        if not mimic_el.get("joint"):
            raise _fail(mimic_el, f"<mimic> of joint '{name}' needs a joint", source)
        mimic = Mimic(mimic_el.get("joint", ""), _floats(mimic_el, "multiplier", 1, (1.0,), source)[0],
                      _floats(mimic_el, "offset", 1, (0.0,), source)[0])
    return Joint(
        name=name, type=joint_type, parent=parent.get("link", ""), child=child.get("link", ""),
        origin=_origin(element, source), axis=(axis[0], axis[1], axis[2]),
        lower=lower, upper=upper, velocity_limit=velocity, effort_limit=effort,
        mimic=mimic,
    )


def _control_joints(robot: etree._Element, source: str) -> dict[str, ControlJoint]:
    joints: dict[str, ControlJoint] = {}
    for block in robot.findall("ros2_control"):
        for element in block.findall("joint"):
            name = element.get("name", "")
            commands = {}
            for ci in element.findall("command_interface"):
                params = {p.get("name"): (p.text or "").strip() for p in ci.findall("param")}
                try:
                    low = float(params.get("min", "-inf"))
                    high = float(params.get("max", "inf"))
                except ValueError:
                    raise _fail(ci, f"ros2_control joint '{name}': min/max must be numbers", source) from None
                if low > high:
                    raise _fail(ci, f"ros2_control joint '{name}': min {low} > max {high}", source)
                commands[ci.get("name", "")] = (low, high)
            states = tuple(si.get("name", "") for si in element.findall("state_interface"))
            joints[name] = ControlJoint(name, commands, states)
    return joints


def parse_urdf(text: str, source: str = "<robot_description>") -> RobotModel:  # noqa: C901, PLR0912 (one check a field)
    """Parse URDF XML text into a :class:`RobotModel`.

    Raises:
        DescriptionError: malformed XML, a missing or bad attribute, an unknown link,
            or links that do not form one tree; the message names ``source``, line
            and element.
    """
    try:
        root = parse_xml(text, source)
    except XmlFileError as exc:
        raise DescriptionError(str(exc)) from exc
    if root.tag != "robot":
        raise _fail(root, f"the root element is <{root.tag}>, not <robot>", source)
    colours = {}
    for material in root.findall("material"):
        colour = material.find("color")
        if colour is not None and material.get("name"):
            colours[material.get("name", "")] = _floats(colour, "rgba", 4, None, source)
    links: dict[str, Link] = {}
    for element in root.findall("link"):
        name = element.get("name")
        if not name:
            raise _fail(element, "<link> needs a name", source)
        if name in links:
            raise _fail(element, f"link '{name}' is defined twice", source)
        links[name] = Link(name, _inertial(element, source), _shapes(element, "visual", colours, source),
                           _shapes(element, "collision", colours, source))
    joints: dict[str, Joint] = {}
    for element in root.findall("joint"):
        joint = _joint(element, source)
        if joint.name in joints:
            raise _fail(element, f"joint '{joint.name}' is defined twice", source)
        for end in (joint.parent, joint.child):
            if end not in links:
                raise _fail(element, f"joint '{joint.name}' refers to unknown link '{end}'", source)
        joints[joint.name] = joint
    _check_tree(links, joints, source)
    for joint in joints.values():
        if joint.mimic is not None and joint.mimic.joint not in joints:
            raise DescriptionError(f"{source}: joint '{joint.name}' mimics unknown joint '{joint.mimic.joint}'")
    sensors = []
    settings: dict[str, dict[str, str]] = {}
    plugins = []
    for gazebo in root.findall("gazebo"):
        reference = gazebo.get("reference")
        if reference is None:
            for plugin in gazebo.findall("plugin"):
                plugins.append(GazeboPlugin(plugin.get("filename", ""), plugin.get("name", ""),
                                            {child.tag: (child.text or "").strip() for child in plugin
                                             if isinstance(child.tag, str)}, plugin, source))
            continue
        if reference not in links:
            raise _fail(gazebo, f"<gazebo reference='{reference}'> names no link", source)
        for child in gazebo:
            if child.tag == "sensor":
                sensors.append(Sensor(child.get("name", ""), child.get("type", ""), reference, child))
            elif isinstance(child.tag, str):
                value = child.get("value") if child.get("value") is not None else (child.text or "").strip()
                settings.setdefault(reference, {})[child.tag] = value
    return RobotModel(root.get("name", ""), links, joints, tuple(sensors), _control_joints(root, source), settings,
                      tuple(plugins))


def _check_tree(links: dict[str, Link], joints: dict[str, Joint], source: str) -> None:
    parents: dict[str, str] = {}
    for joint in joints.values():
        if joint.child in parents:
            raise DescriptionError(f"{source}: link '{joint.child}' has two parent joints "
                                   f"('{parents[joint.child]}' and '{joint.name}')")
        parents[joint.child] = joint.name
    roots = [name for name in links if name not in parents]
    if len(roots) != 1:
        raise DescriptionError(
            f"{source}: links must form one tree with one root; roots found: {', '.join(roots) or 'none (a cycle)'}"
        )
    by_child = {j.child: j.parent for j in joints.values()}
    for link in links:
        name, seen = link, {link}
        while name in by_child:
            name = by_child[name]
            if name in seen:
                raise DescriptionError(f"{source}: joints form a cycle through link '{name}'")
            seen.add(name)
