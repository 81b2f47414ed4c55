"""Nav2's costmap filters in the room: a keepout zone across the way and a speed zone round the
start, each a mask map served by ``launch_sim keepout_mask:=… speed_mask:=…`` (map_servers and
costmap_filter_info_servers), read by the costmaps' KeepoutFilter and SpeedFilter; the robot is
judged on ground truth.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from action_msgs.msg import GoalStatus
from geometry_msgs.msg import Twist
from nav2_msgs.action import NavigateToPose
from nav2_msgs.msg import SpeedLimit
from nav_msgs.msg import OccupancyGrid, Odometry
from nav_msgs.msg import Path as PathMsg
from PIL import Image
from rclpy.action import ActionClient

from pppbot_common.ros.qos import LATCHED
from pppbot_common.ros.wait import send_goal, wait_until

ROOT = Path(__file__).resolve().parents[2]
PPPBOT = str(ROOT / "pppbot")

KEEPOUT = (0.6, 0.9, -0.8, 1.2)  # x0, x1, y0, y1 (m, map): across the way from (0, 0) to the goal
SPEED = (-0.6, 0.6, -0.6, 0.6)  # round the start: value 70, a limit of 100 - 70 = 30 %
GOAL = (1.5, 0.5)
TOP_SPEED = 0.5  # config/nav2_params.yaml's RPP desired_linear_vel


def write_mask(folder: Path, name: str, zone: tuple[float, float, float, float], value: int) -> Path:
    """A raw-mode mask with the room map's geometry: ``value`` inside ``zone``, 0 elsewhere."""
    room = yaml.safe_load((ROOT / "maps" / "room.yaml").read_text())
    width, height = Image.open(ROOT / "maps" / room["image"]).size
    res, (ox, oy, _) = room["resolution"], room["origin"]
    pixels = np.zeros((height, width), dtype=np.uint8)
    x0, x1, y0, y1 = zone
    c0, c1 = round((x0 - ox) / res), round((x1 - ox) / res)
    r0, r1 = round((y0 - oy) / res), round((y1 - oy) / res)
    pixels[height - r1:height - r0, c0:c1] = value  # image rows run down from the top
    Image.fromarray(pixels).save(folder / f"{name}.pgm")
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump({"image": f"{name}.pgm", "mode": "raw", "resolution": res,
                                    "origin": room["origin"], "negate": 0, "occupied_thresh": 0.65,
                                    "free_thresh": 0.196}))
    return path


def inside(zone: tuple[float, float, float, float], x: float, y: float, margin: float = 0.0) -> bool:
    x0, x1, y0, y1 = zone
    return x0 + margin < x < x1 - margin and y0 + margin < y < y1 - margin


