"""``pppbot view``: the live view without a simulator, beside ``pppbot bag play``: it hears
publishers that offer less than it asks for (best effort, volatile, as a bag recorded without
QoS plays), and time going back (``--loop``) starts a new recording in the view; and a saved
recording served as it was. What the server streams is read back by rerun's own CLI."""
from __future__ import annotations

import json
import os
import re
import subprocess
import time
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np
import pytest
import rerun as rr
from pppbot_viz.errors import VizError
from pppbot_viz.ros.view_cli import check_recording
from pppbot_viz.viewer import available_port, free_port, listening, rerun_binary, viewer_environment

from pppbot_common.process import StopTimeouts, listening_addresses, process_tree, stop_process_group
from pppbot_viz import viewer

PPPBOT = str(Path(__file__).resolve().parents[2] / "pppbot")


def test_a_file_that_is_not_a_recording_is_named(tmp_path: Path) -> None:
    bad = tmp_path / "map.yaml"
    bad.write_text("image: map.pgm\n")
    with pytest.raises(VizError, match=f"{bad}: not a rerun recording"):
        check_recording(bad)
    with pytest.raises(VizError, match="missing.rrd: can't read it"):
        check_recording(tmp_path / "missing.rrd")
    with pytest.raises(VizError, match="--port 70000: must be a port number"):
        available_port(70000, "--port ")


def test_rerun_settings_are_written_whole_and_only_when_they_differ(tmp_path: Path) -> None:
    """Launches (parallel test workers) share one settings file: it is replaced in one step, never
    truncated under a rerun reading it, and left alone when it already says the same."""
    written = viewer.write_viewer_settings(tmp_path)
    assert json.loads(written.read_text())["analytics_enabled"] is False
    os.utime(written, ns=(0, 0))
    assert viewer.write_viewer_settings(tmp_path) == written and written.stat().st_mtime_ns == 0  # the same: untouched
    written.write_text("{}")
    viewer.write_viewer_settings(tmp_path)
    assert json.loads(written.read_text())["analytics_enabled"] is False
    assert [p.name for p in written.parent.iterdir()] == ["analytics.json"]  # no part file left


def grpc_of(page_url: str) -> str:
    """The rerun server the page connects to (its settings carry the URL)."""
    with urllib.request.urlopen(page_url, timeout=10) as response:
        page = response.read().decode()
    found = re.search(r"rerun\+http://127\.0\.0\.1:\d+/proxy", page)
    assert found, page[:500]
    return found.group(0)


