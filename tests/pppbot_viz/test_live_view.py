"""The live view end to end: ``launch_sim`` mapping with the view on, its page in a real headless
Chromium. The map area grows on screen as the robot maps, the page's 2D Goal Pose and 2D Pose
Estimate tools publish ``/goal_pose`` and ``/initialpose`` in ``map``, the page asks nothing of
any host but 127.0.0.1, and the launch stops every process of the view cleanly."""
from __future__ import annotations

import io
import math
import os
import re
import signal
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from browser import chromium_page, wait_for
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped, Twist
from nav_msgs.msg import Odometry
from PIL import Image

from pppbot_common.ros.wait import wait_until
from pppbot_common.se2 import yaw_from_quaternion

PPPBOT = str(Path(__file__).resolve().parents[2] / "pppbot")
SIZE = (1000, 700)
#: the top-down map view: the layout's left column (3 of 5 shares), below pppbot's toolbar (36 px),
#: rerun's (35) and the view's title (28), above the collapsed time panel (37)
MAP_VIEW = (0, 99, int(SIZE[0] * 0.6) - 2, SIZE[1] - 37)

pytestmark = pytest.mark.ros


def free_pixels(page: Any) -> int:
    """White pixels (free cells in RViz's map colours) in the top-down view."""
    x0, y0, x1, y1 = MAP_VIEW
    shot = Image.open(io.BytesIO(page.screenshot(clip={"x": x0, "y": y0, "width": x1 - x0, "height": y1 - y0})))
    rgb = np.asarray(shot.convert("RGB"))
    return int(np.all(rgb >= 245, axis=2).sum())


def camera_view(page: Any) -> tuple[float, float]:
    """Shares of the camera view (the right column's lower third, below its title) that are sky
    (black: nothing hit) and ground (MuJoCo's grey plane): what ppp_bot's camera sees in the cones
    world. An empty view is the page's plain background."""
    x0, x1, y1 = int(SIZE[0] * 0.6) + 2, SIZE[0], MAP_VIEW[3]
    y0 = MAP_VIEW[1] + (MAP_VIEW[3] - MAP_VIEW[1]) * 2 // 3 + 28
    shot = Image.open(io.BytesIO(page.screenshot(clip={"x": x0, "y": y0, "width": x1 - x0, "height": y1 - y0})))
    rgb = np.asarray(shot.convert("RGB")).astype(int)
    grey = (np.ptp(rgb, axis=2) < 12) & (rgb.mean(axis=2) > 100) & (rgb.mean(axis=2) < 220)
    black = np.all(rgb < 25, axis=2)
    return float(black.mean()), float(grey.mean())


def view_center() -> tuple[float, float]:
    x0, y0, x1, y1 = MAP_VIEW
    return (x0 + x1) / 2, (y0 + y1) / 2


