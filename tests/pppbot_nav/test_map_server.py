"""The ``map_server`` node over DDS: a Nav2 map file in, a latched ``/map``, ``~/map`` and ``~/load_map``."""
from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from nav2_msgs.srv import LoadMap
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from nav_msgs.srv import GetMap

from pppbot_bringup.run import find_executable
from pppbot_common.maps import OccupancyGrid, save_map
from pppbot_common.ros.qos import LATCHED
from pppbot_common.ros.wait import wait_for_messages, wait_until
from pppbot_nav.ros.map_server import MapLoadError, load_map_file, resolve_map_path

pytestmark = pytest.mark.ros

#: A 4 × 3 trinary map as Nav2's map_saver writes one (P5 PGM, top row first): free 254,
#: occupied 0, unknown 205, and the YAML with the thresholds it records.
NAV2_PIXELS = np.array([[0, 0, 0, 0],
                        [254, 254, 205, 0],
                        [254, 254, 254, 0]], dtype=np.uint8)
NAV2_YAML = """image: nav2.pgm
mode: trinary
resolution: 0.050
origin: [-0.100, 0.200, 0]
negate: 0
occupied_thresh: 0.65
free_thresh: 0.196

"""


def write_nav2_map(directory: Path) -> Path:
    height, width = NAV2_PIXELS.shape
    (directory / "nav2.pgm").write_bytes(b"P5\n# CREATOR: map_saver.cpp 0.050 m/pix\n%d %d\n255\n" % (width, height)
                                         + NAV2_PIXELS.tobytes())
    (directory / "nav2.yaml").write_text(NAV2_YAML)
    return directory / "nav2.yaml"


def test_names_resolve_in_the_working_directory_then_maps(tmp_path: Path, monkeypatch):
    monkeypatch.setenv("PPPBOT_ROOT", str(tmp_path / "checkout"))
    (tmp_path / "checkout" / "maps").mkdir(parents=True)
    (tmp_path / "checkout" / "config").mkdir()
    in_maps = write_nav2_map(tmp_path / "checkout" / "maps")
    monkeypatch.chdir(tmp_path)
    assert resolve_map_path("nav2") == in_maps and resolve_map_path("nav2.yaml") == in_maps
    assert resolve_map_path(f"file://{in_maps}") == in_maps
    (tmp_path / "nav2.yaml").write_text(NAV2_YAML)
    assert resolve_map_path("nav2.yaml") == Path("nav2.yaml")  # the working directory first
    with pytest.raises(MapLoadError, match="map file 'gone' not found") as missing:
        resolve_map_path("gone")
    assert missing.value.result == LoadMap.Response.RESULT_MAP_DOES_NOT_EXIST


@pytest.mark.parametrize("name", ["x" * 300, "a\0b", "~no_such_user_here/map", f"{'d/' * 3000}map"])
def test_names_no_file_can_have_are_not_found(name: str):
    with pytest.raises(MapLoadError, match="not found") as missing:
        resolve_map_path(name)
    assert missing.value.result == LoadMap.Response.RESULT_MAP_DOES_NOT_EXIST


def test_bad_files_get_nav2s_result_codes(tmp_path: Path):
    (tmp_path / "bad_yaml.yaml").write_text(NAV2_YAML.replace("resolution: 0.050", "resolution: -1"))
    with pytest.raises(MapLoadError, match="'resolution' must be positive") as metadata:
        load_map_file(str(tmp_path / "bad_yaml.yaml"))
    assert metadata.value.result == LoadMap.Response.RESULT_INVALID_MAP_METADATA
    (tmp_path / "bad_image.yaml").write_text(NAV2_YAML.replace("nav2.pgm", "bad_image.pgm"))
    (tmp_path / "bad_image.pgm").write_bytes(b"not an image")
    with pytest.raises(MapLoadError, match="not a readable image") as data:
        load_map_file(str(tmp_path / "bad_image.yaml"))
    assert data.value.result == LoadMap.Response.RESULT_INVALID_MAP_DATA


