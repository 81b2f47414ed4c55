"""The fuzz targets of :mod:`fuzz`: every parser of users' files, each fed one file of bytes.

A target writes the bytes where its parser reads them (beside fixed, valid companions: a map's
image, a bag's metadata) and calls the parser as pppbot does. The parser may refuse the file
only with its own error (a :class:`~pppbot_common.errors.PppbotError`) whose message names
the file; anything else (another exception, a crash, a hang, memory beyond the cap) is a
finding. Seed inputs live in ``tests/data/fuzz/<target>/``, the fixed companions in
``tests/data/fuzz/companions/``.
"""
from __future__ import annotations

import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SEEDS = ROOT / "tests" / "data" / "fuzz"
COMPANIONS = SEEDS / "companions"


class Finding(AssertionError):
    """A parser refused a file without naming it."""


@dataclass(frozen=True)
class Target:
    """``run(path)`` parses the file ``file_name`` holding the input, in a scratch folder
    ``prepare`` filled with its companions."""

    name: str
    file_name: str
    run: Callable[[Path], object]
    what: str
    prepare: Callable[[Path], None] = lambda folder: None


def _urdf(path: Path) -> object:
    from pppbot_description.urdf_model import parse_urdf
    return parse_urdf(path.read_bytes().decode("utf-8", "replace"), str(path))


def _xacro(path: Path) -> object:
    from pppbot_description.xacro_model import process_xacro
    return process_xacro(path)


def _sdf(path: Path) -> object:
    from pppbot_sim.sdf_world import read_sdf_world
    return read_sdf_world(path, [ROOT / "worlds" / "models"])


def _mesh(path: Path) -> object:
    from pppbot_sim import meshes
    meshes._load.cache_clear()  # the same path each time: read it again
    return meshes.load_mesh(path)


def _map(path: Path) -> object:
    from pppbot_common.maps import load_map
    return load_map(path)


def _map_companions(folder: Path) -> None:
    shutil.copy(COMPANIONS / "fuzz.pgm", folder / "fuzz.pgm")


def _map_image_yaml(image: str) -> Callable[[Path], None]:
    def prepare(folder: Path) -> None:
        (folder / "map.yaml").write_text(f"image: {image}\nresolution: 0.05\norigin: [-1.0, -1.0, 0.0]\n"
                                         "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.25\nmode: trinary\n")
    return prepare


def _map_image(path: Path) -> object:
    return _map(path.parent / "map.yaml")


def _params(path: Path) -> object:
    from pppbot_bringup.parameter_files import map_free_navigation_problem
    return map_free_navigation_problem(path)


def _bag(path: Path) -> object:
    """The bag folder ``path`` is in, as ``bag info`` and ``bag play`` read it: the summary, then
    every message."""
    from pppbot_bag.reader import bag_messages, open_bag, summarize
    summary = summarize(path.parent)
    with open_bag(path.parent) as reader:
        for _ in bag_messages(reader):
            pass
    return summary


def _bag_companions(keep: str) -> Callable[[Path], None]:
    def prepare(folder: Path) -> None:
        source = COMPANIONS / "bag"
        for file in source.iterdir():
            if file.name != keep:
                shutil.copy(file, folder / file.name)
    return prepare


def _carmen(path: Path) -> object:
    from pppbot_bag.carmen import read_carmen
    return read_carmen(path)


TARGETS = {t.name: t for t in [
    Target("urdf", "robot.urdf", _urdf, "URDF (robot_description)"),
    Target("xacro", "robot.urdf.xacro", _xacro, "xacro"),
    Target("sdf", "world.sdf", _sdf, "SDF world (includes, <state>, plugins, lights)"),
    Target("stl", "mesh.stl", _mesh, "STL mesh"),
    Target("obj", "mesh.obj", _mesh, "OBJ mesh"),
    Target("dae", "mesh.dae", _mesh, "COLLADA mesh"),
    Target("map_yaml", "map.yaml", _map, "map YAML (with a valid PGM)", _map_companions),
    Target("map_pgm", "fuzz.pgm", _map_image, "map image, PGM", _map_image_yaml("fuzz.pgm")),
    Target("map_png", "fuzz.png", _map_image, "map image, PNG", _map_image_yaml("fuzz.png")),
    Target("params", "nav2_params.yaml", _params, "ROS 2 parameter file (Nav2's)"),
    Target("bag_metadata", "metadata.yaml", _bag, "rosbag2 metadata.yaml (with a valid MCAP)",
           _bag_companions("metadata.yaml")),
    Target("mcap", "bag_0.mcap", _bag, "rosbag2 MCAP file (with valid metadata)", _bag_companions("bag_0.mcap")),
    Target("carmen", "fuzz.log", _carmen, "CARMEN log"),
]}


def check_one(target: Target, folder: Path, data: bytes) -> str | None:
    """Write ``data`` as ``target``'s file in ``folder`` and parse it; the parser's message when
    it refused the file, None when it took it.

    Raises:
        Finding: the parser refused it without naming the file.
        Exception: anything but the parser's own error (what the fuzzer reports).
    """
    from pppbot_common.errors import PppbotError

    path = folder / target.file_name
    path.write_bytes(data)
    try:
        target.run(path)
    except PppbotError as exc:
        named = path.name if target.name not in ("bag_metadata", "mcap") else folder.name
        if named not in str(exc):
            raise Finding(f"{target.name}: the error does not name {named}: {exc}") from exc
        return str(exc)
    return None
