"""Meshes at Gazebo's sizes: COLLADA's ``<unit meter>`` applied after the node transforms, its
``<up_axis>`` not (gz-common's ColladaLoader reads neither axis nor rotates), ``<scale>`` on
top; textures never loaded, never a traceback. Expected figures worked out by hand."""
from __future__ import annotations

import logging
import textwrap
from pathlib import Path

import numpy as np
import pytest

from pppbot_common.maps import OCCUPIED
from pppbot_sim.errors import WorldError
from pppbot_sim.ground_truth import ground_truth_map
from pppbot_sim.meshes import _load, collada_meter, load_mesh
from pppbot_sim.mj_build import world_spec
from pppbot_sim.sdf_world import read_sdf_world

#: A square pyramid: base ±1 unit at z 0, apex 3 units up, inside a node moved 2 units along x.
PYRAMID = "-1 -1 0  1 -1 0  1 1 0  -1 1 0  0 0 3"
FACES = "0 2 1  0 3 2  0 1 4  1 2 4  2 3 4  3 0 4"


def dae(path: Path, unit: str = "", up_axis: str = "Z_UP", texture: str = "") -> Path:
    """A COLLADA pyramid with the given ``<unit>`` element and a material whose texture is
    ``texture`` (a file that need not exist)."""
    image = f'<library_images><image id="img"><init_from>{texture}</init_from></image></library_images>' \
        if texture else ""
    diffuse = '<texture texture="smp" texcoord="UV"/>' if texture else '<color>1 0 0 1</color>'
    params = ('<newparam sid="srf"><surface type="2D"><init_from>img</init_from></surface></newparam>'
              '<newparam sid="smp"><sampler2D><source>srf</source></sampler2D></newparam>') if texture else ""
    path.write_text(textwrap.dedent(f"""\
        <?xml version="1.0" encoding="utf-8"?>
        <COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
          <asset>{unit}<up_axis>{up_axis}</up_axis></asset>
          {image}
          <library_effects><effect id="fx"><profile_COMMON>{params}
            <technique sid="c"><lambert><diffuse>{diffuse}</diffuse></lambert></technique>
          </profile_COMMON></effect></library_effects>
          <library_materials><material id="mat"><instance_effect url="#fx"/></material></library_materials>
          <library_geometries><geometry id="g"><mesh>
            <source id="p"><float_array id="pa" count="15">{PYRAMID}</float_array>
              <technique_common><accessor source="#pa" count="5" stride="3">
                <param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/>
              </accessor></technique_common></source>
            <vertices id="v"><input semantic="POSITION" source="#p"/></vertices>
            <triangles count="6" material="m"><input semantic="VERTEX" source="#v" offset="0"/>
              <p>{FACES}</p></triangles>
          </mesh></geometry></library_geometries>
          <library_visual_scenes><visual_scene id="s"><node name="n"><translate>2 0 0</translate>
            <instance_geometry url="#g"><bind_material><technique_common>
              <instance_material symbol="m" target="#mat"/></technique_common></bind_material></instance_geometry>
          </node></visual_scene></library_visual_scenes>
          <scene><instance_visual_scene url="#s"/></scene>
        </COLLADA>
        """))
    return path


@pytest.mark.parametrize("unit, meter", [("", 1.0), ('<unit name="inch" meter="0.0254"/>', 0.0254),
                                         ('<unit name="centimeter" meter="0.01"/>', 0.01)])
def test_collada_units_scale_the_mesh_after_its_node_transforms(tmp_path, unit, meter):
    path = dae(tmp_path / "pyramid.dae", unit)
    assert collada_meter(path) == meter
    vertices, faces = load_mesh(path, (10.0, 10.0, 10.0))
    assert faces.shape == (6, 3)
    # node: x + 2 units; then metres per unit; then <scale> 10
    np.testing.assert_allclose(vertices.min(axis=0), np.array([1.0, -1.0, 0.0]) * meter * 10, atol=1e-12)
    np.testing.assert_allclose(vertices.max(axis=0), np.array([3.0, 1.0, 3.0]) * meter * 10, atol=1e-12)


def test_up_axis_is_not_applied_as_in_gazebo(tmp_path):
    z_up, _ = load_mesh(dae(tmp_path / "z.dae", up_axis="Z_UP"))
    y_up, _ = load_mesh(dae(tmp_path / "y.dae", up_axis="Y_UP"))
    np.testing.assert_array_equal(z_up, y_up)
    assert y_up[:, 2].max() == pytest.approx(3.0)  # the apex stays up the file's z


def test_a_bad_unit_is_named(tmp_path):
    with pytest.raises(WorldError, match=r"bad\.dae: <unit meter=\"-2\"> must be a positive number"):
        load_mesh(dae(tmp_path / "bad.dae", '<unit meter="-2"/>'))
    (tmp_path / "text.dae").write_text("not xml <")
    with pytest.raises(WorldError, match=r"text\.dae: not a COLLADA file"):
        collada_meter(tmp_path / "text.dae")


def test_a_missing_texture_prints_nothing(tmp_path, caplog, capfd):
    caplog.set_level(logging.DEBUG)
    _load.cache_clear()
    vertices, _ = load_mesh(dae(tmp_path / "textured.dae", texture="../materials/textures/cone.png"))
    assert len(vertices) == 5
    assert not [r for r in caplog.records if r.name.startswith("trimesh") and r.levelno < logging.ERROR
                and r.exc_info], "a traceback from trimesh"
    out, err = capfd.readouterr()
    assert "Traceback" not in out + err


def test_an_inch_cone_scaled_ten_times_in_a_world_has_gazebos_size(tmp_path, placed_vertices):
    """The issue's case: a model-library cone in inches with <scale>10 10 10</scale>, ten of them
    in a row: each 0.508 m wide and 0.762 m tall, free space between them, not one block."""
    dae(tmp_path / "cone.dae", '<unit name="inch" meter="0.0254"/>', up_axis="Y_UP")
    models = "".join(f"""
        <model name="cone{i}"><static>true</static><pose>{2.0 * i} 0 0 0 0 0</pose><link name="l">
          <collision name="c"><geometry><mesh><uri>cone.dae</uri><scale>10 10 10</scale></mesh></geometry></collision>
        </link></model>""" for i in range(10))
    (tmp_path / "cones.sdf").write_text(f'<?xml version="1.0"?><sdf version="1.7"><world name="w">{models}'
                                        "</world></sdf>")
    model = world_spec(read_sdf_world(tmp_path / "cones.sdf")).compile()
    placed = placed_vertices(model, "cone3::l::c")
    # model at x 6; node +2 inch; ±1 inch base; 3 inch apex; × 0.0254 × 10
    np.testing.assert_allclose(placed.min(axis=0), [6.0 + 0.254, -0.254, 0.0], atol=1e-6)
    np.testing.assert_allclose(placed.max(axis=0), [6.0 + 0.762, 0.254, 0.762], atol=1e-6)
    # the ground-truth map at lidar height: ten small squares, the rest free
    grid = ground_truth_map(model, resolution=0.05, height=0.2)
    occupied = float((grid.data == OCCUPIED).mean())
    assert 0.0 < occupied < 0.05, occupied