def test_live_view_in_a_browser(ros_node, spawn, tmp_path):
    launch = spawn([PPPBOT, "launch_sim", "world:=cones", "use_teleop:=false", "use_rviz:=false",
                    "viz_port:=0", "viz_viewer:=web"], name="launch_sim")
    url = launch.wait_for_output(r"live view: (http://127\.0\.0\.1:\d+/)", 120).group(1)
    launch.wait_for_output(r"\[viz-1\]: ready", 30)
    odometry: list[Odometry] = []
    goals: list[PoseStamped] = []
    initial_poses: list[PoseWithCovarianceStamped] = []
    ros_node.create_subscription(Odometry, "/odom", odometry.append, 10)
    ros_node.create_subscription(PoseStamped, "/goal_pose", goals.append, 10)
    ros_node.create_subscription(PoseWithCovarianceStamped, "/initialpose", initial_poses.append, 10)
    drive = ros_node.create_publisher(Twist, "/cmd_vel_teleop", 10)

    with chromium_page(spawn, tmp_path / "profile", SIZE) as browser:
        page = browser.page
        page.goto(url)
        wait_for(page, "window.pppbot && window.pppbot.started", 90, "the viewer to start")
        # Live: the view's time follows the simulation's (time_update events from the viewer).
        wait_for(page, "window.pppbot.time !== null", 60, "the view's first data")
        time.sleep(3.0)
        before = free_pixels(page)

        # Map: drive a circle; the map's free area grows on screen.
        wait_until(lambda: odometry, 30, "/odom", node=ros_node)
        start = odometry[-1].header.stamp.sec
        turn = Twist()
        turn.linear.x, turn.angular.z = 0.3, 0.3
        wait_until(lambda: (drive.publish(turn), odometry[-1].header.stamp.sec - start >= 20)[1], 120,
                   "20 s of driving", node=ros_node)
        drive.publish(Twist())
        driven_until = odometry[-1].header.stamp.sec + 6  # SLAM publishes its map every 5 s
        wait_until(lambda: odometry[-1].header.stamp.sec >= driven_until, 60, "the next map", node=ros_node)
        wait_for(page, f"window.pppbot.time >= {driven_until * 1e9}", 90, "the view to show the new map")
        time.sleep(2.0)
        after = free_pixels(page)
        assert after > 1.5 * before + 2000, f"free cells on screen: {before} before driving, {after} after"
        # What the robot sees: the simulator renders ppp_bot's camera for the view, in its camera panel.
        assert "showing camera images of /camera/image_raw" in launch.output
        sky, ground = camera_view(page)
        assert sky > 0.1 and ground > 0.1, f"camera view: {sky:.0%} sky, {ground:.0%} ground"

        # RViz's tools: a button, then the position and a point in the heading.
        cx, cy = view_center()
        set_pose(page, "#goal", (cx, cy), (cx + 120, cy))  # heading +x (the view's right)
        goal = wait_until(lambda: goals[-1] if goals else None, 30, "/goal_pose", node=ros_node)
        assert goal.header.frame_id == "map"
        # The view looks down on the map's origin (the spawn pose): its centre is near (0, 0).
        assert math.hypot(goal.pose.position.x, goal.pose.position.y) < 1.0, goal.pose.position
        o = goal.pose.orientation
        assert abs(yaw_from_quaternion(o.x, o.y, o.z, o.w)) < 0.3
        set_pose(page, "#initial", (cx, cy), (cx, cy - 120))  # heading +y (the view's up)
        initial = wait_until(lambda: initial_poses[-1] if initial_poses else None, 30, "/initialpose",
                             node=ros_node)
        o = initial.pose.pose.orientation
        assert abs(yaw_from_quaternion(o.x, o.y, o.z, o.w) - math.pi / 2) < 0.3
        assert initial.pose.covariance[0] == pytest.approx(0.25) and initial.pose.covariance[35] > 0
        posted = page.evaluate("window.pppbot.posted")
        assert [p["ok"] for p in posted] == [True, True]
        assert posted[0]["message"].startswith("goal sent: x ")
        # Nothing beyond this machine: the viewer's update check and usage reports are blocked.
        assert browser.requests and all(re.match(r"http://127\.0\.0\.1:\d+/", u) for u in browser.requests), \
            sorted({u for u in browser.requests if "127.0.0.1" not in u})

    os.kill(launch.pid, signal.SIGINT)
    assert launch.wait(30) == 0
    for node in ("rerun", "viz"):
        assert re.search(rf"\[{node}-1\]: process has finished cleanly", launch.output), node


def set_pose(page: Any, button: str, position: tuple[float, float], heading: tuple[float, float]) -> None:
    posted = len(page.evaluate("window.pppbot.posted"))
    page.click(button)
    page.mouse.click(*position)
    wait_for(page, "document.getElementById('status').textContent.includes('heading')", 20,
             "the tool to take its first click")
    page.mouse.click(*heading)
    wait_for(page, f"window.pppbot.posted.length > {posted}", 20, "the pose to be posted")
