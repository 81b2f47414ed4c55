"""Model joints as Gazebo reads them: each type becomes its MuJoCo joint where the SDF puts it, a
door swings when the robot pushes it and stays put when its model is static. Positions worked out
by hand from the SDF specification (sdformat.org: "Pose frame semantics", the joint element)."""
from __future__ import annotations

import textwrap
from pathlib import Path

import mujoco
import numpy as np
import pytest

from pppbot_common.maps import OCCUPIED
from pppbot_description.urdf_model import parse_urdf
from pppbot_description.xacro_model import process_xacro
from pppbot_sim.errors import WorldError
from pppbot_sim.ground_truth import Bounds, ground_truth_map
from pppbot_sim.mj_build import SpawnPose, world_spec
from pppbot_sim.sdf_joints import JointKind
from pppbot_sim.sdf_world import read_sdf_world
from pppbot_sim.simulation import Simulation, load_world
from pppbot_sim.worlds import model_paths

CORPUS = Path(__file__).parent / "data" / "corpus"
BUILT = CORPUS / "gazebo_built.sdf"
ROBOT = parse_urdf(process_xacro())
BOX = "<collision name='c'><geometry><box><size>0.1 0.1 0.1</size></box></geometry></collision>"
HALF_PI = "1.5707963267948966"


def world_file(tmp_path: Path, body: str) -> Path:
    path = tmp_path / "joints.sdf"
    path.write_text('<?xml version="1.0"?>\n<sdf version="1.9"><world name="w">\n' + textwrap.dedent(body)
                    + "\n</world></sdf>\n")
    return path


def compiled(path: Path) -> tuple[mujoco.MjModel, mujoco.MjData]:
    model = world_spec(read_sdf_world(path)).compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return model, data


def joint_in_world(model: mujoco.MjModel, data: mujoco.MjData, name: str) -> tuple[np.ndarray, np.ndarray]:
    joint = model.joint(name).id
    return data.xanchor[joint].copy(), data.xaxis[joint].copy()


def test_each_joint_type_becomes_its_mujoco_joint(tmp_path: Path) -> None:
    path = world_file(tmp_path, f"""\
        <model name="m"><link name="base">{BOX}</link>
          <link name="a"><pose>1 0 0 0 0 0</pose>{BOX}</link><link name="b"><pose>2 0 0 0 0 0</pose>{BOX}</link>
          <link name="c"><pose>3 0 0 0 0 0</pose>{BOX}</link><link name="d"><pose>4 0 0 0 0 0</pose>{BOX}</link>
          <link name="e"><pose>5 0 0 0 0 0</pose>{BOX}</link><link name="f"><pose>6 0 0 0 0 0</pose>{BOX}</link>
          <joint name="rev" type="revolute"><parent>base</parent><child>a</child>
            <axis><xyz>0 0 1</xyz><limit><lower>-0.5</lower><upper>0.25</upper><effort>3</effort></limit>
              <dynamics><damping>0.7</damping><friction>0.2</friction></dynamics></axis></joint>
          <joint name="cont" type="continuous"><parent>a</parent><child>b</child><axis><xyz>1 0 0</xyz></axis></joint>
          <joint name="slide" type="prismatic"><parent>b</parent><child>c</child>
            <axis><xyz>0 1 0</xyz><limit><lower>0</lower><upper>0.3</upper></limit></axis></joint>
          <joint name="weld" type="fixed"><parent>c</parent><child>d</child></joint>
          <joint name="ball" type="ball"><parent>d</parent><child>e</child></joint>
          <joint name="cross" type="universal"><parent>e</parent><child>f</child>
            <axis><xyz>1 0 0</xyz></axis><axis2><xyz>0 1 0</xyz></axis2></joint>
        </model>""")
    model, _ = compiled(path)
    kinds = {model.joint(j).name: int(model.jnt_type[j]) for j in range(model.njnt)}
    T = mujoco.mjtJoint
    assert kinds == {"m::base::free": T.mjJNT_FREE, "m::rev": T.mjJNT_HINGE, "m::cont": T.mjJNT_HINGE,
                     "m::slide": T.mjJNT_SLIDE, "m::ball": T.mjJNT_BALL, "m::cross": T.mjJNT_HINGE,
                     "m::cross::axis2": T.mjJNT_HINGE}
    rev = model.joint("m::rev")
    assert bool(rev.limited[0]) and list(rev.range) == pytest.approx([-0.5, 0.25])
    assert (rev.damping[0], rev.frictionloss[0]) == pytest.approx((0.7, 0.2))
    assert not bool(model.joint("m::cont").limited[0])
    assert list(model.joint("m::slide").range) == pytest.approx([0.0, 0.3])
    # the fixed joint welds d into c: one body each, d nested in c with no joint of its own
    assert model.body_parentid[model.body("m::d").id] == model.body("m::c").id
    assert model.body_jntnum[model.body("m::d").id] == 0
    # the chain hangs from base, the only free body
    assert model.body_parentid[model.body("m::a").id] == model.body("m::base").id


