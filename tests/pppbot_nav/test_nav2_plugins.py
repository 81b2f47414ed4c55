"""The planner and controller servers load Nav2's plugins by type name, as Nav2 does: ppp_bot's
own nav2_params.yaml (DWB and NavFn, Humble's checker keys, a voxel layer) unchanged, an unknown
type refused with the known ones, and live parameter sets applied, refused or kept as Nav2's."""
from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import rclpy
from rclpy.parameter import Parameter
from user_plugins import install_user_plugins

from pppbot_common.params import ParameterError
from pppbot_common.ros.unread_parameters import declared_names, reasons, unread_parameters
from pppbot_nav.controller.checkers import SimpleGoalChecker, SimpleProgressChecker, StoppedGoalChecker
from pppbot_nav.controller.dwb import DWBLocalPlanner
from pppbot_nav.controller.pure_pursuit import PurePursuit
from pppbot_nav.costmap.layers import InflationLayer, ObstacleLayer
from pppbot_nav.planner.navfn import NavfnPlanner
from pppbot_nav.planner.plugin_settings import SmoothedSmac2D
from pppbot_nav.ros.controller_server import ControllerServer
from pppbot_nav.ros.planner_server import InvalidPlanner, PlannerServer

pytestmark = pytest.mark.ros

ROOT = Path(__file__).resolve().parents[2]
PPP_BOT = ROOT / "tests" / "data" / "ppp_bot" / "nav2_params.yaml"
OURS = ROOT / "config" / "nav2_params.yaml"
GENERIC = "not implemented"


@pytest.fixture
def params_file(request: Any) -> Iterator[Path]:
    """rclpy initialised with ``--params-file`` the test's parameter (a path)."""
    path = request.param
    rclpy.init(args=["--ros-args", "--params-file", str(path)])
    try:
        yield path
    finally:
        rclpy.shutdown()


@pytest.fixture
def context() -> Iterator[None]:
    rclpy.init()
    try:
        yield
    finally:
        rclpy.shutdown()


def unexplained(node: Any) -> dict[str, list[str]]:
    """The keys given to ``node`` and its composed costmap that no node reads, by reason."""
    nodes = [node, *node.composed_nodes]
    read = declared_names(nodes)
    found: dict[str, list[str]] = {}
    for n in nodes:
        for reason, names in reasons(unread_parameters(n, read), getattr(n, "parameter_notes", {}), GENERIC).items():
            found.setdefault(reason, []).extend(names)
    return found


@pytest.mark.parametrize("params_file", [PPP_BOT], indirect=True)
def test_ppp_bots_controller_file_runs_dwb_with_its_critics_and_checkers(params_file: Path) -> None:
    server = ControllerServer()
    try:
        dwb = server.controllers["FollowPath"]
        assert isinstance(dwb, DWBLocalPlanner)
        s = dwb.settings
        assert (s.max_vel_x, s.max_vel_theta, s.acc_lim_x, s.acc_lim_theta, s.decel_lim_x, s.sim_time) == \
            (1.5, 2.0, 2.5, 3.2, -2.5, 1.7)
        assert list(s.critics) == ["RotateToGoal", "Oscillation", "BaseObstacle", "GoalAlign", "PathAlign",
                                   "PathDist", "GoalDist"]
        scales = {critic.name: critic.scale for critic in dwb.critics}  # each declared under FollowPath.<critic>.
        assert scales == {"RotateToGoal": 32.0, "Oscillation": 1.0, "BaseObstacle": 0.02, "GoalAlign": 24.0,
                          "PathAlign": 32.0, "PathDist": 32.0, "GoalDist": 24.0}
        assert server.get_parameter("FollowPath.PathAlign.forward_point_distance").value == 0.1
        assert s.robot_radius == 0.3  # the local costmap's footprint, as Nav2's
        # Humble's progress_checker_plugin (one name) and ppp_bot's general_goal_checker.
        assert isinstance(server.progress_checkers["progress_checker"], SimpleProgressChecker)
        assert isinstance(server.goal_checkers["general_goal_checker"], SimpleGoalChecker)
        voxel, inflation = server.costmap_node.layers
        assert isinstance(voxel, ObstacleLayer) and voxel.plugin == "nav2_costmap_2d::VoxelLayer"
        assert isinstance(inflation, InflationLayer) and inflation.inflation_radius == 0.9
        (source,) = server.costmap_node.sources
        assert (source.topic, source.params.obstacle_max_range, source.params.raytrace_max_range) == ("/scan", 4.5, 5.0)
        assert server.costmap_node.params.track_unknown_space is False  # Nav2's default: the file sets none
        assert GENERIC not in unexplained(server)  # every key is read, or named with its reason
    finally:
        server.destroy_node()


