"""SDF worlds: every supported feature loads, poses compose as Gazebo's, errors name file and element."""
from __future__ import annotations

import math
import textwrap
from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from pppbot_sim.errors import WorldError
from pppbot_sim.mj_build import world_spec
from pppbot_sim.sdf_world import read_sdf_world
from pppbot_sim.worlds import find_world, known_worlds, model_paths

DATA = Path(__file__).parent / "data"
FEATURES = DATA / "features.sdf"


@pytest.fixture(scope="module")
def world():
    return read_sdf_world(FEATURES, model_paths(FEATURES))


def shape(world, suffix):
    (found,) = [s for s in world.static_shapes if s.name.endswith(suffix)]
    return found


def test_world_settings(world):
    assert (world.name, world.step_size_s, world.gravity) == ("features", 0.002, (0.0, 0.0, -9.81))


def test_every_geometry_kind_loads(world):
    kinds = {s.kind for s in world.static_shapes}
    assert kinds == {"plane", "box", "cylinder", "sphere", "capsule", "ellipsoid", "mesh"}
    assert shape(world, "shapes::l::cyl").size == (0.25, 1.0)
    assert shape(world, "shapes::l::egg").size == (0.2, 0.3, 0.5)


def test_nested_pose_composition_matches_gazebo(world):
    """outer (1, 2, yaw 90°) ∘ inner (1, 0, 0) ∘ link (0, 0, 0.5) ∘ collision (0.5, 0, 0, roll 90°)."""
    box = shape(world, "outer::inner::link::box")
    np.testing.assert_allclose(box.pose[:3, 3], [1.0, 3.5, 0.5], atol=1e-12)
    expected = Rotation.from_euler("z", math.pi / 2) * Rotation.from_euler("x", math.pi / 2)
    np.testing.assert_allclose(box.pose[:3, :3], expected.as_matrix(), atol=1e-12)
    # MuJoCo puts the geom there too: roll 90° turns the box's z (its 0.6 m side) onto -y,
    # then yaw 90° turns -y onto +x, so the long side lies along world x.
    model = world_spec(world).compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    gid = model.geom("outer::inner::link::box").id
    np.testing.assert_allclose(data.geom_xpos[gid], [1.0, 3.5, 0.5], atol=1e-9)
    np.testing.assert_allclose(np.abs(data.geom_xmat[gid].reshape(3, 3) @ [0, 0, 1]), [1, 0, 0], atol=1e-9)


def test_degrees_attribute(world):
    box = shape(world, "deg::l::c")
    np.testing.assert_allclose(box.pose[:3, :3], Rotation.from_euler("z", 90, degrees=True).as_matrix(), atol=1e-12)
    turned = shape(world, "shapes::l::turned")
    np.testing.assert_allclose(turned.pose[:3, :3], Rotation.from_euler("z", 45.0).as_matrix(), atol=1e-12)


def test_include_resolves_models_and_its_pose_replaces_the_models_own(world):
    cone = shape(world, "cone_a::link::collision")
    assert cone.kind == "mesh" and cone.mesh is not None and cone.mesh.name == "traffic_cone.dae"
    np.testing.assert_allclose(cone.pose[:3, 3], [4.0, 0.0, 0.0])
    crate = shape(world, "crate::link::body")  # the model's own pose (100, 100, 100) is replaced
    np.testing.assert_allclose(crate.pose[:3, 3], [4.0, 3.0, 0.25])


def test_collada_mesh_reaches_mujoco_with_its_size(world, placed_vertices):
    world_vertices = placed_vertices(world_spec(world).compile(), "cone_a::link::collision")
    np.testing.assert_allclose(world_vertices.min(axis=0), [3.8, -0.2, 0.0], atol=1e-6)
    np.testing.assert_allclose(world_vertices.max(axis=0)[2], 0.7, atol=1e-6)


def test_dynamic_link_held_by_a_fixed_joint_to_the_world_is_welded_there(world):
    (body,) = world.bodies
    assert body.name == "loose::box" and body.mass == 2.0
    model = world_spec(world).compile()
    box = model.body("loose::box").id
    assert model.body_mass[box] == pytest.approx(2.0)
    assert model.body_parentid[box] == 0 and model.body_jntnum[box] == 0 and model.njnt == 0


def test_skipped_and_unsupported_elements_are_reported(world):
    assert world.skipped_summary() == "skipped gui, plugin ×2"  # the world's <light> lights the cameras
    assert [(light.name, light.kind) for light in world.lighting.lights] == [("sun", "directional")]
    assert any("unsupported element <actor> in <world>" in w and "features.sdf:" in w for w in world.warnings)
    # elements that change physics are named, not silently dropped
    assert any("unsupported element <kinematic> in <link>" in w for w in world.warnings)
    assert any("unsupported element <self_collide> in <link>" in w for w in world.warnings)
    assert not any("scene" in w for w in world.warnings)


