"""The costmap node's observation buffer: scans are applied when the layers update, as Nav2's
ObservationBuffer (``observation_persistence`` 0: the newest scan only)."""
from __future__ import annotations

import math
from collections.abc import Iterator

import pytest
import rclpy
from rclpy.parameter import Parameter
from rclpy.time import Time
from sensor_msgs.msg import LaserScan

from pppbot_nav.costmap.costs import FREE_SPACE, LETHAL_OBSTACLE, NO_INFORMATION
from pppbot_nav.ros.costmap_node import CostmapNode

pytestmark = pytest.mark.ros


@pytest.fixture
def context() -> Iterator[None]:
    rclpy.init()
    try:
        yield
    finally:
        rclpy.shutdown()


def local_costmap(persistence: float) -> CostmapNode:
    """A 4 × 4 m rolling window of an obstacle layer alone, its robot at the origin of 'odom'."""
    node = CostmapNode("local_costmap", parameter_overrides=[
        Parameter("global_frame", value="odom"), Parameter("rolling_window", value=True),
        Parameter("width", value=4), Parameter("height", value=4), Parameter("plugins", value=["obstacle_layer"]),
        Parameter("obstacle_layer.scan.observation_persistence", value=persistence)])
    for child in ("base_link", "lidar"):
        node.tf.set_transform("odom", child, 0.0, (0.0, 0.0, 0.0), True)
    return node


def scan(stamp_s: float, wall_at_m: float | None) -> LaserScan:
    """One beam straight ahead: a return at ``wall_at_m``, or none."""
    msg = LaserScan()
    msg.header.frame_id = "lidar"
    msg.header.stamp = Time(seconds=stamp_s).to_msg()
    msg.angle_min, msg.angle_increment, msg.range_min, msg.range_max = 0.0, 0.01, 0.1, 10.0
    msg.ranges = [math.inf if wall_at_m is None else wall_at_m]
    return msg


def cost(node: CostmapNode, x: float) -> int:
    assert node.costmap is not None
    return int(node.costmap.cost_at(x, 0.0, NO_INFORMATION)[()])


def test_only_the_newest_scan_is_applied_at_an_update_by_default(context: None) -> None:
    node = local_costmap(persistence=0.0)
    try:
        node._on_scan(scan(1.0, 1.0))  # a wall at 1 m, then gone before the layers update
        node._on_scan(scan(1.1, 1.5))
        node.update()
        assert cost(node, 1.52) == LETHAL_OBSTACLE
        assert cost(node, 1.02) == FREE_SPACE  # the older scan was never marked: the newer clears through
        node.update()  # nothing new: the same costmap
        assert cost(node, 1.52) == LETHAL_OBSTACLE
        node._on_scan(scan(1.2, None))
        node.update()
        assert cost(node, 1.52) == FREE_SPACE  # the wall went away
    finally:
        node.destroy_node()


def test_scans_within_observation_persistence_are_all_applied(context: None) -> None:
    node = local_costmap(persistence=0.5)
    try:
        node._on_scan(scan(1.0, 1.5))
        node._on_scan(scan(1.1, 1.0))  # nearer: it hides the first wall, which stays marked
        node.update()
        assert cost(node, 1.02) == LETHAL_OBSTACLE and cost(node, 1.52) == LETHAL_OBSTACLE
        node._on_scan(scan(1.7, 1.0))  # the scan at 1.0 s is now older than 0.5 s: no longer applied
        node._on_scan(scan(1.8, None))
        node.update()
        assert cost(node, 1.02) == FREE_SPACE
    finally:
        node.destroy_node()


def test_a_bad_observation_persistence_is_refused_with_its_name(context: None) -> None:
    with pytest.raises(Exception, match="observation_persistence"):
        local_costmap(persistence=-1.0)


def test_get_costmap_answers_the_master_grid_with_nav2s_costs(context: None) -> None:
    from nav2_msgs.srv import GetCostmap

    node = local_costmap(persistence=0.0)
    try:
        empty = node._get_costmap(GetCostmap.Request(), GetCostmap.Response())
        assert empty.map.metadata.size_x == 0  # nothing yet: an empty costmap
        node._on_scan(scan(1.0, 1.5))
        node.update()
        answer = node._get_costmap(GetCostmap.Request(), GetCostmap.Response()).map
        meta = answer.metadata
        assert answer.header.frame_id == "odom" and meta.layer == "master"
        assert (meta.size_x, meta.size_y) == (80, 80) and meta.resolution == pytest.approx(0.05)
        assert (meta.origin.position.x, meta.origin.position.y) == pytest.approx((-2.0, -2.0))
        # Row-major from cell (0, 0): the wall 1.5 m ahead of the robot at the window's centre.
        col = int((1.52 - meta.origin.position.x) / meta.resolution)
        row = int(-meta.origin.position.y / meta.resolution)
        assert answer.data[row * meta.size_x + col] == LETHAL_OBSTACLE
        assert answer.data[row * meta.size_x + col - 10] == FREE_SPACE
        assert len(answer.data) == 80 * 80
    finally:
        node.destroy_node()


def test_clear_around_and_clear_except_forget_a_square_around_the_robot(context: None) -> None:
    from nav2_msgs.srv import ClearCostmapAroundRobot, ClearCostmapExceptRegion

    node = local_costmap(persistence=0.0)
    try:
        node._on_scan(scan(1.0, 1.5))  # a wall 1.5 m ahead
        node.update()
        around = ClearCostmapAroundRobot.Request(reset_distance=2.0)  # a 2 m square: the wall is outside it
        node._clear_around(around, ClearCostmapAroundRobot.Response())
        assert cost(node, 1.52) == LETHAL_OBSTACLE and cost(node, 0.5) == NO_INFORMATION
        node._clear_around(ClearCostmapAroundRobot.Request(reset_distance=3.2), ClearCostmapAroundRobot.Response())
        assert cost(node, 1.52) == NO_INFORMATION  # inside the 3.2 m square now: forgotten
        node._on_scan(scan(1.1, 1.5))
        node.update()
        assert cost(node, 1.52) == LETHAL_OBSTACLE and cost(node, 1.0) == FREE_SPACE
        node._clear_except(ClearCostmapExceptRegion.Request(reset_distance=2.4), ClearCostmapExceptRegion.Response())
        assert cost(node, 1.52) == NO_INFORMATION and cost(node, 1.0) == FREE_SPACE  # outside forgotten, inside kept
        assert not node.clear_square(math.nan, inside=True)  # a bad distance is refused
    finally:
        node.destroy_node()