@pytest.mark.parametrize("params_file", [PPP_BOT], indirect=True)
def test_ppp_bots_planner_file_runs_navfn(params_file: Path) -> None:
    server = PlannerServer()
    try:
        planner = server.planner_for("")
        assert isinstance(planner, NavfnPlanner) and planner.settings.tolerance == 0.5
        assert server.planner_for("GridBased") is planner
        with pytest.raises(InvalidPlanner, match="'Smac' is not one of this server's: GridBased"):
            server.planner_for("Smac")
        assert server.costmap_node.params.track_unknown_space is True
        assert GENERIC not in unexplained(server)
    finally:
        server.destroy_node()


@pytest.mark.parametrize("params_file", [OURS], indirect=True)
def test_pppbots_own_file_has_no_key_without_effect(params_file: Path) -> None:
    for server_type in (ControllerServer, PlannerServer):
        server = server_type()
        try:
            assert unexplained(server) == {}
        finally:
            server.destroy_node()


def test_several_planners_and_controllers_by_type_and_an_unknown_type_refused(context: None) -> None:
    planner = PlannerServer(parameter_overrides=[
        Parameter("planner_plugins", value=["GridBased", "Smac"]),
        Parameter("Smac.plugin", value="nav2_smac_planner/SmacPlanner2D"), Parameter("Smac.tolerance", value=0.25)])
    try:
        assert isinstance(planner.planner_for("GridBased"), NavfnPlanner)  # Nav2's default type for GridBased
        smac = planner.planner_for("Smac")
        assert isinstance(smac, SmoothedSmac2D) and smac.planner.settings.tolerance == 0.25
        with pytest.raises(InvalidPlanner):
            planner.planner_for("")  # two planners: a request must name one
    finally:
        planner.destroy_node()
    with pytest.raises(ParameterError, match=r"'GridBased.plugin' = 'nav2_theta_star_planner/ThetaStarPlanner'.*"
                                             r"group .pppbot_nav.planners.; installed: .*NavfnPlanner.*SmacPlanner2D"):
        PlannerServer(parameter_overrides=[Parameter("GridBased.plugin",
                                                     value="nav2_theta_star_planner/ThetaStarPlanner")])
    controller = ControllerServer(parameter_overrides=[
        Parameter("controller_plugins", value=["FollowPath", "RPP"]),
        Parameter("RPP.plugin", value="nav2_regulated_pure_pursuit_controller::RegulatedPurePursuitController"),
        Parameter("RPP.desired_linear_vel", value=0.3),
        Parameter("goal_checker_plugins", value=["stopped"]),
        Parameter("stopped.plugin", value="nav2_controller::StoppedGoalChecker")])
    try:
        assert isinstance(controller.controllers["FollowPath"], DWBLocalPlanner)  # Nav2's default type
        assert isinstance(controller.controllers["RPP"], PurePursuit)
        assert controller.controllers["RPP"].settings.desired_linear_vel == 0.3
        assert isinstance(controller.goal_checkers["stopped"], StoppedGoalChecker)
    finally:
        controller.destroy_node()
    with pytest.raises(ParameterError, match=r"'FollowPath.plugin' = 'nav2_mppi_controller::MPPIController'.*"
                                             r"'pppbot_nav.controllers'; installed: "
                                             r"dwb_core::DWBLocalPlanner, nav2_regulated_pure_pursuit"):
        ControllerServer(parameter_overrides=[Parameter("FollowPath.plugin",
                                                        value="nav2_mppi_controller::MPPIController")])
    with pytest.raises(ParameterError, match="'FollowPath.critics'.*PathDist"):
        ControllerServer(parameter_overrides=[Parameter("FollowPath.critics", value=["PathDist", "Wobble"])])


def set_one(node: Any, name: str, value: Any) -> Any:
    return node.set_parameters([Parameter(name, value=value)])[0]


