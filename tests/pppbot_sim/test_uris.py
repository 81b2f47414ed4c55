"""SDF URIs as Gazebo resolves them: model://, package:// (ament index), file://, paths, a path
from another machine that names a model here, and Fuel URLs from the local Fuel cache."""
from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest

from pppbot_sim.sdf_world import read_sdf_world
from pppbot_sim.uris import UriError, fuel_caches, resolve_uri

BOX_MODEL = """<?xml version="1.0"?><sdf version="1.7"><model name="{name}"><static>true</static><link name="l">
  <collision name="c"><geometry><box><size>1 1 1</size></box></geometry></collision></link></model></sdf>"""


@pytest.fixture()
def models(tmp_path: Path) -> Path:
    root = tmp_path / "models"
    for name in ("room", "cone"):
        (root / name / "meshes").mkdir(parents=True)
        (root / name / "model.sdf").write_text(BOX_MODEL.format(name=name))
    (root / "cone" / "meshes" / "cone.dae").write_text("<COLLADA/>")
    return root


def test_model_file_and_relative_uris(models: Path, tmp_path: Path) -> None:
    here = tmp_path / "worlds"
    assert resolve_uri("model://room", here, [models]) == (models / "room", None)
    assert resolve_uri("model://cone/meshes/cone.dae", here, [models]) == (models / "cone" / "meshes" / "cone.dae",
                                                                           None)
    assert resolve_uri("meshes/x.stl", here, [models]) == (here / "meshes" / "x.stl", None)
    assert resolve_uri(f"file://{models / 'room'}", here, []) == (models / "room", None)
    with pytest.raises(UriError, match=r"unknown model 'door' \(model://door\); searched .*models"):
        resolve_uri("model://door", here, [models])
    with pytest.raises(UriError, match="the scheme 'ftp://' is not supported"):
        resolve_uri("ftp://host/x", here, [models])


def test_a_path_from_another_machine_resolves_to_the_model_of_that_name_with_a_warning(models: Path,
                                                                                       tmp_path: Path) -> None:
    path, warning = resolve_uri("file:///home/someone/ws/src/sim/models/room", tmp_path, [models])
    assert path == models / "room"
    assert warning == ("file:///home/someone/ws/src/sim/models/room does not exist here; using "
                       f"{models / 'room'}, the model of that name on the resource path")
    mesh, warning = resolve_uri("/home/someone/models/cone/meshes/cone.dae", tmp_path, [models])
    assert mesh == models / "cone" / "meshes" / "cone.dae" and warning is not None
    # nothing of that name here: the path as given (the caller says it is missing)
    assert resolve_uri("file:///home/someone/models/door", tmp_path, [models]) == \
        (Path("/home/someone/models/door"), None)


def test_package_uris_go_through_the_ament_index(tmp_path: Path) -> None:
    path, _ = resolve_uri("package://pppbot_description/urdf/robot.urdf.xacro", tmp_path, [])
    assert path.name == "robot.urdf.xacro" and path.parent.name == "urdf" and path.is_file()
    with pytest.raises(UriError, match="package 'no_such_pkg' is not in the ament index"):
        resolve_uri("package://no_such_pkg/x.dae", tmp_path, [])


def test_fuel_urls_come_from_the_local_cache_newest_version_first(tmp_path: Path) -> None:
    cache = tmp_path / "fuel"
    for version in ("2", "10"):
        (cache / "fuel.gazebosim.org" / "openrobotics" / "models" / "construction cone" / version / "meshes").mkdir(
            parents=True)
    url = "https://fuel.gazebosim.org/1.0/OpenRobotics/models/Construction%20Cone"
    model = cache / "fuel.gazebosim.org" / "openrobotics" / "models" / "construction cone"
    assert resolve_uri(url, tmp_path, [], [cache]) == (model / "10", None)
    assert resolve_uri(url + "/2", tmp_path, [], [cache]) == (model / "2", None)
    assert resolve_uri(url + "/2/files/meshes/cone.dae", tmp_path, [], [cache]) == \
        (model / "2" / "meshes" / "cone.dae", None)
    with pytest.raises(UriError, match=r"'OpenRobotics/Door' is not in the local Fuel cache .*gz fuel download"):
        resolve_uri("https://fuel.gazebosim.org/1.0/OpenRobotics/models/Door", tmp_path, [], [cache])
    assert fuel_caches({"HOME": "/h", "GZ_FUEL_CACHE_PATH": "/c"}) == \
        [Path("/c"), Path("/h/.gz/fuel"), Path("/h/.ignition/fuel")]


def test_a_world_copied_from_another_machine_loads_with_one_warning(models: Path, tmp_path: Path) -> None:
    world = tmp_path / "copied.sdf"
    world.write_text(textwrap.dedent("""\
        <?xml version="1.0"?>
        <sdf version="1.7"><world name="w">
          <include><uri>file:///home/someone/gz_ws/src/my_sim/models/room</uri><pose>1 2 0 0 0 0</pose></include>
        </world></sdf>
        """))
    loaded = read_sdf_world(world, [models])
    (shape,) = loaded.static_shapes
    np.testing.assert_allclose(shape.pose[:3, 3], [1.0, 2.0, 0.0])
    (warning,) = [w for w in loaded.warnings if "does not exist here" in w]
    assert warning.startswith(f"{world}:3: file:///home/someone/gz_ws/src/my_sim/models/room does not exist here")
