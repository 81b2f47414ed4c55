"""The example plugin package (``examples/pppbot_example_plugins``), installed from outside the
project's packages, drives goals: its planner, DWB critic and behaviour-tree node are found by
the type names a params file gives them, through their entry points, as pluginlib finds a
Nav2 user's.

The package is pip-installed into a folder of the test's own (a copy of its sources, so the
checkout is left as it is) and that folder put on ``PYTHONPATH``, as a user's workspace is.
"""
from __future__ import annotations

import math
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from action_msgs.msg import GoalStatus
from nav2_msgs.action import NavigateToPose
from nav_msgs.msg import Odometry
from nav_msgs.msg import Path as PathMsg
from rclpy.action import ActionClient

from pppbot_common.ros.wait import send_goal, wait_until

ROOT = Path(__file__).resolve().parents[2]
PPPBOT = str(ROOT / "pppbot")
EXAMPLE = ROOT / "examples" / "pppbot_example_plugins"

#: pppbot's navigate_to_pose tree with the example's condition in front: a goal the robot stands on fails.
TREE = """<root BTCPP_format="4" main_tree_to_execute="MainTree">
  <BehaviorTree ID="MainTree">
    <Sequence>
      <GoalFartherThan goal="{goal}" distance="0.4"/>
      <PipelineSequence>
        <RateController hz="1.0">
          <ComputePathToPose goal="{goal}" path="{path}" planner_id="GridBased"/>
        </RateController>
        <FollowPath path="{path}" controller_id="FollowPath"/>
      </PipelineSequence>
    </Sequence>
  </BehaviorTree>
</root>
"""


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder holding the installed example package (its dist-info with the entry points)."""
    work = tmp_path_factory.mktemp("example_plugins")
    source = work / "source"
    shutil.copytree(EXAMPLE, source, ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"))
    target = work / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation",
                    "--no-index", "--target", str(target), str(source)], check=True, capture_output=True)
    return target


def with_site(site: Path) -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(site), env.get("PYTHONPATH", "")]))
    return env


def run_python(site: Path, code: str) -> str:
    done = subprocess.run([sys.executable, "-c", code], env=with_site(site), capture_output=True, text=True,
                          check=False)
    assert done.returncode == 0, done.stderr
    return done.stdout


def test_the_installed_package_is_found_by_type_name_and_its_planner_cuts_corners(site: Path) -> None:
    out = run_python(site, """
import json
import numpy as np
from pppbot_nav.plugins import plugins
from pppbot_nav.costmap.grid import Costmap
from pppbot_nav.ros.navigator import plugin_nodes
planner_type = plugins("planner")["pppbot_example_plugins/ShortcutPlanner"]   # either spelling
params = planner_type(line_of_sight_cost=128)
params.validate()
planner = params.make()
costs = np.zeros((60, 60), dtype=np.uint8)
costs[0:40, 28:32] = 254                                                       # a wall from the bottom
costmap = Costmap(costs, 0.05, (0.0, 0.0))
planner.set_costmap(costmap)
plan = planner.plan((0.5, 0.5), (2.5, 0.5))
critic = plugins("DWB critic")["pppbot_example_plugins::Clearance"]().make("Clearance")
print(json.dumps({"points": plan.points_xy.tolist(), "critic": type(critic).__name__,
                  "nodes": sorted(plugin_nodes(["pppbot_example_bt_nodes", "nav2_spin_action_bt_node"])),
                  "planners": list(plugins("planner"))}))
""")
    import json

    found = json.loads(out.strip().splitlines()[-1])
    points = np.array(found["points"])
    assert found["critic"] == "Clearance" and found["nodes"] == ["GoalFartherThan"]
    assert "pppbot_example_plugins::ShortcutPlanner" in found["planners"]
    assert "nav2_navfn_planner::NavfnPlanner" in found["planners"]  # pppbot's own, registered alike
    assert np.allclose(points[0], (0.5, 0.5), atol=0.05) and np.allclose(points[-1], (2.5, 0.5), atol=0.05)
    # Round the wall's top (y = 2.0 m) and never through it (x 1.4-1.6 m below 2.0 m).
    assert points[:, 1].max() > 2.0
    through = (points[:, 0] > 1.38) & (points[:, 0] < 1.62) & (points[:, 1] < 1.9)
    assert not through.any()
    # Any-angle: straight legs whose headings are not all multiples of 45° (the grid's).
    d = np.diff(points, axis=0)
    headings = np.degrees(np.arctan2(d[:, 1], d[:, 0]))
    assert np.any(np.abs((headings + 22.5) % 45.0 - 22.5) > 5.0)
    length = np.linalg.norm(d, axis=1).sum()
    assert length < 5.0  # up 1.5 m, over, down: a grid path with its 45° zig-zags is longer


def test_an_unknown_type_names_its_group_and_what_is_installed(site: Path) -> None:
    out = run_python(site, """
