"""A world's lights and ambient light (``<light>``, ``<scene><ambient>``), for the cameras.

Lights carry no physics; they only light what cameras render. Directional, point and spot
lights become MuJoCo lights (without shadows: cameras render none); the scene's ambient
light (SDF's default 0.4) becomes the ambient part of MuJoCo's headlight, whose directional
part is then off (Gazebo has no light at the camera). A world without lights keeps MuJoCo's
headlight, so its images are not flat.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import mujoco
import numpy as np
from lxml import etree

#: OpenGL's fixed pipeline, which MuJoCo renders with, lights at most this many.
MAX_LIGHTS = 8
_TYPES = {"directional": mujoco.mjtLightType.mjLIGHT_DIRECTIONAL, "point": mujoco.mjtLightType.mjLIGHT_POINT,
          "spot": mujoco.mjtLightType.mjLIGHT_SPOT}


@dataclass(frozen=True)
class Light:
    name: str
    kind: str  # directional, point or spot
    position: tuple[float, float, float]
    direction: tuple[float, float, float]  # in the world
    diffuse: tuple[float, float, float]
    specular: tuple[float, float, float]
    attenuation: tuple[float, float, float]  # constant, linear, quadratic
    cutoff_rad: float = 0.0  # spot: the outer angle


@dataclass(frozen=True)
class Lighting:
    ambient: tuple[float, float, float] = (0.4, 0.4, 0.4)
    lights: tuple[Light, ...] = field(default_factory=tuple)


def read_lighting(world: etree._Element, pose_of: Callable[[etree._Element], np.ndarray],
                  floats: Callable[[etree._Element, int | tuple[int, ...]], list[float]]) -> Lighting:
    """The ``<world>``'s lights and ambient light; ``pose_of`` reads an element's ``<pose>`` (4 x 4),
    ``floats`` an element's numbers (raising the world's error on bad ones)."""
    def values(parent: etree._Element, tag: str, default: tuple[float, ...]) -> tuple[float, ...]:
        element = parent.find(tag)
        return default if element is None else tuple(floats(element, len(default)))

    def colour(parent: etree._Element, tag: str, default: tuple[float, float, float]) -> tuple[float, float, float]:
        element = parent.find(tag)
        if element is None:
            return default
        v = floats(element, (3, 4))
        return (v[0], v[1], v[2])

    scene = world.find("scene")
    ambient = colour(scene, "ambient", (0.4, 0.4, 0.4)) if scene is not None else (0.4, 0.4, 0.4)
    lights = []
    for element in world.findall("light"):
        kind = element.get("type", "point")
        if kind not in _TYPES:
            continue
        pose = pose_of(element)
        direction = pose[:3, :3] @ np.asarray(values(element, "direction", (0.0, 0.0, -1.0)))
        att = element.find("attenuation")
        attenuation = (1.0, 0.0, 0.0) if att is None or kind == "directional" else (
            values(att, "constant", (1.0,))[0], values(att, "linear", (1.0,))[0], values(att, "quadratic", (0.0,))[0])
        spot = element.find("spot")
        cutoff = values(spot, "outer_angle", (0.0,))[0] if spot is not None else 0.0
        x, y, z = pose[:3, 3]
        dx, dy, dz = direction
        lights.append(Light(element.get("name", ""), kind, (float(x), float(y), float(z)),
                            (float(dx), float(dy), float(dz)), colour(element, "diffuse", (1.0, 1.0, 1.0)),
                            colour(element, "specular", (0.1, 0.1, 0.1)), attenuation, cutoff))
    return Lighting(ambient, tuple(lights))


def add_lighting(spec: mujoco.MjSpec, lighting: Lighting) -> None:
    """``lighting``'s lights (the first :data:`MAX_LIGHTS`) and ambient light into ``spec``."""
    if not lighting.lights:
        return
    headlight = spec.visual.headlight
    headlight.ambient = list(lighting.ambient)
    headlight.diffuse = [0.0, 0.0, 0.0]
    headlight.specular = [0.0, 0.0, 0.0]
    for light in lighting.lights[:MAX_LIGHTS]:
        added = spec.worldbody.add_light(name=f"light/{light.name}" if light.name else "", pos=list(light.position),
                                         dir=list(light.direction), diffuse=list(light.diffuse),
                                         specular=list(light.specular), attenuation=list(light.attenuation),
                                         castshadow=False)
        added.type = _TYPES[light.kind]
        if light.kind == "spot" and light.cutoff_rad > 0:
            added.cutoff = float(np.degrees(light.cutoff_rad))  # MuJoCo's cutoff is in degrees, always
