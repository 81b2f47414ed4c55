"""Files from strangers cannot reach beyond themselves: every reader of users' XML (SDF worlds,
included models, model.config, URDF, xacro and its includes, COLLADA meshes) refuses external
entities (XXE) and entity-expansion bombs ("billion laughs") with one message naming the file
and line; a world's URIs cannot leave its folder, the resource path or an installed share
(``model://m/../..``, absolute paths, ``file://``, a symlink out), while one the user puts on
GZ_SIM_RESOURCE_PATH is read."""
from __future__ import annotations

import textwrap
from collections.abc import Callable
from pathlib import Path

import pytest

from pppbot_common.xml_files import XmlFileError, parse_xml
from pppbot_description.errors import DescriptionError
from pppbot_description.urdf_model import parse_urdf
from pppbot_description.xacro_model import process_xacro
from pppbot_sim.errors import WorldError
from pppbot_sim.meshes import collada_meter
from pppbot_sim.sdf_world import read_sdf_world

SECRET = "SECRET-7f3e9a"
BOX = ("<static>true</static><link name='l'><collision name='c'><geometry><box><size>1 1 1</size></box>"
       "</geometry></collision></link>")


@pytest.fixture()
def secret(tmp_path: Path) -> Path:
    path = tmp_path / "outside" / "secret.txt"
    path.parent.mkdir()
    path.write_text(SECRET)
    return path


def xxe(root: str, body: str, secret: Path) -> str:
    """A document whose entity ``x`` reads ``secret``: ``body`` uses ``&x;`` in an attribute and in text."""
    return f'<?xml version="1.0"?>\n<!DOCTYPE {root} [<!ENTITY x SYSTEM "file://{secret}">]>\n{body}\n'


def laughs(root: str, body: str) -> str:
    """A document whose entity ``x`` expands to 10⁹ "lol"s (about 3 GB)."""
    entities = '<!ENTITY l0 "lol">' + "".join(f'<!ENTITY l{i} "{f"&l{i - 1};" * 10}">' for i in range(1, 10))
    return f'<?xml version="1.0"?>\n<!DOCTYPE {root} [{entities}<!ENTITY x "&l9;">]>\n{body}\n'


ATTACKS = {"xxe": xxe, "billion_laughs": lambda root, body, _secret: laughs(root, body)}
WORLD = "<sdf version='1.8'><world name='&x;'><model name='m'>{box}<pose>0 0 0 0 0 0</pose></model></world></sdf>"
MODEL = "<sdf version='1.8'><model name='&x;'>{box}<plugin name='p' filename='&x;'>&x;</plugin></model></sdf>"
ROBOT = "<robot name='&x;'><link name='base_link'/><material name='m'><color rgba='&x;'/></material></robot>"


def world_including(folder: Path, model_sdf: str, config: str | None = None) -> Path:
    model = folder / "models" / "thing"
    model.mkdir(parents=True)
    (model / "model.sdf").write_text(model_sdf)
    if config is not None:
        (model / "model.config").write_text(config)
    world = folder / "w.sdf"
    world.write_text("<sdf version='1.8'><world name='w'><include><uri>model://thing</uri></include></world></sdf>")
    return world


def refused(call: Callable[[], object], error: type[Exception], file: Path) -> str:
    with pytest.raises(error) as info:
        call()
    message = str(info.value)
    assert message.startswith(f"{file}:") and "entit" in message, message
    assert SECRET not in message and "lollol" not in message
    return message


