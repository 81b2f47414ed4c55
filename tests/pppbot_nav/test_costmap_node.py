"""The costmap node: its layers as Nav2's plugin types, its observation buffer (scans are applied
when the layers update, as Nav2's ObservationBuffer; ``observation_persistence`` 0: the newest scan
only) and its live parameters."""
from __future__ import annotations

import math
from collections.abc import Iterator

import pytest
import rclpy
from rclpy.parameter import Parameter
from rclpy.time import Time
from sensor_msgs.msg import LaserScan

from pppbot_common.params import ParameterError
from pppbot_nav.costmap.costs import FREE_SPACE, INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE, NO_INFORMATION
from pppbot_nav.costmap.layers import InflationLayer
from pppbot_nav.ros.costmap_node import CostmapNode

pytestmark = pytest.mark.ros


@pytest.fixture
def context() -> Iterator[None]:
    rclpy.init()
    try:
        yield
    finally:
        rclpy.shutdown()


def local_costmap(persistence: float, *extra: Parameter) -> CostmapNode:
    """A 4 × 4 m rolling window of an obstacle layer alone (its source ``scan`` marking and
    clearing, no-return beams too), its robot at the origin of 'odom'."""
    node = CostmapNode("local_costmap", parameter_overrides=[
        Parameter("global_frame", value="odom"), Parameter("rolling_window", value=True),
        Parameter("track_unknown_space", value=True), Parameter("robot_radius", value=0.3),
        Parameter("width", value=4), Parameter("height", value=4), Parameter("plugins", value=["obstacle_layer"]),
        Parameter("obstacle_layer.observation_sources", value="scan"),
        Parameter("obstacle_layer.scan.clearing", value=True),
        Parameter("obstacle_layer.scan.inf_is_valid", value=True),
        Parameter("obstacle_layer.scan.observation_persistence", value=persistence), *extra])
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
        node._on_scan(node.sources[0], scan(1.0, 1.0))  # a wall at 1 m, then gone before the layers update
        node._on_scan(node.sources[0], scan(1.1, 1.5))
        node.update()
        assert cost(node, 1.52) == LETHAL_OBSTACLE
        assert cost(node, 1.02) == FREE_SPACE  # the older scan was never marked: the newer clears through
        node.update()  # nothing new: the same costmap
        assert cost(node, 1.52) == LETHAL_OBSTACLE
        node._on_scan(node.sources[0], scan(1.2, None))
        node.update()
        assert cost(node, 1.52) == FREE_SPACE  # the wall went away
    finally:
        node.destroy_node()


def test_scans_within_observation_persistence_are_all_applied(context: None) -> None:
    node = local_costmap(persistence=0.5)
    try:
        node._on_scan(node.sources[0], scan(1.0, 1.5))
        node._on_scan(node.sources[0], scan(1.1, 1.0))  # nearer: it hides the first wall, which stays marked
        node.update()
        assert cost(node, 1.02) == LETHAL_OBSTACLE and cost(node, 1.52) == LETHAL_OBSTACLE
        node._on_scan(node.sources[0], scan(1.7, 1.0))  # the scan at 1.0 s is now older than 0.5 s: no longer applied
        node._on_scan(node.sources[0], scan(1.8, None))
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
        node._on_scan(node.sources[0], scan(1.0, 1.5))
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
        node._on_scan(node.sources[0], scan(1.0, 1.5))  # a wall 1.5 m ahead
        node.update()
        around = ClearCostmapAroundRobot.Request(reset_distance=2.0)  # a 2 m square: the wall is outside it
        node._clear_around(around, ClearCostmapAroundRobot.Response())
        assert cost(node, 1.52) == LETHAL_OBSTACLE and cost(node, 0.5) == NO_INFORMATION
        node._clear_around(ClearCostmapAroundRobot.Request(reset_distance=3.2), ClearCostmapAroundRobot.Response())
        assert cost(node, 1.52) == NO_INFORMATION  # inside the 3.2 m square now: forgotten
        node._on_scan(node.sources[0], scan(1.1, 1.5))
        node.update()
        assert cost(node, 1.52) == LETHAL_OBSTACLE and cost(node, 1.0) == FREE_SPACE
        node._clear_except(ClearCostmapExceptRegion.Request(reset_distance=2.4), ClearCostmapExceptRegion.Response())
        assert cost(node, 1.52) == NO_INFORMATION and cost(node, 1.0) == FREE_SPACE  # outside forgotten, inside kept
        assert not node.clear_square(math.nan, inside=True)  # a bad distance is refused
    finally:
        node.destroy_node()


