"""The ``map_saver`` node over DDS: nav2_msgs/srv/SaveMap requests in, Nav2 map files out."""
from __future__ import annotations

import os
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from nav2_msgs.srv import LoadMap, SaveMap

from pppbot_bringup.run import find_executable
from pppbot_common.errors import TimeoutExpired
from pppbot_common.ros.wait import wait_until

pytestmark = pytest.mark.ros

SERVICE = "/map_saver/save_map"


@pytest.fixture
def start_saver(spawn, tmp_path: Path):
    """Start the installed executable (what ``pppbot run pppbot_nav map_saver`` runs) with parameters,
    in a stand-in checkout (its maps/ is where an empty map_url saves); wait until it is ready."""
    def start(*params: str) -> Any:
        (tmp_path / "checkout" / "config").mkdir(parents=True, exist_ok=True)
        env = {**os.environ, "PPPBOT_ROOT": str(tmp_path / "checkout")}
        ros_args = [a for p in params for a in ("-p", p)]
        saver = spawn([str(find_executable("pppbot_nav", "map_saver")), "--ros-args", *ros_args],
                      name="map_saver", env=env)
        saver.wait_for_output(r"ready: /map_saver/save_map", 30)
        return saver
    return start


def save(node: Any, timeout_s: float = 10, attempts: int = 3, **fields: Any) -> bool:
    """Call save_map; the request again when no reply came within ``timeout_s``. A client is
    "ready" once DDS matched its requests to the server; on a loaded machine the replies' side
    can match later, and a reply sent before it is lost (a request is safe to repeat)."""
    client = node.create_client(SaveMap, SERVICE)
    try:
        wait_until(client.service_is_ready, 20, f"service {SERVICE}", node=node)
        for attempt in range(attempts):
            future = client.call_async(SaveMap.Request(**fields))
            try:
                return wait_until(future.result, timeout_s, f"a reply from {SERVICE}", node=node).result
            except TimeoutExpired:
                if attempt == attempts - 1:
                    raise
        raise AssertionError("unreachable")
    finally:
        node.destroy_client(client)


def test_interfaces_are_jazzys():
    """nav2_msgs 1.3 (Jazzy): SaveMap and LoadMap field for field."""
    assert SaveMap.Request.get_fields_and_field_types() == {
        "map_topic": "string", "map_url": "string", "image_format": "string", "map_mode": "string",
        "free_thresh": "float", "occupied_thresh": "float"}
    assert SaveMap.Response.get_fields_and_field_types() == {"result": "boolean"}
    assert LoadMap.Request.get_fields_and_field_types() == {"map_url": "string"}
    assert LoadMap.Response.get_fields_and_field_types() == {"map": "nav_msgs/OccupancyGrid", "result": "uint8"}
    assert (LoadMap.Response.RESULT_SUCCESS, LoadMap.Response.RESULT_MAP_DOES_NOT_EXIST,
            LoadMap.Response.RESULT_INVALID_MAP_DATA, LoadMap.Response.RESULT_INVALID_MAP_METADATA,
            LoadMap.Response.RESULT_UNDEFINED_FAILURE) == (0, 1, 2, 3, 255)


def test_saves_with_the_requests_url_format_mode_and_thresholds(ros_node, publish_map, start_saver, read_saved,
                                                                 tmp_path: Path):
    publish_map(topic="/slam_map")
    saver = start_saver()
    assert save(ros_node, map_topic="/slam_map", map_url=str(tmp_path / "scaled"), image_format="png",
                map_mode="scale", free_thresh=0.2, occupied_thresh=0.7)
    saved = read_saved(tmp_path / "scaled.yaml")
    # float32 request fields, written as the decimals that were asked for
    assert saved.meta == {"image": "scaled.png", "mode": "scale", "resolution": 0.1, "origin": [-1.5, 2.0, 0.0],
                          "negate": 0, "occupied_thresh": 0.7, "free_thresh": 0.2}
    assert saved.image_mode == "LA" and saved.grey(2, 3) == 127 and saved.alpha(4, 6) == 0
    assert save(ros_node, map_topic="slam_map", map_url=str(tmp_path / "binary.yaml"), image_format="BMP",
                map_mode="trinary", free_thresh=0.35, occupied_thresh=0.45)
    saved = read_saved(tmp_path / "binary.yaml")
    assert saved.meta["image"] == "binary.bmp" and saved.image_format == "BMP"
    assert [saved.grey(1, 1), saved.grey(2, 3), saved.grey(3, 4), saved.grey(4, 6)] == [254, 0, 205, 205]
    saver.wait_for_output(r"saved .*binary\.yaml and binary\.bmp: 7 x 5 cells of 0\.1 m", 5)