@pytest.mark.parametrize("attack", ATTACKS)
def test_every_xml_reader_refuses_entities_naming_the_file(attack: str, tmp_path: Path, secret: Path) -> None:
    make = ATTACKS[attack]
    world = tmp_path / "world.sdf"
    world.write_text(make("sdf", WORLD.format(box=BOX), secret))
    refused(lambda: read_sdf_world(world), WorldError, world)

    included = world_including(tmp_path / "a", make("sdf", MODEL.format(box=BOX), secret))
    refused(lambda: read_sdf_world(included), WorldError, included.parent / "models" / "thing" / "model.sdf")

    config = make("model", "<model><name>&x;</name><sdf version='1.8'>model.sdf</sdf></model>", secret)
    with_config = world_including(tmp_path / "b", f"<sdf version='1.8'><model name='t'>{BOX}</model></sdf>", config)
    refused(lambda: read_sdf_world(with_config), WorldError, with_config.parent / "models" / "thing" / "model.config")

    urdf = tmp_path / "robot.urdf"
    urdf.write_text(make("robot", ROBOT, secret))
    refused(lambda: parse_urdf(urdf.read_text(), str(urdf)), DescriptionError, urdf)

    top = tmp_path / "robot.urdf.xacro"
    top.write_text(make("robot", ROBOT.replace("<robot ", "<robot xmlns:xacro='http://www.ros.org/wiki/xacro' "),
                        secret))
    refused(lambda: process_xacro(top), DescriptionError, top)
    part = tmp_path / "part.xacro"
    part.write_text(make("robot", "<robot xmlns:xacro='http://www.ros.org/wiki/xacro'><link name='&x;'/></robot>",
                         secret))
    including = tmp_path / "including.urdf.xacro"
    including.write_text("<robot name='r' xmlns:xacro='http://www.ros.org/wiki/xacro'><link name='base_link'/>"
                         f"<xacro:include filename='{part}'/></robot>")
    with pytest.raises(DescriptionError) as info:  # expat (xacro's parser) or pppbot's check refuses it
        process_xacro(including)
    assert str(part) in str(info.value) and SECRET not in str(info.value)

    mesh = tmp_path / "mesh.dae"
    mesh.write_text(make("COLLADA", "<COLLADA xmlns='http://www.collada.org/2005/11/COLLADASchema'><asset>"
                                    "<unit meter='&x;'/></asset></COLLADA>", secret))
    refused(lambda: collada_meter(mesh), WorldError, mesh)


def test_an_entity_declared_in_utf16_is_refused_too(tmp_path: Path, secret: Path) -> None:
    data = xxe("robot", "<robot name='r'><link name='base_link'/></robot>", secret).replace(
        'encoding="utf-8"', "").replace('<?xml version="1.0"?>', '<?xml version="1.0" encoding="UTF-16"?>')
    with pytest.raises(XmlFileError, match=r"robot\.urdf: declares an entity"):
        parse_xml(data.encode("utf-16"), "robot.urdf")


def test_an_entity_only_named_in_a_comment_or_a_text_is_no_declaration(tmp_path: Path, secret: Path) -> None:
    """A file that talks about ``<!ENTITY`` is read; one that declares an entity after such a mention
    is refused at the declaration's line."""
    mention = "<!-- no <!ENTITY here: this file declares none -->\n"
    urdf = tmp_path / "robot.urdf"
    urdf.write_text(f"<?xml version='1.0'?>\n{mention}<robot name='r'><link name='base_link'/>"
                    "<!-- <!ENTITY --></robot>")
    assert parse_urdf(urdf.read_text(), str(urdf)).name == "r"
    assert parse_xml(b"<r><![CDATA[<!ENTITY x 'y'>]]></r>", "cdata.xml").text == "<!ENTITY x 'y'>"
    declared = tmp_path / "declared.urdf"
    declared.write_text(xxe("robot", ROBOT, secret).replace("?>\n", "?>\n" + mention, 1))
    assert refused(lambda: parse_urdf(declared.read_text(), str(declared)), DescriptionError, declared).startswith(
        f"{declared}:3: declares an entity")


def test_a_doctype_naming_an_outside_dtd_fetches_nothing(tmp_path: Path, secret: Path) -> None:
    dtd = tmp_path / "outside" / "defaults.dtd"
    dtd.write_text('<!ATTLIST robot name CDATA "from-the-dtd">')
    root = parse_xml(f'<!DOCTYPE robot SYSTEM "file://{dtd}"><robot><link name="base_link"/></robot>', "r.urdf")
    assert root.get("name") is None  # the DTD's default attribute was never read


@pytest.fixture()
def world_folder(tmp_path: Path, secret: Path) -> Path:
    """A world's folder with a model ``thing`` whose mesh the tests point at things."""
    folder = tmp_path / "world"
    (folder / "models" / "thing" / "meshes").mkdir(parents=True)
    (secret.parent / "mesh.stl").write_text("solid s\nendsolid s\n")
    return folder


def world_with_mesh(folder: Path, uri: str) -> Path:
    (folder / "models" / "thing" / "model.sdf").write_text(textwrap.dedent(f"""\
        <sdf version='1.8'><model name='thing'><static>true</static><link name='l'><collision name='c'>
        <geometry><mesh><uri>{uri}</uri></mesh></geometry></collision></link></model></sdf>"""))
    world = folder / "w.sdf"
    world.write_text("<sdf version='1.8'><world name='w'><include><uri>model://thing</uri></include></world></sdf>")
    return world


