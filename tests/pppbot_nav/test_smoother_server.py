"""The smoother server over DDS: smooth_path on a published costmap, with Nav2's error codes."""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from action_msgs.msg import GoalStatus
from builtin_interfaces.msg import Duration
from geometry_msgs.msg import PoseStamped
from lifecycle_msgs.msg import Transition
from nav2_msgs.action import SmoothPath
from nav_msgs.msg import Path
from rclpy.action import ActionClient
from rclpy.parameter import Parameter
from user_plugins import install_user_plugins

from pppbot_common.maps import OccupancyGrid
from pppbot_common.params import ParameterError
from pppbot_common.ros.wait import change_state, send_goal, wait_until
from pppbot_nav.planner.simple_smoother import SimpleSmootherSettings, blocked_cells, smooth_path
from pppbot_nav.ros.smoother_server import SmootherServer

pytestmark = pytest.mark.ros

Result = SmoothPath.Result
COSTMAP = "/global_costmap/costmap"


def free_costmap() -> OccupancyGrid:
    """4 × 4 m of free cells at 0.05 m, its corner at (-1, -1)."""
    return OccupancyGrid(np.zeros((80, 80), dtype=np.int8), 0.05, (-1.0, -1.0, 0.0), "map")


def staircase(n: int = 41, step_m: float = 0.05) -> np.ndarray:
    """(n, 2) points of a 45° line drawn as grid steps: right, up, right, up..."""
    moves = np.array([[step_m, 0.0], [0.0, step_m]])[np.arange(n - 1) % 2]
    return np.vstack([[0.0, 0.0], np.cumsum(moves, axis=0)])


def roughness(points: np.ndarray) -> float:
    return float((np.diff(points, 2, axis=0) ** 2).sum())


def path_of(points: np.ndarray) -> Path:
    path = Path()
    path.header.frame_id = "map"
    poses = []
    for x, y in points.tolist():
        pose = PoseStamped(header=path.header)
        pose.pose.position.x, pose.pose.position.y = x, y
        pose.pose.orientation.w = 1.0
        poses.append(pose)
    path.poses = poses
    return path


def points_of(path: Path) -> np.ndarray:
    return np.array([[p.pose.position.x, p.pose.position.y] for p in path.poses])


class Server:
    """The smoother server spun in the background; the test's client on ``ros_node``."""

    def __init__(self, ros_node: Any, server: SmootherServer) -> None:
        self.node, self.server = ros_node, server
        self.client = ActionClient(ros_node, SmoothPath, "smooth_path")
        assert self.client.wait_for_server(timeout_sec=10)

    def change(self, transition: int) -> bool:
        return change_state(self.node, "smoother_server", transition)

    def activate(self) -> None:
        assert self.change(Transition.TRANSITION_CONFIGURE)
        assert self.change(Transition.TRANSITION_ACTIVATE)

    def has_costmap(self) -> None:
        wait_until(lambda: self.server.costmap is not None, 10, "the server's costmap", node=self.node)

    def send(self, points: np.ndarray, **fields: Any) -> Any:
        goal = SmoothPath.Goal(path=path_of(points), max_smoothing_duration=Duration(sec=5), **fields)
        return send_goal(self.client, goal, self.node)

    def result(self, handle: Any) -> Any:
        future = handle.get_result_async()
        return wait_until(lambda: future.result() if future.done() else None, 30, "the smooth_path result",
                          node=self.node)


@pytest.fixture
def smoother(ros_node: Any, spin_in_background: Callable[..., Any]) -> Callable[..., Server]:
    """``smoother(**parameters)``: a smoother server (unconfigured) with the parameters."""
    def start(**parameters: Any) -> Server:
        server = SmootherServer(parameter_overrides=[Parameter(k, value=v) for k, v in parameters.items()])
        spin_in_background(server)
        return Server(ros_node, server)
    return start


def test_goals_are_rejected_until_active_then_the_path_comes_back_smoother(smoother, publish_map, ros_node):
    publish_map(COSTMAP, grid=free_costmap())
    s = smoother()
    smoothed_topic: list[Path] = []
    ros_node.create_subscription(Path, "/plan_smoothed", smoothed_topic.append, 1)
    s.has_costmap()
    assert not s.send(staircase()).accepted
    s.activate()
    end = s.result(s.send(staircase(), check_for_collisions=True))
    assert end.status == GoalStatus.STATUS_SUCCEEDED
    assert end.result.error_code == Result.NONE and end.result.was_completed
    out = points_of(end.result.path)
    assert len(out) == len(staircase())
    assert roughness(out) < 0.2 * roughness(staircase())
    np.testing.assert_allclose(out[[0, -1]], staircase()[[0, -1]])
    wait_until(lambda: smoothed_topic, 10, "plan_smoothed", node=ros_node)
    np.testing.assert_allclose(points_of(smoothed_topic[-1]), out)


def test_an_unknown_smoother_id_is_invalid_smoother(smoother, publish_map):
    publish_map(COSTMAP, grid=free_costmap())
    s = smoother()
    s.activate()
    end = s.result(s.send(staircase(), smoother_id="savitzky_golay"))
    assert end.status == GoalStatus.STATUS_ABORTED
    assert end.result.error_code == Result.INVALID_SMOOTHER
    assert "'savitzky_golay'" in end.result.error_msg


def test_an_empty_path_is_invalid_path(smoother, publish_map):
    publish_map(COSTMAP, grid=free_costmap())
    s = smoother()
    s.activate()
    s.has_costmap()
    end = s.result(s.send(np.zeros((0, 2))))
    assert end.result.error_code == Result.INVALID_PATH


