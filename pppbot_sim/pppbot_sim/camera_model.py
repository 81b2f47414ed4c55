"""The robot's camera tags put into the MuJoCo model: a site at each sensor's pose and a MuJoCo
camera looking along the sensor's +x with +z up (MuJoCo's cameras look along their -z with +y
up), with the tag's field of view."""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
from transforms3d.quaternions import mat2quat, quat2mat

from pppbot_description.urdf_model import JointType, RobotModel, Sensor
from pppbot_sim.camera_worker import CameraBinding
from pppbot_sim.cameras import CAMERA_TYPES, CameraSpec, scoped_sensor_name
from pppbot_sim.errors import SpawnError
from pppbot_sim.mj_build import rpy_quat_wxyz
from pppbot_sim.render import CameraView
from pppbot_sim.sensors import tag_pose

#: MuJoCo's camera axes (x right, y up, z backward) in a Gazebo sensor's frame (x forward, z up).
CAMERA_IN_SENSOR = np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


@dataclass(frozen=True)
class PlacedCamera:
    spec: CameraSpec
    site: str
    camera: str


def lumped_link(robot: RobotModel, link: str) -> str:
    """The link Gazebo puts a sensor on once fixed joints are merged (ppp_bot's camera_link → base_link)."""
    parents = {j.child: j for j in robot.joints.values()}
    while link in parents and parents[link].type is JointType.FIXED:
        link = parents[link].parent
    return link


def camera_tags(tags: Sequence[Sensor]) -> tuple[list[Sensor], list[Sensor]]:
    """(camera tags, the others)."""
    return [t for t in tags if t.type in CAMERA_TYPES], [t for t in tags if t.type not in CAMERA_TYPES]


def add_cameras(spec: mujoco.MjSpec, robot: RobotModel, tags: Sequence[Sensor], name: str,
                world_name: str) -> tuple[list[PlacedCamera], list[str]]:
    """A site and a MuJoCo camera for each camera tag of robot ``name``; what is not simulated.

    Raises:
        SpawnError: a bad tag, or one on a link the robot does not have.
    """
    placed, notes = [], []
    for tag in tags:
        body = spec.body(f"{name}/{tag.link}")
        if body is None:
            raise SpawnError(f"sensor '{tag.name}' is on link '{tag.link}', which the robot does not have")
        pose = tag_pose(tag)
        camera, tag_notes = CameraSpec.from_tag(
            tag, robot_links=set(robot.links), pose=pose,
            default_topic_prefix=scoped_sensor_name(world_name, name, lumped_link(robot, tag.link), tag.name))
        notes += tag_notes
        x, y, z, roll, pitch, yaw = pose
        quat = rpy_quat_wxyz(roll, pitch, yaw)
        site = f"{name}/sensor/{tag.name}"
        body.add_site(name=site, pos=[x, y, z], quat=quat)
        view_quat = mat2quat(quat2mat(quat) @ CAMERA_IN_SENSOR)
        body.add_camera(name=f"{name}/camera/{tag.name}", pos=[x, y, z], quat=[float(q) for q in view_quat],
                        fovy=camera.fovy_deg)
        placed.append(PlacedCamera(camera, site, f"{name}/camera/{tag.name}"))
    return placed, notes


def bind_cameras(model: mujoco.MjModel, placed: Sequence[PlacedCamera], link_sites: dict[str, str]) -> list[
        CameraBinding]:
    """The cameras as the compiled ``model`` has them; ``link_sites``: the robot's link → site."""
    bindings = []
    for p in placed:
        s = p.spec
        frame_site = link_sites.get(s.frame_id)
        view = CameraView(model.camera(p.camera).id, s.width, s.height, s.render_near_m, s.far_m)
        bindings.append(CameraBinding(s, view, model.site(p.site).id,
                                      model.site(frame_site).id if frame_site is not None else -1))
    return bindings
