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
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped, Twist
from nav_msgs.msg import Odometry
from PIL import Image
from pppbot_viz.headless import chromium_page, wait_for, wait_for_view_time

from pppbot_common.ros.wait import wait_until
from pppbot_common.se2 import yaw_from_quaternion
from pppbot_viz import headless as tools

PPPBOT = str(Path(__file__).resolve().parents[2] / "pppbot")
SIZE = (1000, 700)
#: the top-down map view: the layout's left column (3 of 5 shares), below pppbot's toolbar (36 px),
#: rerun's (35) and the view's title (28), above the collapsed time panel (37)
MAP_VIEW = (0, 99, int(SIZE[0] * 0.6) - 2, SIZE[1] - 37)

#: the radius of a scan point in the view (m; pppbot_viz.ros.convert.scan)
SCAN_POINT_M = 0.03
#: the mouse wheel zooms the top-down view in this many steps of this many pixels (about 4x)
ZOOM_STEPS, ZOOM_STEP_PX = 3, 100

pytestmark = [pytest.mark.ros, pytest.mark.heavy]


def map_view(page: Any) -> np.ndarray:
    """The top-down view as the page shows it: (height, width, 3) RGB."""
    x0, y0, x1, y1 = MAP_VIEW
    shot = Image.open(io.BytesIO(page.screenshot(clip={"x": x0, "y": y0, "width": x1 - x0, "height": y1 - y0})))
    return np.asarray(shot.convert("RGB")).astype(int)


def free_pixels(page: Any) -> int:
    """White pixels (free cells in RViz's map colours) in the top-down view."""
    return int(np.all(map_view(page) >= 245, axis=2).sum())


def scan_to_wall_px(rgb: np.ndarray, point_px: float) -> np.ndarray:
    """For each pixel of the scan (RViz's red points, ``point_px`` in radius), how far (px) the
    nearest occupied map cell (black) is on screen: where the map lies under the scan, a cell
    or less from a point's edge. The robot's lidar (a red disk, far wider than a point) is left
    out."""
    from scipy import ndimage
    red = (rgb[..., 0] > 170) & (rgb[..., 1] < 80) & (rgb[..., 2] < 80)
    radius = int(math.ceil(point_px)) + 1
    disk = np.hypot(*np.mgrid[-radius:radius + 1, -radius:radius + 1]) <= radius
    wide = ndimage.binary_dilation(ndimage.binary_opening(red, structure=disk), structure=disk, iterations=2)
    red &= ~wide
    black = np.all(rgb < 40, axis=2)
    assert red.sum() > 20 and black.sum() > 20, f"{red.sum()} scan and {black.sum()} wall pixels on screen"
    return ndimage.distance_transform_edt(~black)[red]


def metres_per_pixel(page: Any, center: tuple[float, float], apart_px: float = 160.0) -> float:
    """The view's scale: two clicks ``apart_px`` apart, where the viewer says they hit the map."""
    hits = []
    for dx in (-apart_px / 2, apart_px / 2):
        page.evaluate("window.pppbot.selected = null")
        page.mouse.click(center[0] + dx, center[1])
        hits.append(wait_for(page, "window.pppbot.selected", 20, "the viewer to report a click"))
    page.keyboard.press("Escape")  # nothing stays selected (a selection tints what it selects)
    return math.dist(hits[0][:2], hits[1][:2]) / apart_px


def camera_view(page: Any) -> tuple[float, float]:
    """Shares of the camera view (the right column's tenths 5-7, below its title; the SLAM health under it) that are sky
    (black: nothing hit) and ground (MuJoCo's grey plane): what ppp_bot's camera sees in the cones
    world. An empty view is the page's plain background."""
    x0, x1, height = int(SIZE[0] * 0.6) + 2, SIZE[0], MAP_VIEW[3] - MAP_VIEW[1]
    y0, y1 = MAP_VIEW[1] + height * 4 // 10 + 28, MAP_VIEW[1] + height * 7 // 10
    shot = Image.open(io.BytesIO(page.screenshot(clip={"x": x0, "y": y0, "width": x1 - x0, "height": y1 - y0})))
    rgb = np.asarray(shot.convert("RGB")).astype(int)
    grey = (np.ptp(rgb, axis=2) < 12) & (rgb.mean(axis=2) > 100) & (rgb.mean(axis=2) < 220)
    black = np.all(rgb < 25, axis=2)
    return float(black.mean()), float(grey.mean())