def test_layers_are_nav2s_plugin_types_and_an_unknown_one_is_refused_with_the_known_ones(context: None) -> None:
    node = CostmapNode("local_costmap", parameter_overrides=[
        Parameter("global_frame", value="odom"), Parameter("rolling_window", value=True),
        Parameter("plugins", value=["my_lidar", "inflate"]),
        Parameter("my_lidar.plugin", value="nav2_costmap_2d/VoxelLayer"),  # pluginlib's other spelling
        Parameter("my_lidar.observation_sources", value="front back"),
        Parameter("my_lidar.front.topic", value="/front_scan"),
        Parameter("my_lidar.front.obstacle_max_range", value=4.5),
        Parameter("inflate.plugin", value="nav2_costmap_2d::InflationLayer")])
    try:
        assert [type(layer).__name__ for layer in node.layers] == ["ObstacleLayer", "InflationLayer"]
        assert node.layers[0].plugin == "nav2_costmap_2d::VoxelLayer"
        assert [(s.name, s.topic, s.params.obstacle_max_range) for s in node.sources] == [
            ("my_lidar.front", "/front_scan", 4.5), ("my_lidar.back", "back", 2.5)]  # topic defaults to the name
        inflation = node.layers[1]
        assert isinstance(inflation, InflationLayer) and inflation.cost_scaling_factor == 10.0  # Nav2's default
        assert node.params.track_unknown_space is False  # Nav2's default
    finally:
        node.destroy_node()
    with pytest.raises(ParameterError, match=r"'inflation_layer.plugin'.*nav2_costmap_2d::InflationLayer"):
        CostmapNode("local_costmap", parameter_overrides=[
            Parameter("rolling_window", value=True), Parameter("plugins", value=["inflation_layer"]),
            Parameter("inflation_layer.plugin", value="nav2_costmap_2d::DenoiseLayer")])
    with pytest.raises(ParameterError, match="'my_layer.plugin'"):
        CostmapNode("local_costmap", parameter_overrides=[
            Parameter("rolling_window", value=True), Parameter("plugins", value=["my_layer"])])
    with pytest.raises(ParameterError, match="obstacle_layer.scan.data_type.*LaserScan"):
        local_costmap(0.0, Parameter("obstacle_layer.scan.data_type", value="PointCloud2"))


def set_parameters(node: CostmapNode, **values: object) -> list:
    return node.set_parameters([Parameter(name.replace("__", "."), value=value) for name, value in values.items()])


def test_live_parameters_apply_at_once_without_forgetting_what_was_seen(context: None) -> None:
    node = local_costmap(0.0, Parameter("plugins", value=["obstacle_layer", "inflation_layer"]),
                         Parameter("inflation_layer.inflation_radius", value=0.55),
                         Parameter("inflation_layer.cost_scaling_factor", value=3.0))
    try:
        node._on_scan(node.sources[0], scan(1.0, 1.5))
        node.update()
        before = cost(node, 1.52 - 0.7)
        assert before == FREE_SPACE  # 0.7 m off the wall: beyond the 0.55 m radius
        results = set_parameters(node, inflation_layer__inflation_radius=0.9)
        assert results[0].successful
        assert cost(node, 1.52 - 0.7) > FREE_SPACE  # inflated at once
        assert cost(node, 1.52) == LETHAL_OBSTACLE  # the wall seen before is kept
        refused = set_parameters(node, obstacle_layer__scan__obstacle_max_range=1.0)
        assert not refused[0].successful and "cannot change while the node runs" in refused[0].reason
        assert node.sources[0].params.obstacle_max_range == 2.5
        bad = set_parameters(node, inflation_layer__inflation_radius=-1.0)
        assert not bad[0].successful and "inflation_radius" in bad[0].reason
        assert set_parameters(node, width=10)[0].successful is False
        assert set_parameters(node, robot_radius=0.5)[0].successful
        assert cost(node, 1.52 - 0.45) == INSCRIBED_INFLATED_OBSTACLE  # the inscribed zone grew with it
        assert set_parameters(node, obstacle_layer__enabled=False)[0].successful
        assert cost(node, 1.52) == NO_INFORMATION  # a disabled layer adds nothing...
        assert set_parameters(node, obstacle_layer__enabled=True)[0].successful
        assert cost(node, 1.52) == LETHAL_OBSTACLE  # ...and keeps what it had seen
    finally:
        node.destroy_node()


def test_published_footprint_is_the_padded_circle_at_the_robot_in_the_costmaps_frame(context: None) -> None:
    from geometry_msgs.msg import PolygonStamped

    from pppbot_common.ros.wait import wait_until

    node = local_costmap(persistence=0.0)
    node.tf.set_transform("odom", "base_link", 0.0, (1.0, 2.0, 0.5), True)
    listener = rclpy.create_node("footprint_listener")
    got: list[PolygonStamped] = []
    listener.create_subscription(PolygonStamped, "/local_costmap/published_footprint", got.append, 10)
    try:
        node._on_scan(node.sources[0], scan(1.0, 1.5))
        node.update()
        def published() -> bool:
            node.publish()
            return bool(got)

        wait_until(published, 10, "a footprint", node=listener)
        msg = got[-1]
        assert msg.header.frame_id == "odom" and len(msg.polygon.points) == 16
        radii = [math.hypot(p.x - 1.0, p.y - 2.0) for p in msg.polygon.points]
        assert radii == pytest.approx([0.31] * 16, abs=1e-6)  # robot_radius 0.3, padding 0.01
        first = msg.polygon.points[0]
        assert math.atan2(first.y - 2.0, first.x - 1.0) == pytest.approx(0.5, abs=1e-6)  # turned with the robot
    finally:
        listener.destroy_node()
        node.destroy_node()
