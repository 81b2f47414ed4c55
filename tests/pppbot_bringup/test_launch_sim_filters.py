"""launch_sim's costmap filters: ``keepout_mask:=`` and ``speed_mask:=`` start Nav2's mask and
filter-info servers and put Nav2's filters in the costmaps (planned, nothing started)."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest
import yaml

from pppbot_common.launch_args import ArgumentError

sys.path.insert(0, str(Path(__file__).parent))
from test_launch_sim import fake_plan  # noqa: E402


def write_mask(folder: Path, name: str) -> Path:
    (folder / f"{name}.pgm").write_bytes(b"P5\n4 4\n255\n" + bytes(16))
    path = folder / f"{name}.yaml"
    path.write_text(f"image: {name}.pgm\nmode: raw\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n"
                    "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
    return path


def test_masks_start_the_filter_servers_and_put_nav2s_filters_in_the_costmaps(tmp_path):
    keepout, speed = write_mask(tmp_path, "keepout"), write_mask(tmp_path, "speed")
    p, _ = fake_plan("world:=maze", "localization:=true", f"keepout_mask:={keepout}", f"speed_mask:={speed}")
    by_name = {n.name: n for n in p.nodes}
    filters = " ".join(by_name["costmap_filters"].cmd)
    assert filters.startswith("/bin/pppbot_nav/costmap_filters --keepout --speed ")
    assert f"keepout_filter_mask_server:yaml_filename:={keepout}" in filters
    assert "speed_costmap_filter_info_server:filter_info_topic:=speed_costmap_filter_info" in filters
    assert by_name["costmap_filters"].required and by_name["costmap_filters"].after == ("localization",)
    params_file = Path(by_name["navigation"].cmd[by_name["navigation"].cmd.index("--params-file") + 1])
    assert params_file.parent == Path("/tmp")  # beside the robot description, never in the checkout
    document = yaml.safe_load(p.files[params_file])
    glob = document["global_costmap"]["global_costmap"]["ros__parameters"]
    local = document["local_costmap"]["local_costmap"]["ros__parameters"]
    assert glob["filters"] == ["keepout_filter", "keepout_inflation", "speed_filter"]
    assert local["filters"] == ["keepout_filter", "keepout_inflation"]
    assert glob["keepout_filter"] == {"plugin": "nav2_costmap_2d::KeepoutFilter", "enabled": True,
                                      "filter_info_topic": "keepout_costmap_filter_info"}
    # The zone is inflated as the costmap's own inflation layer inflates.
    assert glob["keepout_inflation"]["inflation_radius"] == glob["inflation_layer"]["inflation_radius"]
    assert glob["speed_filter"]["plugin"] == "nav2_costmap_2d::SpeedFilter"


def test_a_params_files_own_filter_is_enabled_and_keeps_its_info_topic(tmp_path):
    from pppbot_bringup.filter_masks import with_filters

    params: dict = {"global_costmap": {"global_costmap": {"ros__parameters": {
        "filters": ["zones"], "zones": {"plugin": "nav2_costmap_2d/KeepoutFilter", "enabled": False,
                                        "filter_info_topic": "/my_info"}}}}}
    setup = with_filters(params, ["keepout"])
    inner = setup.document["global_costmap"]["global_costmap"]["ros__parameters"]
    assert inner["zones"]["enabled"] is True and inner["filters"][0] == "zones"
    assert params["global_costmap"]["global_costmap"]["ros__parameters"]["zones"]["enabled"] is False  # a copy
    assert setup.info_topics == {"keepout": "/my_info"}
    params["local_costmap"] = {"local_costmap": {"ros__parameters": {
        "filters": ["k"], "k": {"plugin": "nav2_costmap_2d::KeepoutFilter", "filter_info_topic": "/other"}}}}
    with pytest.raises(ValueError, match="different info topics"):
        with_filters(params, ["keepout"])


def test_a_mask_needs_navigation_and_a_readable_map_file(tmp_path):
    with pytest.raises(ArgumentError, match="need navigation"):
        fake_plan("world:=maze", f"keepout_mask:={write_mask(tmp_path, 'k')}")
    with pytest.raises(ArgumentError, match="speed_mask:=.*nowhere.yaml"):
        fake_plan("world:=maze", "localization:=true", f"speed_mask:={tmp_path / 'nowhere.yaml'}")