def test_joint_frame_and_axis_follow_the_frame_rules(tmp_path: Path) -> None:
    """Model at (10, 0, 0) turned 90° about z. Link L at model (1, 0, 0) → world (10, 1, 0).
    - J1: pose (0, 0.5, 0) in L's frame (the default) → world (9.5, 1, 0); xyz 1 0 0 in the joint frame
      (turned like the model) → world +y.
    - J2: pose relative_to __model__ (0, 0, 1) → world (10, 0, 1); xyz 1 0 0 expressed_in __model__ → +y.
    - J3: SDF 1.6's use_parent_model_frame: xyz 0 1 0 in the model frame → world -x; L2 turned 90° about x
      so the joint frame's own axes differ from the model's.
    """
    path = world_file(tmp_path, f"""\
        <model name="m"><pose>10 0 0 0 0 {HALF_PI}</pose>
          <link name="base">{BOX}</link>
          <link name="L"><pose>1 0 0 0 0 0</pose>{BOX}</link>
          <link name="L2"><pose>2 0 0 {HALF_PI} 0 0</pose>{BOX}</link>
          <link name="L3"><pose>3 0 0 0 0 0</pose>{BOX}</link>
          <joint name="J1" type="revolute"><parent>base</parent><child>L</child><pose>0 0.5 0 0 0 0</pose>
            <axis><xyz>1 0 0</xyz></axis></joint>
          <joint name="J3" type="revolute"><parent>base</parent><child>L2</child>
            <axis><xyz>0 1 0</xyz><use_parent_model_frame>true</use_parent_model_frame></axis></joint>
          <joint name="J2" type="revolute"><parent>base</parent><child>L3</child>
            <pose relative_to="__model__">0 0 1 0 0 0</pose>
            <axis><xyz expressed_in="__model__">1 0 0</xyz></axis></joint>
        </model>""")
    model, data = compiled(path)
    anchor, axis = joint_in_world(model, data, "m::J1")
    np.testing.assert_allclose(anchor, [9.5, 1.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(axis, [0.0, 1.0, 0.0], atol=1e-9)
    anchor, axis = joint_in_world(model, data, "m::J2")
    np.testing.assert_allclose(anchor, [10.0, 0.0, 1.0], atol=1e-9)
    np.testing.assert_allclose(axis, [0.0, 1.0, 0.0], atol=1e-9)
    _, axis = joint_in_world(model, data, "m::J3")
    np.testing.assert_allclose(axis, [-1.0, 0.0, 0.0], atol=1e-9)
    # in L2's own frame (turned about x) the same axis is not the written 0 1 0
    np.testing.assert_allclose(model.jnt_axis[model.joint("m::J3").id], [0.0, 0.0, -1.0], atol=1e-9)


def test_nested_model_links_and_world_parent(tmp_path: Path) -> None:
    path = world_file(tmp_path, f"""\
        <model name="outer"><pose>0 0 1 0 0 0</pose>
          <link name="arm">{BOX}</link>
          <model name="inner"><pose>1 0 0 0 0 0</pose><link name="tip">{BOX}</link></model>
          <joint name="to_world" type="revolute"><parent>world</parent><child>arm</child>
            <axis><xyz>0 0 1</xyz></axis></joint>
          <joint name="to_tip" type="prismatic"><parent>arm</parent><child>inner::tip</child>
            <axis><xyz>1 0 0</xyz></axis></joint>
        </model>""")
    world = read_sdf_world(path)
    joints = {j.name: j for j in world.joints}
    assert (joints["outer::to_world"].parent, joints["outer::to_tip"].child) == ("world", "outer::inner::tip")
    model, data = compiled(path)
    np.testing.assert_allclose(joint_in_world(model, data, "outer::to_tip")[0], [1.0, 0.0, 1.0], atol=1e-9)
    # nothing is free: the arm hangs from the world, the tip from the arm
    assert model.nq == 2 and model.body_parentid[model.body("outer::arm").id] == 0


@pytest.mark.parametrize(("body", "message"), [
    (f"<model name='m'><link name='a'>{BOX}</link><joint name='j' type='hinge'><parent>world</parent>"
     "<child>a</child></joint></model>", r"joints\.sdf:\d+: joint 'j' has type 'hinge' \(SDF's types: "),
    (f"<model name='m'><link name='a'>{BOX}</link><joint name='j' type='revolute'><parent>world</parent>"
     "<child>door</child></joint></model>", r"joint 'j' of model 'm': no link 'door' \(links: a, or world\)"),
    (f"<model name='m'><link name='a'>{BOX}</link><joint name='j' type='revolute'><parent>world</parent>"
     "<child>a</child><axis><xyz>0 0 0</xyz></axis></joint></model>", r"joint 'm::j': <axis><xyz> must not be 0 0 0"),
    (f"<model name='m'><link name='a'>{BOX}</link><joint name='j' type='revolute'><parent>world</parent>"
     "<child>a</child><axis><limit><lower>1</lower><upper>0</upper></limit></axis></joint></model>",
     r"<limit> lower 1.0 is above upper 0.0"),
])
def test_bad_joints_are_named_by_file_and_line(tmp_path: Path, body: str, message: str) -> None:
    with pytest.raises(WorldError, match=message):
        read_sdf_world(world_file(tmp_path, body))


def test_unsimulated_joints_and_loops_are_named_once(tmp_path: Path) -> None:
    world = read_sdf_world(world_file(tmp_path, f"""\
        <model name="m"><link name="a">{BOX}</link><link name="b">{BOX}</link><link name="c">{BOX}</link>
          <joint name="screw" type="screw"><parent>a</parent><child>b</child></joint>
          <joint name="j1" type="revolute"><parent>b</parent><child>c</child></joint>
          <joint name="j2" type="revolute"><parent>a</parent><child>c</child></joint>
          <joint name="j3" type="revolute"><parent>c</parent><child>a</child></joint>
        </model>"""))
    text = "\n".join(world.warnings)
    assert "joint 'm::screw' of type screw is not simulated: its child link 'm::b' is held fixed to 'm::a'" in text
    assert "joint 'm::j2' ignored: link 'm::c' is already the child of joint 'm::j1'" in text
    assert "joint 'm::j3' ignored: it would close a kinematic loop through 'm::a'" in text
    assert {j.name: j.kind for j in world.joints} == {"m::screw": JointKind.FIXED, "m::j1": JointKind.REVOLUTE}


def test_static_model_has_no_joints_and_links_default_to_sdf_inertia(tmp_path: Path) -> None:
    world = read_sdf_world(BUILT, model_paths(BUILT))
    assert world.warnings == []  # a world built as Gazebo users build it: nothing left out
    names = {j.name for j in world.joints}
    assert "swing_door::hinge" in names and not any(n.startswith("locked_door") for n in names)
    hinge = next(j for j in world.joints if j.name == "swing_door::hinge")
    # the leaf's centre at model (0, 0, 1); the joint 0.5 m along -y in the leaf's frame: world (2, -0.5, 1)
    np.testing.assert_allclose(hinge.anchor, [2.0, -0.5, 1.0], atol=1e-12)
    assert (hinge.axes[0].lower, hinge.axes[0].upper) == pytest.approx((-1.5708, 1.5708))
    locked = [s for s in world.static_shapes if s.name.startswith("locked_door")]
    np.testing.assert_allclose(locked[0].pose[:3, 3], [2.0, 4.0, 1.0], atol=1e-12)
    # a link without <inertial> has SDF's defaults (1 kg, 1 kg·m²), as Gazebo simulates it
    path = world_file(tmp_path, f"<model name='m'><link name='l'>{BOX}</link></model>")
    (body,) = read_sdf_world(path).bodies
    assert (body.mass, body.inertia) == (1.0, (1.0, 0.0, 0.0, 1.0, 0.0, 1.0))


def built_sim(spawn: SpawnPose = SpawnPose()) -> Simulation:
    spec, world = load_world(BUILT, model_paths(BUILT))
    return Simulation(spec, ROBOT, spawn, world=world)


def push(sim: Simulation, seconds: float, speed_rad_s: float = 6.0) -> None:
    end = sim.time_s + seconds
    while sim.time_s < end:
        sim.set_wheel_velocities({"left_wheel_joint": speed_rad_s, "right_wheel_joint": speed_rad_s})
        sim.advance(20)


def test_robot_pushes_the_door_open_and_is_stopped_by_the_static_one() -> None:
    # Towards the swinging door (its leaf at x = 2, y in [-0.5, 0.5]): 0.3 m/s for 12 s.
    sim = built_sim(SpawnPose(0.0, 0.0))
    hinge = sim.model.joint("swing_door::hinge").qposadr[0]
    push(sim, 12.0)
    # pushed at y ≈ 0 towards +x, the leaf turns about +z through the hinge at y = -0.5: the angle goes negative
    assert sim.data.qpos[hinge] < -0.6
    assert sim.ground_truth().position[0] > 2.2
    # Towards the locked door (the same model, included static, at y = 4): the robot stays in front of it.
    sim = built_sim(SpawnPose(0.0, 4.0))
    push(sim, 12.0)
    assert sim.ground_truth().position[0] < 2.0 - 0.025 - 0.2 + 0.02  # chassis front 0.2 m ahead of base_link
    assert any(c.obstacle.startswith("locked_door") for c in sim.take_collisions())


def test_ground_truth_and_lidar_see_the_built_world() -> None:
    world = read_sdf_world(BUILT, model_paths(BUILT))
    grid = ground_truth_map(world_spec(world).compile(), 0.05, 0.25, Bounds(-5, -5, 5, 5))

    def occupied(x: float, y: float) -> bool:
        row, col = grid.cell_of(x, y)
        return bool(grid.data[row, col] == OCCUPIED)

    # both doors' leaves: x 1.975..2.025, y ±0.5 about their centres
    assert all(occupied(2.0, y) for y in (-0.45, 0.0, 0.45, 3.55, 4.0, 4.45))
    assert not occupied(2.0, 0.6) and not occupied(2.1, 0.0)
    # the vehicle's chassis, turned 90° at (-3, -3): x -3.2..-2.8, y -3.3..-2.7
    assert occupied(-3.0, -3.25) and occupied(-3.15, -2.75) and not occupied(-3.3, -3.0)
    # the inch pyramid ×10 at frame "markers" (0, -4) + (1, 0): base ±0.254 m about x = 1 + 0.508, y = -4,
    # apex 0.762 m up; at 0.25 m, a third of the way up, the section is ±0.254·(1 - 0.25/0.762) m
    half = 0.254 * (1 - 0.25 / 0.762)
    assert occupied(1.508, -4.0) and occupied(1.508 + half - 0.03, -4.0) and not occupied(1.508 + half + 0.03, -4.0)
    assert not occupied(1.0, -4.0)
    sim = built_sim(SpawnPose(0.0, 0.0))
    scan = sim.lidar_scan(0)
    ahead = scan.ranges[int(round(-scan.spec.angle_min / scan.spec.angle_increment))]
    # the lidar sits 0.05 m ahead of base_link; the leaf's near face is at x = 2 - 0.025
    assert ahead == pytest.approx(2.0 - 0.025 - 0.05, abs=0.04)