def test_a_smoothed_path_on_an_inscribed_cell_is_in_collision_when_checked(smoother, publish_map):
    grid = free_costmap()
    points = staircase()
    row, col = grid.cell_of(points[20, 0], points[20, 1])
    grid.data[row, col] = 99  # the path itself runs over an inscribed cell: the smoother cannot take it off
    publish_map(COSTMAP, grid=grid)
    s = smoother()
    s.activate()
    s.has_costmap()
    end = s.result(s.send(points, check_for_collisions=True))
    assert end.status == GoalStatus.STATUS_ABORTED
    assert end.result.error_code == Result.SMOOTHED_PATH_IN_COLLISION
    assert "collides at pose" in end.result.error_msg
    unchecked = s.result(s.send(points, check_for_collisions=False))
    assert unchecked.status == GoalStatus.STATUS_SUCCEEDED


def test_bad_parameters_and_plugin_types_are_refused_naming_them(smoother):
    with pytest.raises(ParameterError, match="simple_smoother.w_smooth"):
        SmootherServer(parameter_overrides=[Parameter("simple_smoother.w_smooth", value=0.9)])
    with pytest.raises(ParameterError, match="smoother_plugins"):
        SmootherServer(parameter_overrides=[Parameter("smoother_plugins", value=["a", "a"])])
    s = smoother(**{"simple_smoother.plugin": "nav2_smoother::SavitzkyGolaySmoother"})
    assert not s.change(Transition.TRANSITION_CONFIGURE)  # as pluginlib fails Nav2's configure
    failure = s.server.configure_failure
    assert "'simple_smoother.plugin' = 'nav2_smoother::SavitzkyGolaySmoother'" in failure
    assert "'pppbot_nav.smoothers'" in failure and "installed: nav2_smoother::SimpleSmoother" in failure


def test_a_smoother_named_without_a_type_fails_the_configure(smoother):
    s = smoother(smoother_plugins=["sg"])  # only simple_smoother has a default type
    assert not s.change(Transition.TRANSITION_CONFIGURE)
    assert "'sg.plugin'" in s.server.configure_failure and "must name the plugin's type" in s.server.configure_failure


def test_two_smoothers_by_name_each_with_its_parameters_chosen_by_smoother_id(smoother, publish_map):
    grid = free_costmap()
    publish_map(COSTMAP, grid=grid)
    s = smoother(**{"smoother_plugins": ["light", "strong"],
                    "light.plugin": "nav2_smoother/SimpleSmoother",  # pluginlib's other spelling
                    "light.w_data": 0.5, "light.w_smooth": 0.02,
                    "strong.plugin": "nav2_smoother::SimpleSmoother"})
    s.activate()
    s.has_costmap()
    stairs = staircase()
    light = s.result(s.send(stairs, smoother_id="light"))
    strong = s.result(s.send(stairs, smoother_id="strong"))
    assert light.result.error_code == strong.result.error_code == Result.NONE
    # Each is the SimpleSmoother with its own parameters (strong's are Nav2's defaults).
    for end, settings in ((light, SimpleSmootherSettings(w_data=0.5, w_smooth=0.02)),
                          (strong, SimpleSmootherSettings())):
        expected = smooth_path(stairs, np.zeros(len(stairs)), settings, clock_s=lambda: 0.0, max_duration_s=1.0,
                               blocked=blocked_cells(grid))
        np.testing.assert_allclose(points_of(end.result.path), expected.points_xy, atol=1e-9)
    assert roughness(points_of(strong.result.path)) < roughness(points_of(light.result.path)) < roughness(stairs)
    # Nav2's rule: with several smoothers an empty id names none; an unknown one is refused alike.
    for smoother_id, said in (("", "no smoother_id"), ("simple_smoother", "unknown smoother_id 'simple_smoother'")):
        refused = s.result(s.send(stairs, smoother_id=smoother_id))
        assert refused.status == GoalStatus.STATUS_ABORTED
        assert refused.result.error_code == Result.INVALID_SMOOTHER
        assert said in refused.result.error_msg and "'light', 'strong'" in refused.result.error_msg


def test_a_smoothers_parameters_and_type_cannot_change_while_it_runs(smoother):
    s = smoother()
    for name, value in (("simple_smoother.w_smooth", 0.1), ("simple_smoother.plugin", "x::Y")):
        result = s.server.set_parameters([Parameter(name, value=value)])[0]
        assert not result.successful and f"'{name}' cannot change while the node runs" in result.reason
    assert s.server.get_parameter("simple_smoother.w_smooth").value == 0.3


def test_a_users_smoother_is_found_by_its_type_name_and_smooths(smoother, publish_map, tmp_path, monkeypatch):
    install_user_plugins(tmp_path / "site", monkeypatch)
    publish_map(COSTMAP, grid=free_costmap())
    s = smoother(**{"smoother_plugins": ["simple_smoother", "straight"],
                    "straight.plugin": "pppbot_test_plugins::Straighten", "straight.max_poses": 50})
    s.activate()
    s.has_costmap()
    stairs = staircase()
    end = s.result(s.send(stairs, smoother_id="straight"))
    assert end.status == GoalStatus.STATUS_SUCCEEDED and end.result.was_completed
    out = points_of(end.result.path)
    np.testing.assert_allclose(out, np.linspace(stairs[0], stairs[-1], len(stairs)), atol=1e-9)
    simple = s.result(s.send(stairs, smoother_id="simple_smoother"))  # pppbot's own, beside it
    assert not np.allclose(points_of(simple.result.path), out, atol=1e-3)
    # The user's smoother's failure is the action's INVALID_PATH, with its message.
    too_long = s.result(s.send(staircase(n=61), smoother_id="straight"))
    assert too_long.result.error_code == Result.INVALID_PATH
    assert "61 poses: more than the 50" in too_long.result.error_msg