def test_live_controller_parameters_apply_refuse_and_keep_state(context: None) -> None:
    server = ControllerServer(parameter_overrides=[
        Parameter("FollowPath.plugin", value="nav2_regulated_pure_pursuit_controller::RegulatedPurePursuitController"),
        Parameter("goal_checker_plugins", value=["general_goal_checker"])])
    try:
        rpp = server.controllers["FollowPath"]
        checker = server.goal_checkers["general_goal_checker"]
        assert checker.is_goal_reached((0.1, 0.0, 1.0), (0.0, 0.0, 0.0)) is False  # within xy: latched (stateful)
        assert set_one(server, "FollowPath.desired_linear_vel", 0.8).successful
        assert server.controllers["FollowPath"] is rpp and rpp.settings.desired_linear_vel == 0.8
        bad = set_one(server, "FollowPath.desired_linear_vel", -1.0)
        assert not bad.successful and "desired_linear_vel" in bad.reason and rpp.settings.desired_linear_vel == 0.8
        assert set_one(server, "general_goal_checker.yaw_goal_tolerance", 1.2).successful
        assert server.goal_checkers["general_goal_checker"] is checker and checker.yaw_goal_tolerance == 1.2
        # The latch survived the set: 1.0 rad off is now within the new tolerance, wherever the robot is.
        assert checker.is_goal_reached((5.0, 5.0, 1.0), (0.0, 0.0, 0.0)) is True
        assert set_one(server, "controller_frequency", 10.0).successful
        assert server.timer.timer_period_ns == 100_000_000 and server.timer.is_canceled()
        refused = set_one(server, "odom_topic", "/other_odom")
        assert not refused.successful and "'odom_topic' cannot change while the node runs" in refused.reason
        assert set_one(server, "failure_tolerance", -1.0).successful  # Nav2: -1 never fails
    finally:
        server.destroy_node()


def test_live_dwb_limits_apply_and_its_critics_are_refused(context: None) -> None:
    server = ControllerServer()
    try:
        dwb = server.controllers["FollowPath"]
        assert set_one(server, "FollowPath.max_vel_x", 0.7).successful
        assert server.controllers["FollowPath"] is dwb and dwb.settings.max_vel_x == 0.7
        assert dwb.settings.robot_radius == server.costmap_node.params.robot_radius  # kept from the costmap
        refused = set_one(server, "FollowPath.PathDist.scale", 1.0)
        assert not refused.successful and "cannot change while the node runs" in refused.reason
        critics = list(dwb.critics)
        assert set_one(server.costmap_node, "robot_radius", 0.4).successful  # the costmap's footprint...
        assert server.controllers["FollowPath"] is dwb and dwb.settings.robot_radius == 0.4  # ...is DWB's
        assert dwb.critics == critics  # the critics kept (none of ObstacleFootprint here)
    finally:
        server.destroy_node()


def test_live_planner_parameters(context: None) -> None:
    server = PlannerServer()
    try:
        assert set_one(server, "GridBased.tolerance", 1.0).successful
        assert server.planner_for("").settings.tolerance == 1.0
        refused = set_one(server, "GridBased.max_planning_time", 5.0)  # NavFn's own, not dynamic in Nav2
        assert not refused.successful and "GridBased.max_planning_time" in refused.reason
        assert set_one(server, "expected_planner_frequency", 2.0).successful
        assert not set_one(server, "planner_plugins", ["X"]).successful
    finally:
        server.destroy_node()


@pytest.mark.parametrize("make, name, value", [
    ("pppbot_nav.ros.map_server:MapServer", "frame_id", "other"),
    ("pppbot_nav.ros.navigator:Navigator", "replanning_frequency", 2.0),
    ("pppbot_nav.ros.behavior_server:BehaviorServer", "cycle_frequency", 5.0),
    ("pppbot_nav.ros.smoother_server:SmootherServer", "simple_smoother.max_its", 10),
    ("pppbot_nav.ros.waypoint_follower:WaypointFollower", "loop_rate", 5),
])
def test_nodes_without_dynamic_parameters_refuse_a_set_with_the_reason(context: None, make: str, name: str,
                                                                        value: Any) -> None:
    import importlib

    module, cls = make.split(":")
    node = getattr(importlib.import_module(module), cls)()
    try:
        before = node.get_parameter(name).value
        result = set_one(node, name, value)
        assert not result.successful and f"'{name}' cannot change while the node runs" in result.reason
        assert node.get_parameter(name).value == before
    finally:
        node.destroy_node()


def test_the_waypoint_followers_stop_on_failure_is_live(context: None) -> None:
    from pppbot_nav.ros.waypoint_follower import WaypointFollower

    node = WaypointFollower()
    try:
        assert set_one(node, "stop_on_failure", False).successful and node.params.stop_on_failure is False
    finally:
        node.destroy_node()


@pytest.mark.parametrize("make, name, value", [
    ("pppbot_slam.ros.slam:Slam", "resolution", 0.1),
    ("pppbot_slam.ros.slam:Slam", "scan_topic", "/other"),
    ("pppbot_nav.ros.amcl:Amcl", "scan_topic", "/other"),
    ("pppbot_control.ros.diff_drive_controller:DiffDriveController", "use_stamped_vel", False),
])
def test_what_is_built_at_start_up_is_refused_not_silently_kept(context: None, make: str, name: str,
                                                               value: Any) -> None:
    import importlib

    module, cls = make.split(":")
    node = getattr(importlib.import_module(module), cls)()
    try:
        result = set_one(node, name, value)
        assert not result.successful and f"'{name}' cannot change while the node runs" in result.reason
    finally:
        node.destroy_node()