from pppbot_nav.plugins import PluginError, plugins
try:
    plugins("DWB critic")["pppbot_example_plugins::NoSuchCritic"]
except PluginError as exc:
    print(exc)
""")
    installed = out.partition("installed: ")[2].rstrip(")\n").split(", ")
    assert "'pppbot_nav.dwb_critics'" in out and "pppbot_example_plugins::Clearance" in installed
    assert "dwb_critics::PathDistCritic" in installed  # DWB's own are registered the same way


def params_with_examples(folder: Path) -> Path:
    params = yaml.safe_load((ROOT / "config" / "nav2_params.yaml").read_text())
    planner = params["planner_server"]["ros__parameters"]
    planner["GridBased"] = {"plugin": "pppbot_example_plugins::ShortcutPlanner", "line_of_sight_cost": 100}
    controller = params["controller_server"]["ros__parameters"]
    dwb = yaml.safe_load((ROOT / "tests" / "data" / "ppp_bot" / "nav2_params.yaml").read_text())
    follow = dwb["controller_server"]["ros__parameters"]["FollowPath"]
    follow["critics"] = [*follow["critics"], "Clearance"]
    follow["Clearance.scale"] = 0.05
    controller["FollowPath"] = follow
    tree = folder / "with_goal_distance.xml"
    tree.write_text(TREE)
    navigator = params["bt_navigator"]["ros__parameters"]
    navigator["plugin_lib_names"] = ["pppbot_example_bt_nodes"]
    navigator["default_nav_to_pose_bt_xml"] = str(tree)
    path = folder / "nav2_params.yaml"
    path.write_text(yaml.safe_dump(params, sort_keys=False))
    return path


@pytest.mark.ros
@pytest.mark.heavy
def test_a_goal_runs_through_the_examples_planner_critic_and_tree_node(ros_node: Any, spawn: Any, site: Path,
                                                                       tmp_path: Path) -> None:
    params = params_with_examples(tmp_path)
    launch = spawn([PPPBOT, "launch_sim", "world:=room", "localization:=true", f"params_file:={params}",
                    "use_teleop:=false", "use_rviz:=false", "use_viz:=false", "lockstep:=true",
                    "real_time_factor:=1.0"], name="launch_sim", env=with_site(site))
    launch.wait_for_output(r"ppp_bot is up in 'room'", 120)
    assert "pppbot_example_plugins::ShortcutPlanner" in launch.output
    truths: list[Odometry] = []
    plans: list[PathMsg] = []
    ros_node.create_subscription(Odometry, "/ground_truth/odom", truths.append, 10)
    ros_node.create_subscription(PathMsg, "/plan", plans.append, 10)
    client = ActionClient(ros_node, NavigateToPose, "navigate_to_pose")
    assert client.wait_for_server(timeout_sec=30)

    status, result = goal(ros_node, client, 1.5, 0.5)
    assert status == GoalStatus.STATUS_SUCCEEDED, result.error_msg
    x, y = truths[-1].pose.pose.position.x, truths[-1].pose.pose.position.y
    assert math.hypot(x - 1.5, y - 0.5) < 0.35
    assert plans, "no plan published"
    # The plan is the example planner's: resampled straight legs about a cell apart, not a smoothed curve.
    xy = np.array([(p.pose.position.x, p.pose.position.y) for p in plans[0].poses])
    d = np.diff(xy, axis=0)
    turns = np.abs(np.diff(np.arctan2(d[:, 1], d[:, 0])))
    assert np.count_nonzero(turns > 1e-3) <= 6

    # The robot stands on the goal: the example's GoalFartherThan fails the tree before any plan.
    plans.clear()
    status, result = goal(ros_node, client, x, y)
    assert status == GoalStatus.STATUS_ABORTED
    assert not plans


def goal(node: Any, client: Any, x: float, y: float) -> tuple[int, Any]:
    msg = NavigateToPose.Goal()
    msg.pose.header.frame_id = "map"
    msg.pose.pose.position.x, msg.pose.pose.position.y = x, y
    msg.pose.pose.orientation.w = 1.0
    handle = send_goal(client, msg, node)
    assert handle.accepted
    done = handle.get_result_async()
    wait_until(done.done, 180, "the goal's result", node=node)
    return done.result().status, done.result().result