@pytest.mark.ros
@pytest.mark.heavy
def test_the_robot_keeps_out_of_a_keepout_zone_and_slows_in_a_speed_zone(ros_node: Any, spawn: Any,
                                                                          tmp_path: Path) -> None:
    keepout = write_mask(tmp_path, "keepout", KEEPOUT, 100)
    speed = write_mask(tmp_path, "speed", SPEED, 70)
    launch = spawn([PPPBOT, "launch_sim", "world:=room", "localization:=true", f"keepout_mask:={keepout}",
                    f"speed_mask:={speed}", "use_teleop:=false", "use_rviz:=false", "use_viz:=false",
                    "lockstep:=true", "real_time_factor:=1.0"], name="launch_sim")
    launch.wait_for_output(r"ppp_bot is up in 'room'", 120)
    truths: list[Odometry] = []
    commands: list[tuple[float, Odometry | None]] = []
    limits: list[SpeedLimit] = []
    plans: list[PathMsg] = []
    costmaps: dict[str, OccupancyGrid] = {}
    ros_node.create_subscription(Odometry, "/ground_truth/odom", truths.append, 10)
    ros_node.create_subscription(Twist, "/cmd_vel_nav", lambda m: commands.append(
        (m.linear.x, truths[-1] if truths else None)), 10)
    ros_node.create_subscription(SpeedLimit, "/speed_limit", limits.append, 10)
    ros_node.create_subscription(PathMsg, "/plan", plans.append, 10)
    ros_node.create_subscription(OccupancyGrid, "/global_costmap/costmap",
                                 lambda m: costmaps.__setitem__("global", m), LATCHED)
    client = ActionClient(ros_node, NavigateToPose, "navigate_to_pose")
    assert client.wait_for_server(timeout_sec=30)

    # The global costmap has the zone as lethal (100 in OccupancyGrid terms), inflated round it.
    def zone_in_costmap() -> bool:
        grid = costmaps.get("global")
        return grid is not None and cell(grid, 0.75, 0.2) == 100
    wait_until(zone_in_costmap, 60, "the keepout zone in the global costmap", node=ros_node)
    grid = costmaps["global"]
    assert cell(grid, 0.75, -0.7) == 100 and cell(grid, 0.75, 1.1) == 100
    assert 0 < cell(grid, 0.75, 1.3) < 100 and cell(grid, -0.3, 0.2) == 0

    goal = NavigateToPose.Goal()
    goal.pose.header.frame_id = "map"
    goal.pose.pose.position.x, goal.pose.pose.position.y = GOAL
    goal.pose.pose.orientation.w = 1.0
    handle = send_goal(client, goal, ros_node)
    assert handle.accepted
    done = handle.get_result_async()
    wait_until(done.done, 240, "the goal's result", node=ros_node)
    assert done.result().status == GoalStatus.STATUS_SUCCEEDED, done.result().result.error_msg

    # Keepout: no plan crosses the zone and the robot never entered it (on ground truth).
    assert plans
    for plan in plans:
        assert not any(inside(KEEPOUT, p.pose.position.x, p.pose.position.y) for p in plan.poses)
    positions = [(t.pose.pose.position.x, t.pose.pose.position.y) for t in truths]
    assert not any(inside(KEEPOUT, x, y) for x, y in positions)
    x, y = positions[-1]
    assert math.hypot(x - GOAL[0], y - GOAL[1]) < 0.35
    # Speed: inside the zone (well inside: the limit follows the costmap's updates) the controller
    # asks for at most 30 % of its top speed, and the robot drives no faster; out of it, faster.
    within = [v for v, t in commands if t is not None and inside(SPEED, t.pose.pose.position.x,
                                                                 t.pose.pose.position.y, margin=0.15)]
    assert within and max(within) > 0.1  # it did drive in the zone
    assert max(abs(v) for v in within) <= 0.3 * TOP_SPEED + 1e-6
    # On ground truth: the distance covered in each half second there (a wheel's contact transient
    # is no speed).
    stamps = np.array([t.header.stamp.sec + t.header.stamp.nanosec * 1e-9 for t in truths])
    xy = np.array(positions)
    speeds = []
    for i, t0 in enumerate(stamps):
        j = int(np.searchsorted(stamps, t0 + 0.5))
        if j < len(stamps) and inside(SPEED, xy[i][0], xy[i][1], 0.15) and inside(SPEED, xy[j][0], xy[j][1], 0.15):
            speeds.append(float(np.linalg.norm(xy[j] - xy[i]) / (stamps[j] - t0)))
    assert speeds and max(speeds) <= 0.3 * TOP_SPEED * 1.05
    assert max(abs(v) for v, t in commands) > 0.3 * TOP_SPEED * 1.5
    # Leaving the zone lifted the limit (Nav2's 0: none).
    assert any(m.speed_limit == 0.0 for m in limits)


def cell(grid: OccupancyGrid, x: float, y: float) -> int:
    col = int((x - grid.info.origin.position.x) / grid.info.resolution)
    row = int((y - grid.info.origin.position.y) / grid.info.resolution)
    return int(grid.data[row * grid.info.width + col])