@pytest.mark.parametrize("params_file", [PPP_BOT], indirect=True)
def test_ppp_bots_file_leaves_the_other_nav2_nodes_no_key_without_its_reason(params_file: Path) -> None:
    import importlib

    for spec in ("pppbot_nav.ros.navigator:Navigator", "pppbot_nav.ros.behavior_server:BehaviorServer",
                 "pppbot_nav.ros.smoother_server:SmootherServer", "pppbot_nav.ros.waypoint_follower:WaypointFollower",
                 "pppbot_nav.ros.velocity_smoother:VelocitySmoother", "pppbot_nav.ros.amcl:Amcl"):
        module, cls = spec.split(":")
        node = getattr(importlib.import_module(module), cls)()
        try:
            assert GENERIC not in reasons(unread_parameters(node), getattr(node, "parameter_notes", {}), GENERIC), spec
        finally:
            node.destroy_node()


def test_behaviours_are_nav2s_plugin_types_under_any_name(context: None) -> None:
    from pppbot_nav.ros.behavior_server import BehaviorServer

    server = BehaviorServer(parameter_overrides=[
        Parameter("behavior_plugins", value=["turn", "backup"]),
        Parameter("turn.plugin", value="nav2_behaviors/Spin")])  # Humble's spelling, a name of one's own
    try:
        assert {name: plugin.type_name for name, plugin in server.plugins.items()} == {
            "turn": "nav2_behaviors::Spin", "backup": "nav2_behaviors::BackUp"}
        assert set(server.servers) == {"turn", "backup"}  # the actions are named as the behaviours
    finally:
        server.destroy_node()
    with pytest.raises(ParameterError, match=r"'spin.plugin' = 'nav2_behaviors::Dock'.*group 'pppbot_nav.behaviors'"
                                             r".*installed: .*nav2_behaviors::Spin"):
        BehaviorServer(parameter_overrides=[Parameter("spin.plugin", value="nav2_behaviors::Dock")])


def test_nodes_that_read_their_parameters_once_refuse_sets(context: None) -> None:
    from pppbot_control.ros.twist_mux import TwistMuxNode
    from pppbot_nav.ros.collision_monitor import CollisionMonitor

    mux = TwistMuxNode(parameter_overrides=[Parameter("topics.navigation.topic", value="cmd_vel"),
                                            Parameter("topics.navigation.timeout", value=0.5),
                                            Parameter("topics.navigation.priority", value=10)])
    try:
        result = mux.set_parameters([Parameter("topics.navigation.priority", value=200)])[0]
        assert not result.successful and "twist_mux reads its inputs" in result.reason
    finally:
        mux.destroy_node()
    from rclpy.lifecycle import TransitionCallbackReturn

    box = "[[0.4, 0.3], [0.4, -0.3], [0.0, -0.3], [0.0, 0.3]]"
    monitor = CollisionMonitor(parameter_overrides=[
        Parameter(k, value=v) for k, v in {"polygons": ["Stop"], "Stop.type": "polygon", "Stop.points": box,
                                           "Stop.action_type": "stop", "observation_sources": ["scan"],
                                           "scan.type": "scan", "scan.topic": "scan"}.items()])
    try:
        assert monitor.set_parameters([Parameter("base_frame_id", value="base_footprint")])[0].successful
        assert monitor.trigger_configure() == TransitionCallbackReturn.SUCCESS  # it reads them now...
        refused = monitor.set_parameters([Parameter("base_frame_id", value="base_link")])[0]
        assert not refused.successful and "read at configure" in refused.reason  # ...and not again until then
    finally:
        monitor.destroy_node()


def test_a_users_critic_runs_beside_dwbs_own_and_takes_its_live_parameters(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    install_user_plugins(tmp_path / "site", monkeypatch)
    rclpy.init(args=["--ros-args", "-p", "FollowPath.critics:=['BaseObstacle', 'Lean']",
                     "-p", "FollowPath.Lean.scale:=2.0"])
    try:
        server = ControllerServer()
        try:
            dwb = server.controllers["FollowPath"]
            base, lean = dwb.critics
            assert (type(base).__name__, type(lean).__name__, lean.name, lean.scale) == \
                ("BaseObstacle", "Lean", "Lean", 2.0)
            assert set_one(server, "FollowPath.Lean.scale", 0.5).successful
            assert dwb.critics[0] is base and dwb.critics[1].scale == 0.5  # made again in its place
            assert not set_one(server, "FollowPath.Lean.scale", -1.0).successful
            assert not set_one(server, "FollowPath.BaseObstacle.scale", 0.5).successful  # DWB's own: fixed
        finally:
            server.destroy_node()
    finally:
        rclpy.shutdown()