def test_empty_and_zero_fields_take_nav2s_defaults(ros_node, publish_map, start_saver, read_saved, tmp_path: Path):
    publish_map()  # on /map, the default map_topic
    start_saver("free_thresh_default:=0.35", "occupied_thresh_default:=0.45")
    before = int(time.time())
    assert save(ros_node)  # every field empty or zero
    (yaml_path,) = (tmp_path / "checkout" / "maps").glob("map_*.yaml")
    assert before <= int(yaml_path.stem.removeprefix("map_")) <= time.time()  # maps/map_<unix time>, as Nav2 names it
    saved = read_saved(yaml_path)
    assert (saved.meta["mode"], saved.meta["image"], saved.image_format) == ("trinary", f"{yaml_path.stem}.pgm", "PPM")
    # the node's threshold defaults classify: 30 <= 35 free, 50 >= 45 occupied
    assert [saved.grey(1, 1), saved.grey(2, 3)] == [254, 0]
    assert save(ros_node, map_url=str(tmp_path / "s"), map_mode="scale")  # scale without a format: png
    assert read_saved(tmp_path / "s.yaml").meta["image"] == "s.png"


def test_no_map_within_the_timeout_is_a_failed_save(ros_node, start_saver, tmp_path: Path):
    saver = start_saver("save_map_timeout:=1.0")
    start = time.monotonic()
    assert not save(ros_node, map_topic="/nobody_publishes_this", map_url=str(tmp_path / "out" / "m"))
    assert time.monotonic() - start < 15
    saver.wait_for_output(r"no map on '/nobody_publishes_this' within 1 s: nothing saved", 5)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("fields, logged", [
    ({"map_mode": "fancy"}, r"map mode 'fancy' is not one of trinary, scale, raw"),
    ({"image_format": "jpg"}, r"image format 'jpg' is not supported"),
    ({"free_thresh": 0.5, "occupied_thresh": 0.4}, r"thresholds need 0 <= free \(0\.5\) < occupied \(0\.4\)"),
    ({"map_topic": "bad topic"}, r"map_topic 'bad topic': Invalid topic name"),
])
def test_bad_requests_fail_and_write_nothing(ros_node, publish_map, start_saver, tmp_path: Path, fields, logged):
    publish_map()
    saver = start_saver()
    assert not save(ros_node, map_url=str(tmp_path / "out" / "m"), **fields)
    saver.wait_for_output(logged, 5)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("param, message", [
    ("save_map_timeout:=0.0", "parameter 'save_map_timeout' = 0.0: must be a finite number in (0.0, 3600.0]"),
    ("free_thresh_default:=0.7", "parameter 'free_thresh_default' = 0.7: must be below occupied_thresh_default"),
    ("map_subscribe_transient_local:=3", "parameter 'map_subscribe_transient_local' = 3: must be true or false"),
])
def test_bad_parameters_stop_the_node_naming_them(spawn, param, message):
    saver = spawn([sys.executable, "-m", "pppbot_nav.ros.map_saver", "--ros-args", "-p", param], name="map_saver")
    assert saver.wait(30) == 1
    assert f"[map_saver] error: {message}" in saver.output


def test_a_malformed_map_is_not_saved(ros_node, publish_map, start_saver, tmp_path: Path):
    published = publish_map(topic="/broken_map")
    published.message.info.width = 8  # 8 × 5 cells announced, 7 × 5 sent
    published.again()
    saver = start_saver()
    assert not save(ros_node, map_topic="/broken_map", map_url=str(tmp_path / "out" / "m"))
    saver.wait_for_output(r"could not save the map to .*m\.yaml: map data has 35 cells, not width × height = 40", 5)
    assert not (tmp_path / "out").exists()


def test_runtime_parameter_updates_are_validated(ros_node, start_saver):
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import SetParameters

    start_saver()
    client = ros_node.create_client(SetParameters, "/map_saver/set_parameters")
    wait_until(client.service_is_ready, 20, "the parameter service", node=ros_node)

    def set_double(name: str, value: float) -> Any:
        value_msg = ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value)
        future = client.call_async(SetParameters.Request(parameters=[Parameter(name=name, value=value_msg)]))
        return wait_until(future.result, 20, "a reply", node=ros_node).results[0]

    refused = set_double("free_thresh_default", 0.9)
    assert not refused.successful
    assert refused.reason == "parameter 'free_thresh_default' = 0.9: must be below occupied_thresh_default (0.65)"
    assert set_double("free_thresh_default", 0.3).successful