def health_text_share(page: Any, save: Path) -> float:
    """The share of the SLAM health panel (the right column's last three tenths, below its title) that is
    text (light on the panel's dark background); the panel's picture is saved at ``save``."""
    x0, height = int(SIZE[0] * 0.6) + 2, MAP_VIEW[3] - MAP_VIEW[1]
    y0 = MAP_VIEW[1] + height * 7 // 10 + 28
    shot = page.screenshot(clip={"x": x0, "y": y0, "width": SIZE[0] - x0, "height": MAP_VIEW[3] - y0})
    save.write_bytes(shot)
    rgb = np.asarray(Image.open(io.BytesIO(shot)).convert("RGB")).astype(int)
    return float((rgb.mean(axis=2) > 120).mean())


def view_center() -> tuple[float, float]:
    x0, y0, x1, y1 = MAP_VIEW
    return (x0 + x1) / 2, (y0 + y1) / 2


def test_live_view_in_a_browser(ros_node, spawn, tmp_path):
    launch = spawn([PPPBOT, "launch_sim", "world:=cones", "use_teleop:=false", "use_rviz:=false",
                    "viz_port:=0", "viz_viewer:=web"], name="launch_sim")
    url = launch.wait_for_output(r"live view: (http://127\.0\.0\.1:\d+/)", 120).group(1)
    launch.wait_for_output(r"\[viz-1\]: ready", 30)
    odometry: list[Odometry] = []
    ros_node.create_subscription(Odometry, "/odom", odometry.append, 10)
    drive = ros_node.create_publisher(Twist, "/cmd_vel_teleop", 10)

    with chromium_page(spawn, tmp_path / "profile", SIZE) as browser:
        page = browser.page
        page.goto(url)
        wait_for(page, "window.pppbot && window.pppbot.started", 90, "the viewer to start")
        # Live: the view's time follows the simulation's (time_update events from the viewer).
        wait_for_view_time(page, 0.0, 120, 240, "the view's first data")
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
        # The view follows at its own pace: without a GPU, it has frames of many seconds now and then.
        wait_for_view_time(page, driven_until, 60, 400, "the view to show the new map")
        time.sleep(2.0)
        after = free_pixels(page)
        assert after > 1.5 * before + 2000, f"free cells on screen: {before} before driving, {after} after"
        # The map lies under the scan: seen closer (the wheel zooms in on the map's origin), every
        # cone's red arc sits on its black cells, within a cell (the map is no longer drawn
        # upside down: then the arcs were about 1 m from their cones).
        assert_map_under_scan(page, tmp_path)
        # What the robot sees: the simulator renders ppp_bot's camera for the view, in its camera panel.
        assert "showing camera images of /camera/image_raw" in launch.output  # once the page's viewer is here
        # and all along: the page says it is open even while its viewer is busy with a long frame
        assert "no viewer open" not in launch.output
        sky, ground = camera_view(page)
        assert sky > 0.1 and ground > 0.1, f"camera view: {sky:.0%} sky, {ground:.0%} ground"
        # The SLAM node's health (/diagnostics) in its panel: text, not an empty panel.
        assert health_text_share(page, tmp_path / "health.png") > 0.005

        # RViz's tools: a button, then the position and a point in the heading.
        assert_pose_tools(page, ros_node)
        # Nothing beyond this machine: the viewer's update check and usage reports are blocked (a
        # blob: URL is the page's own worker).
        assert browser.requests and all(re.match(r"(blob:)?http://127\.0\.0\.1:\d+/", u) for u in browser.requests), \
            sorted({u for u in browser.requests if "127.0.0.1" not in u})

    os.kill(launch.pid, signal.SIGINT)
    assert launch.wait(30) == 0
    for node in ("rerun", "viz"):
        assert re.search(rf"\[{node}-1\]: process has finished cleanly", launch.output), node