@pytest.mark.parametrize("uri", ["model://thing/../../../outside/mesh.stl", "model://../../outside/mesh.stl",
                                 "{outside}/mesh.stl", "file://{outside}/mesh.stl", "../../../outside/mesh.stl",
                                 "meshes/link.stl"])
def test_a_world_cannot_point_outside_its_folders(uri: str, world_folder: Path, secret: Path) -> None:
    link = world_folder / "models" / "thing" / "meshes" / "link.stl"
    link.symlink_to(secret.parent / "mesh.stl")  # a symlink out, as an archive can carry
    world = world_with_mesh(world_folder, uri.format(outside=secret.parent))
    with pytest.raises(WorldError, match=rf"{secret.parent / 'mesh.stl'} is outside the folders this world may read "
                                         r"from \(.*\); copy it .* or add its folder to GZ_SIM_RESOURCE_PATH"):
        read_sdf_world(world)


def test_a_folder_the_user_puts_on_the_resource_path_is_read(world_folder: Path, secret: Path,
                                                              monkeypatch: pytest.MonkeyPatch) -> None:
    (secret.parent / "mesh.stl").write_text(textwrap.dedent("""\
        solid t
        facet normal 0 0 1
        outer loop
        vertex 0 0 0
        vertex 1 0 0
        vertex 0 1 0
        endloop
        endfacet
        endsolid t
        """))
    world = world_with_mesh(world_folder, f"{secret.parent}/mesh.stl")
    monkeypatch.setenv("GZ_SIM_RESOURCE_PATH", str(secret.parent))
    assert read_sdf_world(world).name == "w"
    local = world_folder / "models" / "thing" / "meshes" / "own.stl"
    local.write_text((secret.parent / "mesh.stl").read_text())
    monkeypatch.delenv("GZ_SIM_RESOURCE_PATH")
    assert read_sdf_world(world_with_mesh(world_folder, "meshes/own.stl")).name == "w"  # its own files: always


def test_dot_dots_after_a_symlink_cannot_pass_for_an_installed_share(world_folder: Path, secret: Path,
                                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    # As text, s/../../(...)/opt/fake/share/p/mesh.stl is the installed share /opt/fake/share; the kernel
    # follows s into the world's own d1/.../dN first, climbs back to the world folder, and takes its
    # opt/fake/share/p/mesh.stl: a symlink out.
    monkeypatch.setenv("AMENT_PREFIX_PATH", "/opt/fake")
    model = world_folder / "models" / "thing"
    depth = len(model.parts)
    deep = model.joinpath(*[f"d{i}" for i in range(depth)])
    deep.mkdir(parents=True)
    (model / "s").symlink_to(deep)
    bait = model / "opt" / "fake" / "share" / "p" / "mesh.stl"
    bait.parent.mkdir(parents=True)
    bait.symlink_to(secret.parent / "mesh.stl")
    world = world_with_mesh(world_folder, "s/" + "../" * depth + "opt/fake/share/p/mesh.stl")
    with pytest.raises(WorldError, match=rf"{secret.parent / 'mesh.stl'} is outside the folders this world may read"):
        read_sdf_world(world)


@pytest.mark.parametrize("named", ["../../../outside/model.sdf", "{outside}/model.sdf"])
def test_a_model_config_cannot_name_a_model_file_outside(named: str, world_folder: Path, secret: Path) -> None:
    (secret.parent / "model.sdf").write_text(f"<sdf version='1.8'><model name='stolen'>{BOX}</model></sdf>")
    model = world_folder / "models" / "thing"
    named = named.format(outside=secret.parent)
    (model / "model.config").write_text(f"<model><sdf version='1.8'>{named}</sdf></model>")
    world = world_with_mesh(world_folder, "meshes/none.stl")
    with pytest.raises(WorldError, match=rf"{secret.parent / 'model.sdf'} is outside the folders this world may read"):
        read_sdf_world(world)
    (model / "model.config").unlink()
    (model / "model.config").symlink_to(secret.parent / "model.sdf")  # the config itself a symlink out
    with pytest.raises(WorldError, match=r"model\.sdf is outside the folders this world may read"):
        read_sdf_world(world)