def test_free_link_with_full_inertia(tmp_path):
    (tmp_path / "w.sdf").write_text(world_text("""
        <model name="m"><pose>0 0 1 0 0 0</pose><link name="l">
          <inertial><pose>0.1 0 0 0 0 0</pose><mass>3.0</mass>
            <inertia><ixx>0.1</ixx><iyy>0.2</iyy><izz>0.3</izz></inertia></inertial>
          <collision name="c"><geometry><sphere><radius>0.2</radius></sphere></geometry></collision>
        </link></model>"""))
    model = world_spec(read_sdf_world(tmp_path / "w.sdf")).compile()
    body = model.body("m::l")
    assert body.mass[0] == pytest.approx(3.0)
    np.testing.assert_allclose(sorted(body.inertia), [0.1, 0.2, 0.3])
    np.testing.assert_allclose(body.ipos, [0.1, 0.0, 0.0])
    assert model.jnt_type[model.joint("m::l::free").id] == mujoco.mjtJoint.mjJNT_FREE  # no joint holds it
    (tmp_path / "bad.sdf").write_text(world_text("""
        <model name="m"><link name="l"><inertial><mass>1</mass><inertia><ixx>-1</ixx><iyy>1</iyy><izz>1</izz>
        </inertia></inertial><collision name="c"><geometry><sphere><radius>0.2</radius></sphere></geometry>
        </collision></link></model>"""))
    with pytest.raises(WorldError, match="inertia matrix must be positive definite"):
        read_sdf_world(tmp_path / "bad.sdf")


@pytest.mark.parametrize("suffix, scale", [(".stl", (1.0, 1.0, 1.0)), (".obj", (2.0, 1.0, 0.5))])
def test_stl_and_obj_meshes_with_scale(tmp_path, suffix, scale):
    trimesh.creation.box(extents=[1, 1, 1]).export(tmp_path / f"cube{suffix}")
    (tmp_path / "w.sdf").write_text(world_text(f"""
        <model name="m"><static>true</static><link name="l"><collision name="c"><geometry>
          <mesh><uri>cube{suffix}</uri><scale>{' '.join(map(str, scale))}</scale></mesh>
        </geometry></collision></link></model>"""))
    w = read_sdf_world(tmp_path / "w.sdf")
    model = world_spec(w).compile()
    mid = model.geom_dataid[model.geom("m::l::c").id]
    vertices = model.mesh_vert[model.mesh_vertadr[mid]:model.mesh_vertadr[mid] + model.mesh_vertnum[mid]]
    extents = sorted(np.ptp(vertices, axis=0))
    np.testing.assert_allclose(extents, sorted(scale), atol=1e-6)


def world_text(body: str) -> str:
    return textwrap.dedent(f"""\
        <?xml version="1.0"?>
        <sdf version="1.8"><world name="w">{body}
        </world></sdf>
    """)


@pytest.mark.parametrize("body, message", [
    ('<include><uri>model://no_such_model</uri></include>', r"w\.sdf:2: unknown model 'no_such_model'"),
    ('<model name="m"><static>true</static><link name="l"><collision name="c"><geometry>'
     '<heightmap><uri>h.png</uri></heightmap></geometry></collision></link></model>',
     r"geometry <heightmap> is not supported \(supported: box, capsule"),
    ('<model name="m"><static>true</static><link name="l"><collision name="c"><geometry>'
     '<mesh><uri>missing.dae</uri></mesh></geometry></collision></link></model>', r"mesh file not found: missing\.dae"),
    ('<model name="m"><static>true</static><pose>1 2 three 0 0 0</pose></model>',
     r"<pose> needs 6 or 7 numbers, not '1 2 three 0 0 0'"),
    ('<physics><max_step_size>0.5</max_step_size></physics>', r"max_step_size 0\.5 s must be in \(0, 0\.1\]"),
    ('<model name="m"><static>true</static><link name="l"><collision name="c"><geometry>'
     '<box><size>1 -1 1</size></box></geometry></collision></link></model>', r"sizes must be positive"),
    ('<model name="m"><static>true</static><pose rotation_format="quat_xyzw">0 0 0 0 0 0 0</pose></model>',
     r"quat_xyzw'> needs x y z qx qy qz qw with a nonzero quaternion, not '0 0 0 0 0 0 0'"),
    ('<model name="m"><static>true</static><pose rotation_format="quat_xyzw">0 0 0 1e-9 0 0 1e-9</pose></model>',
     r"quat_xyzw'> needs x y z qx qy qz qw with a nonzero quaternion"),
    ('<model name="m"><static>true</static><link name="l"><collision name="c"><geometry>'
     '<plane><normal>0 0 0</normal></plane></geometry></collision></link></model>', r"<normal> must not be 0 0 0"),
])
def test_bad_worlds_name_file_line_and_element(tmp_path, body, message):
    (tmp_path / "w.sdf").write_text(world_text(body))
    with pytest.raises(WorldError, match=message):
        read_sdf_world(tmp_path / "w.sdf")