def assert_map_under_scan(page: Any, tmp_path: Path) -> None:
    """Zoomed in on the map's origin, the scan's points lie on the map's occupied cells, within a
    cell; then the view is zoomed out again."""
    page.mouse.move(*view_center())
    for _ in range(ZOOM_STEPS):
        page.mouse.wheel(0, -ZOOM_STEP_PX)
        time.sleep(0.3)
    page.mouse.move(SIZE[0] - 10, 10)  # off the view: a hovered thing shows a tooltip and a tint
    time.sleep(3.0)
    zoomed = map_view(page)
    Image.fromarray(zoomed.astype(np.uint8)).save(tmp_path / "zoomed.png")  # to look at when it fails
    metres_px = metres_per_pixel(page, view_center())
    cell_px, point_px = 0.05 / metres_px, SCAN_POINT_M / metres_px
    assert cell_px > 2.0, f"zoomed in to {cell_px:.1f} px a cell"
    distances = scan_to_wall_px(zoomed, point_px) - point_px  # from a point's edge
    assert np.median(distances) <= cell_px and np.mean(distances <= 2 * cell_px) > 0.8, \
        f"scan to map: median {np.median(distances):.1f} px, {np.mean(distances <= 2 * cell_px):.0%} within " \
        f"two cells ({cell_px:.1f} px a cell)"
    page.mouse.move(*view_center())
    for _ in range(ZOOM_STEPS):  # back to the whole map
        page.mouse.wheel(0, ZOOM_STEP_PX)
        time.sleep(0.3)


def assert_pose_tools(page: Any, ros_node: Any) -> None:
    """RViz's 2D Goal Pose and 2D Pose Estimate, used as a user does, publish what was clicked."""
    goals: list[PoseStamped] = []
    initial_poses: list[PoseWithCovarianceStamped] = []
    ros_node.create_subscription(PoseStamped, "/goal_pose", goals.append, 10)
    ros_node.create_subscription(PoseWithCovarianceStamped, "/initialpose", initial_poses.append, 10)
    cx, cy = view_center()
    set_pose(page, "#goal", (cx, cy), (cx + 120, cy))  # heading +x (the view's right)
    goal = wait_until(lambda: goals[-1] if goals else None, 30, "/goal_pose", node=ros_node)
    assert goal.header.frame_id == "map"
    # The view looks down on the map's origin (the spawn pose): its centre is near (0, 0).
    assert math.hypot(goal.pose.position.x, goal.pose.position.y) < 1.0, goal.pose.position
    o = goal.pose.orientation
    assert abs(yaw_from_quaternion(o.x, o.y, o.z, o.w)) < 0.3
    set_pose(page, "#initial", (cx, cy), (cx, cy - 120))  # heading +y (the view's up)
    initial = wait_until(lambda: initial_poses[-1] if initial_poses else None, 30, "/initialpose", node=ros_node)
    o = initial.pose.pose.orientation
    assert abs(yaw_from_quaternion(o.x, o.y, o.z, o.w) - math.pi / 2) < 0.3
    assert initial.pose.covariance[0] == pytest.approx(0.25) and initial.pose.covariance[35] > 0
    posted = page.evaluate("window.pppbot.posted")
    assert [p["ok"] for p in posted] == [True, True]
    assert posted[0]["message"].startswith("goal sent: x ")


def set_pose(page: Any, button: str, position: tuple[float, float], heading: tuple[float, float]) -> None:
    """A pose tool used as a user does, until the page has posted the pose."""
    posted = len(page.evaluate("window.pppbot.posted"))
    tools.set_pose(page, button, position, heading)
    wait_for(page, f"window.pppbot.posted.length > {posted}", 20, "the pose to be posted")