def start_server(spawn: Any, *params: str) -> tuple[Any, Any]:
    """map_server, and a lifecycle manager that brings it up (as lifecycle_manager_localization does)."""
    ros_args = [a for p in params for a in ("-p", p)]
    server = spawn([str(find_executable("pppbot_nav", "map_server")), "--ros-args", *ros_args], name="map_server",
                   env={**os.environ})
    manager = spawn([str(find_executable("pppbot_nav", "lifecycle_manager")), "--ros-args",
                     "-p", "node_names:=[map_server]", "-p", "autostart:=true"], name="lifecycle_manager",
                    env={**os.environ})
    return server, manager


def call(node: Any, kind: Any, name: str, request: Any) -> Any:
    client = node.create_client(kind, name)
    try:
        wait_until(client.service_is_ready, 20, f"service {name}", node=node)
        future = client.call_async(request)
        return wait_until(future.result, 20, f"a reply from {name}", node=node)
    finally:
        node.destroy_client(client)


def test_serves_a_nav2_map_latched_and_switches_maps(ros_node, spawn, tmp_path: Path):
    nav2 = write_nav2_map(tmp_path)
    server, _ = start_server(spawn, f"yaml_filename:={nav2}", "frame_id:=world")
    server.wait_for_output(r"serving .*nav2.yaml on /map: 4 x 3 cells of 0.05 m, origin \(-0.1, 0.2, 0\)", 30)
    (msg,) = wait_for_messages(ros_node, OccupancyGridMsg, "/map", qos=LATCHED, timeout_s=10)
    assert msg.header.frame_id == "world"
    assert (msg.info.width, msg.info.height) == (4, 3) and msg.info.resolution == pytest.approx(0.05)
    assert (msg.info.origin.position.x, msg.info.origin.position.y) == pytest.approx((-0.1, 0.2))
    # Rows from the bottom, as the message stores them: the image's last row first.
    assert list(msg.data) == [0, 0, 0, 100,  0, 0, -1, 100,  100, 100, 100, 100]
    assert list(call(ros_node, GetMap, "/map_server/map", GetMap.Request()).map.data) == list(msg.data)

    # Another map by ~/load_map: published and returned; a bad one keeps the current map.
    save_map(OccupancyGrid(np.zeros((5, 7), dtype=np.int8), 0.1, (0.0, 0.0, 0.0)), tmp_path / "other")
    reply = call(ros_node, LoadMap, "/map_server/load_map", LoadMap.Request(map_url=str(tmp_path / "other.yaml")))
    assert reply.result == LoadMap.Response.RESULT_SUCCESS and (reply.map.info.width, reply.map.info.height) == (7, 5)
    (switched,) = wait_for_messages(ros_node, OccupancyGridMsg, "/map", qos=LATCHED, timeout_s=10,
                                    predicate=lambda m: m.info.width == 7)
    assert switched.header.frame_id == "world"
    reply = call(ros_node, LoadMap, "/map_server/load_map", LoadMap.Request(map_url=str(tmp_path / "none.yaml")))
    assert reply.result == LoadMap.Response.RESULT_MAP_DOES_NOT_EXIST
    server.wait_for_output(r"load_map: map file '.*none.yaml' not found .*; still serving the previous map", 10)
    assert call(ros_node, GetMap, "/map_server/map", GetMap.Request()).map.info.width == 7


def test_a_missing_map_fails_its_configure_naming_it_and_the_bringup_stops(spawn, tmp_path: Path):
    server, manager = start_server(spawn, f"yaml_filename:={tmp_path / 'absent.yaml'}")
    manager.wait_for_output(r"Failed to bring up all requested nodes\. Aborting bringup\.", 60)
    assert "Failed to change state for node: map_server (configure left it unconfigured)" in manager.output
    server.wait_for_output(f"failed to configure: map file '{tmp_path / 'absent.yaml'}' not found", 10)
    assert server.running()  # unconfigured, as Nav2's: a manager or `ros2 lifecycle set` may try again