def test_malformed_xml_and_missing_file(tmp_path):
    (tmp_path / "bad.sdf").write_text('<?xml version="1.0"?>\n<sdf>\n<world name="x">\n</sdf>\n')
    with pytest.raises(WorldError, match=r"bad\.sdf:4: malformed XML"):
        read_sdf_world(tmp_path / "bad.sdf")
    with pytest.raises(WorldError, match=r"nope\.sdf: world file not found"):
        read_sdf_world(tmp_path / "nope.sdf")


def test_shipped_worlds_are_known_and_load():
    assert {"empty", "cones", "maze", "room", "office"} <= set(known_worlds())
    for name in ("empty", "cones", "maze", "room", "office"):
        path = find_world(name)
        w = read_sdf_world(path, model_paths(path))
        assert w.warnings == [], (name, w.warnings)
        world_spec(w).compile()


def test_unknown_world_lists_the_known_ones():
    with pytest.raises(WorldError, match=r"unknown world 'mars'; known worlds: "
                                         r"cones, empty, maze, maze_boxes, office, room, room_boxes"):
        find_world("mars")
    assert find_world("maze.sdf") == find_world("maze")
    with pytest.raises(WorldError, match=r"world file 'mars.sdf' not found \(known worlds in .*: cones, empty"):
        find_world("mars.sdf")


@pytest.mark.parametrize("normal", [(0, 0, 1), (0, 0, -1), (1, 0, 0), (0.3, -0.4, 0.5)])
def test_a_plane_turns_its_z_onto_its_normal_and_a_quaternion_pose_reads_as_xyzw(tmp_path, normal):
    n = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    q = Rotation.from_euler("z", 30, degrees=True).as_quat()  # x y z w
    (tmp_path / "w.sdf").write_text(world_text(
        f'<model name="m"><static>true</static><pose rotation_format="quat_xyzw">1 2 3 {" ".join(map(str, q))}</pose>'
        f'<link name="l"><collision name="c"><geometry><plane><normal>{" ".join(map(str, normal))}</normal>'
        f'</plane></geometry></collision></link></model>'))
    (plane,) = read_sdf_world(tmp_path / "w.sdf").static_shapes
    model = Rotation.from_quat(q).as_matrix()
    np.testing.assert_allclose(plane.pose[:3, 3], [1, 2, 3], atol=1e-12)
    np.testing.assert_allclose(plane.pose[:3, :3] @ [0, 0, 1], model @ n, atol=1e-12)
    np.testing.assert_allclose(plane.pose[:3, :3] @ plane.pose[:3, :3].T, np.eye(3), atol=1e-12)


def test_world_lights_light_the_cameras_images(tmp_path):
    (tmp_path / "w.sdf").write_text(world_text("""
        <scene><ambient>0.3 0.3 0.3 1</ambient></scene>
        <light type="directional" name="sun"><pose>0 0 10 0 0 0</pose><direction>-0.5 0.1 -0.9</direction>
          <diffuse>0.8 0.8 0.8 1</diffuse></light>
        <light type="spot" name="lamp"><pose>1 2 3 0 0 0</pose>
          <attenuation><range>5</range><constant>0.5</constant><linear>0.1</linear><quadratic>0.01</quadratic></attenuation>
          <spot><inner_angle>0.3</inner_angle><outer_angle>0.6</outer_angle></spot></light>"""))
    world = read_sdf_world(tmp_path / "w.sdf")
    assert world.skipped_summary() == "" and world.warnings == []
    model = world_spec(world).compile()
    assert model.nlight == 2 and not model.light_castshadow.any()
    np.testing.assert_allclose(model.light_dir[0], np.array([-0.5, 0.1, -0.9]) / np.linalg.norm([-0.5, 0.1, -0.9]),
                               atol=1e-6)
    np.testing.assert_allclose(model.light_diffuse[0], [0.8, 0.8, 0.8])
    assert int(model.light_type[1]) == int(mujoco.mjtLightType.mjLIGHT_SPOT)
    np.testing.assert_allclose(model.light_pos[1], [1, 2, 3])
    np.testing.assert_allclose(model.light_attenuation[1], [0.5, 0.1, 0.01])
    assert model.light_cutoff[1] == pytest.approx(math.degrees(0.6))
    # the scene's ambient light; no light at the camera, as in Gazebo
    np.testing.assert_allclose(model.vis.headlight.ambient, [0.3, 0.3, 0.3])
    np.testing.assert_allclose(model.vis.headlight.diffuse, [0, 0, 0])