def saved_stream(grpc_url: str, out: Path, seconds: float) -> Path:
    """What the server streams to a new client within ``seconds``, saved by rerun's CLI."""
    env = {**os.environ, **viewer_environment(out.parent / "rerun"), "RUST_LOG": "warn"}
    saver = subprocess.Popen([str(rerun_binary()), grpc_url, "--save", str(out), "--bind", "127.0.0.1",
                              "--port", str(free_port())], env=env, stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        time.sleep(seconds)
    finally:
        stop_process_group(saver, StopTimeouts(10.0, 5.0))
    return out


def recordings_in(printed: str) -> set[str]:
    """The recordings (not layouts) in ``rerun rrd print``'s output, by id."""
    return set(re.findall(r'StoreId\(\s*Recording,\s*"pppbot",\s*"([^"]+)"', printed))


def bag_without_qos(path: Path, seconds: float = 3.0) -> None:
    """An MCAP bag of /scan (10 Hz) and /map (1 Hz) as another tool writes it, with no offered
    QoS: ``bag play`` offers such topics best effort and volatile."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    LaserScan, OccupancyGrid = store.types["sensor_msgs/msg/LaserScan"], store.types["nav_msgs/msg/OccupancyGrid"]
    Header, Time = store.types["std_msgs/msg/Header"], store.types["builtin_interfaces/msg/Time"]
    MapMetaData, Pose = store.types["nav_msgs/msg/MapMetaData"], store.types["geometry_msgs/msg/Pose"]
    Point, Quaternion = store.types["geometry_msgs/msg/Point"], store.types["geometry_msgs/msg/Quaternion"]
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        scans = writer.add_connection("/scan", LaserScan.__msgtype__, typestore=store)
        maps = writer.add_connection("/map", OccupancyGrid.__msgtype__, typestore=store)
        for i in range(int(seconds * 10)):
            t_ns = 100_000_000_000 + i * 100_000_000
            stamp = Time(sec=t_ns // 10**9, nanosec=t_ns % 10**9)
            header = Header(stamp=stamp, frame_id="lidar_frame")
            scan = LaserScan(header=header, angle_min=-1.0, angle_max=1.0, angle_increment=1.0, time_increment=0.0,
                             scan_time=0.1, range_min=0.1, range_max=12.0, ranges=np.array([1.0, 2.0, 3.0], np.float32),
                             intensities=np.zeros(0, np.float32))
            writer.write(scans, t_ns, store.serialize_cdr(scan, LaserScan.__msgtype__))
            if i % 10 == 0:
                origin = Pose(position=Point(x=0.0, y=0.0, z=0.0), orientation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0))
                info = MapMetaData(map_load_time=stamp, resolution=0.5, width=4, height=3, origin=origin)
                grid = OccupancyGrid(header=Header(stamp=stamp, frame_id="map"), info=info,
                                     data=np.array([0, 100, -1, 0] * 3, np.int8))
                writer.write(maps, t_ns, store.serialize_cdr(grid, OccupancyGrid.__msgtype__))


@pytest.mark.ros
def test_view_of_a_bag_played_in_a_loop_hears_it_and_starts_over_when_its_time_goes_back(
        spawn, tmp_path: Path, rerun_cli, rrd_chunks) -> None:
    bag = tmp_path / "other_tool_bag"
    bag_without_qos(bag)
    view = spawn([PPPBOT, "view", "--viewer", "web", "--port", "0"], name="view")
    page_url = view.wait_for_output(r"live view: (http://127\.0\.0\.1:\d+/)", 60).group(1)
    spawn([PPPBOT, "bag", "play", str(bag), "--loop", "--clock"], name="bag_play")
    # /map is latched for the view; the bag offers it best effort and volatile: the view follows
    view.wait_for_output(r"/map: subscribed best_effort and volatile, as its publishers offer", 30)
    view.wait_for_output(r"time went back from 10\d\.\d s to 100\.\d s: a new recording in the view", 30)
    stream = saved_stream(grpc_of(page_url), tmp_path / "stream.rrd", 8.0)
    assert len(recordings_in(rerun_cli("rrd", "print", str(stream)))) >= 2
    chunks = rrd_chunks(stream)
    assert chunks.get("/map", 0) >= 1 and chunks.get("/scan", 0) >= 1, chunks


@pytest.mark.ros
def test_a_saved_recording_is_served_as_it_was(spawn, tmp_path: Path, rerun_cli, rrd_chunks) -> None:
    recording = tmp_path / "view.rrd"
    rec = rr.RecordingStream("pppbot")
    rec.save(str(recording))
    rec.set_time("sim_time", duration=5.0)
    rec.log("scan", rr.Points3D([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0]]))
    rec.flush()
    rec.disconnect()
    view = spawn([PPPBOT, "view", str(recording), "--viewer", "web", "--port", "0"], name="view")
    page_url = view.wait_for_output(r"view\.rrd: open (http://127\.0\.0\.1:\d+/) in a browser", 60).group(1)
    copy = saved_stream(grpc_of(page_url), tmp_path / "copy.rrd", 5.0)
    copied = recordings_in(rerun_cli("rrd", "print", str(copy)))
    assert copied == recordings_in(rerun_cli("rrd", "print", str(recording))) and len(copied) == 1
    assert rrd_chunks(copy).get("/scan") == 1
    # A recording has no robot behind it: the page refuses a pose, saying why.
    request = urllib.request.Request(page_url + "pose", data=b'{"kind": "goal", "from": [0, 0], "to": [1, 0]}',
                                     headers={"Content-Type": "application/json", "Origin": page_url.rstrip("/")})
    try:
        with urllib.request.urlopen(request, timeout=10) as response:
            answer = response.read().decode()
    except urllib.error.HTTPError as refused:
        answer = refused.read().decode()
    assert '"ok": false' in answer and "a recording has no robot behind it" in answer
    # The page and rerun's server listen on 127.0.0.1 only.
    grpc_port = int(grpc_of(page_url).rsplit(":", 1)[1].removesuffix("/proxy"))
    bound = listening_addresses(process_tree(view.pid))
    assert {("127.0.0.1", int(page_url.rsplit(":", 1)[1].strip("/"))), ("127.0.0.1", grpc_port)} <= set(bound)
    assert [address for address in bound if address[0] != "127.0.0.1"] == []
    # Stopped as a launch or a test stops it (SIGINT, then SIGTERM and SIGKILL 5 s apart), the view
    # takes rerun's server with it: no server is left listening.
    assert view.stop() == 0
    assert not listening(grpc_port)
