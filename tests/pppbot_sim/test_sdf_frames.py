"""SDF 1.7 frame semantics: <frame> with attached_to, relative_to on links, collisions, models,
includes and joints, __model__, empty poses, nested models; cycles and unknown frames named by
file and line. Positions worked out by hand from the SDF specification (sdformat.org, "Pose
frame semantics")."""
from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest

from pppbot_sim.errors import WorldError
from pppbot_sim.sdf_frames import FrameGraph
from pppbot_sim.sdf_world import read_sdf_world

ROOM = """<?xml version="1.0"?><sdf version="1.7"><model name="room"><static>true</static><link name="wall">
  <collision name="c"><geometry><box><size>1 1 1</size></box></geometry></collision></link></model></sdf>"""
BOX = "<geometry><box><size>0.1 0.1 0.1</size></box></geometry>"


def world(tmp_path: Path, body: str) -> Path:
    (tmp_path / "models" / "room").mkdir(parents=True, exist_ok=True)
    (tmp_path / "models" / "room" / "model.sdf").write_text(ROOM)
    path = tmp_path / "frames.sdf"
    path.write_text('<?xml version="1.0"?>\n<sdf version="1.7"><world name="w">\n' + textwrap.dedent(body)
                    + "\n</world></sdf>\n")
    return path


def positions(path: Path) -> dict[str, list[float]]:
    loaded = read_sdf_world(path)
    return {s.name: [round(float(v), 9) for v in s.pose[:3, 3]] for s in loaded.static_shapes}


def test_frames_relative_to_and_empty_poses_in_a_model(tmp_path: Path) -> None:
    # The model frame at (10, 0, 0) turned 90° about z: its x axis is the world's y.
    found = positions(world(tmp_path, f"""\
        <model name="m"><static>true</static><pose>10 0 0 0 0 1.5707963267948966</pose>
          <frame name="F"><pose>1 0 0 0 0 0</pose></frame>
          <link name="L"><pose relative_to="F">0 2 0 0 0 0</pose>
            <collision name="at_link">{BOX}</collision>
            <collision name="at_model"><pose relative_to="__model__">0 0 1 0 0 0</pose>{BOX}</collision>
            <collision name="at_frame"><pose relative_to="F"/>{BOX}</collision>
            <collision name="at_joint"><pose relative_to="J">0.5 0 0 0 0 0</pose>{BOX}</collision>
          </link>
          <joint name="J" type="fixed"><parent>world</parent><child>L</child><pose>0 0 1 0 0 0</pose></joint>
          <model name="N"><pose relative_to="F">0 0 0 0 0 1.5707963267948966</pose>
            <link name="k"><collision name="c"><pose>1 0 0 0 0 0</pose>{BOX}</collision></link>
          </model>
        </model>"""))
    # F: model (1, 0, 0) → world (10, 1, 0). L: F + (0, 2, 0) = model (1, 2, 0) → world (8, 1, 0).
    assert found["m::L::at_link"] == [8.0, 1.0, 0.0]
    assert found["m::L::at_model"] == [10.0, 0.0, 1.0]
    assert found["m::L::at_frame"] == [10.0, 1.0, 0.0]
    # J: L + (0, 0, 1) (a joint's pose is in its child's frame); then 0.5 along J's x (the world's y)
    assert found["m::L::at_joint"] == [8.0, 1.5, 1.0]
    # N: at F, turned another 90°: its x axis is the world's -x; k's collision 1 m along it
    assert found["m::N::k::c"] == [9.0, 1.0, 0.0]


def test_world_frames_and_includes_relative_to_them(tmp_path: Path) -> None:
    found = positions(world(tmp_path, """\
        <frame name="corner"><pose>5 5 0 0 0 0</pose></frame>
        <frame name="beside" attached_to="corner"><pose>0 1 0 0 0 0</pose></frame>
        <include><uri>model://room</uri><name>room_a</name><pose relative_to="corner">1 0 0 0 0 0</pose></include>
        <include><uri>model://room</uri><name>room_b</name><pose relative_to="beside"/></include>"""))
    assert found["room_a::wall::c"] == [6.0, 5.0, 0.0]
    assert found["room_b::wall::c"] == [5.0, 6.0, 0.0]  # attached_to is also the default relative_to


def test_a_cycle_and_an_unknown_frame_are_named_with_file_and_line(tmp_path: Path) -> None:
    cycle = world(tmp_path, f"""\
        <model name="m"><static>true</static>
          <frame name="A"><pose relative_to="B">1 0 0 0 0 0</pose></frame>
          <frame name="B"><pose relative_to="A">1 0 0 0 0 0</pose></frame>
          <link name="L"><pose relative_to="A"/><collision name="c">{BOX}</collision></link>
        </model>""")
    with pytest.raises(WorldError, match=rf"{cycle}:4: the poses of model 'm' form a cycle: A → B → A"):
        read_sdf_world(cycle)
    unknown = world(tmp_path, f"""\
        <model name="m"><static>true</static>
          <link name="L"><collision name="c"><pose relative_to="nope">0 0 0 0 0 0</pose>{BOX}</collision></link>
        </model>""")
    message = rf"{unknown}:4: there is no frame 'nope' in model 'm' \(frames: L, __model__\)"
    with pytest.raises(WorldError, match=message):
        read_sdf_world(unknown)
    twice = world(tmp_path, f"""\
        <model name="m"><static>true</static>
          <frame name="L"/><link name="L"><collision name="c">{BOX}</collision></link>
        </model>""")
    with pytest.raises(WorldError, match="the frame name 'L' is used twice in model 'm'"):
        read_sdf_world(twice)


def test_frame_graph_resolves_chains_once() -> None:
    graph = FrameGraph("__model__", "model 'm'")
    step = np.eye(4)
    step[0, 3] = 1.0
    graph.add("a", "__model__", step, Path("m.sdf"), 1)
    graph.add("b", "a", step, Path("m.sdf"), 2)
    graph.add("c", "b", step, Path("m.sdf"), 3)
    assert graph.resolve("c")[0, 3] == 3.0 and graph.resolve("b")[0, 3] == 2.0
    with pytest.raises(WorldError, match="reserved"):
        graph.add("__model__x__", "a", step, Path("m.sdf"), 4)
