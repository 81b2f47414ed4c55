"""``pppbot eval <scenario>``: a headless scenario run against ground truth, with a report.

    ./pppbot eval drive --world maze [--route coverage] [--seed 0] [--no-lockstep --real-time-factor 3]
                        [--wheel-slip 0.02] [--speed 0.3] [--out DIR] [--json]
    ./pppbot eval navigation --world maze [--goals 50] [--seed 0] [--out DIR] [--json]
    ./pppbot eval batch SPEC.yaml [--workers N] [--resume] [--ray auto]   (many runs: pppbot_eval.ros.batch_cli)

The stack starts through the same supervisor and node plan as ``launch_sim``
(no teleop, no RViz, no viewer), spawned at the route's start. A route driver
in this process follows the route on ground truth through ``/cmd_vel_teleop``
(twist_mux's teleop input) while this process records ``/ground_truth/odom``,
the estimate under test (``/odom`` for ``drive``; a ``/tf`` chain such as map → odom →
base_link for mapping and localization) and ``/ground_truth/collisions``. The
navigation scenario has no route: it starts the navigation nodes too, and sends
random reachable goals (``--goals``, drawn with ``--seed``) to ``navigate_to_pose``
one after another. Then the stack stops and the report is written: ``report.json``
and PNG plots in ``--out`` (``slam`` also saves its final map there as ``map.yaml`` + ``map.pgm``,
ready for ``--map``); with ``--json`` the last line of stdout is the report as
one JSON object. Exit code 0 when the scenario succeeded, 1 when not, 2 for bad arguments.
"""
from __future__ import annotations

import argparse
import dataclasses
import functools
import math
import os
import signal
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from pppbot_bringup.launch_sim import LaunchArgs, NavigationMode, controllers_file, plan
from pppbot_bringup.paths import config_directory
from pppbot_bringup.ros.graph_probe import GraphProbe, domain_taken_message, free_domain
from pppbot_bringup.run import RunError, find_executable
from pppbot_bringup.supervisor import Output, Supervisor
from pppbot_common.dds_isolation import claim_domain_id
from pppbot_common.launch_args import ArgumentError
from pppbot_common.maps import MapFileError, OccupancyGrid
from pppbot_description.errors import DescriptionError
from pppbot_description.xacro_model import process_xacro
from pppbot_eval.config import EvalConfig, ScoredParameters, map_free_params
from pppbot_eval.driver import DriverSettings, RouteDriver
from pppbot_eval.errors import GoalSamplingError, MapQualityError, RouteError
from pppbot_eval.goals import sample_goals
from pppbot_eval.progress import Progress
from pppbot_eval.report import write_json
from pppbot_eval.ros.behaviors import Behavior, Chain, DriveRoute, NavigateGoals, StartLocalization
from pppbot_eval.ros.node import PARTICIPANT, EvalNode
from pppbot_eval.ros.run_report import VIEW_FILE, report
from pppbot_eval.routes import Route, load_routes, routes_file, select_route
from pppbot_eval.scenarios import (
    ESTIMATES,
    MAP_FREE_ESTIMATE,
    Recording,
    Scenario,
    score_saved_map,
    shortest_path_m,
    world_truth,
)
from pppbot_sim.errors import WorldError
from pppbot_sim.wheel_slip import MAX_SLIP_STDDEV
from pppbot_sim.worlds import find_world

READY_TIMEOUT_S = 120.0
#: Without a map, the global costmap's rolling window reaches this far past the start and the goal (m),
#: and is at most this wide (m): 1200 × 1200 cells of 0.05 m.
WINDOW_MARGIN_M = 2.0
MAX_WINDOW_M = 60


def window_size_m(reach_m: float) -> int:
    """The map-free global costmap's width (m): a square holding everything ``reach_m`` from the start
    with :data:`WINDOW_MARGIN_M` more, in whole metres."""
    return 2 * math.ceil(reach_m + WINDOW_MARGIN_M)
#: Wall seconds without a ground-truth message before the run is declared stuck.
STALL_TIMEOUT_S = 30.0
#: Wall seconds to wait for SLAM's map after the route (it updates every map_update_interval sim s).
FINAL_MAP_TIMEOUT_S = 60.0
#: The covariance RViz's 2D Pose Estimate sends: 0.5 m and π/12 rad standard deviations.
INITIAL_POSE_COVARIANCE = [float(v) for v in np.diag([0.25, 0.25, 0.0, 0.0, 0.0, (math.pi / 12) ** 2]).ravel()]



def _progress_line(sim_s: float, wall_s: float, detail: str) -> str:
    """The progress bar's detail: sim time, the speed against the wall clock, the behaviour's word."""
    return f"sim {sim_s:6.1f} s, {sim_s / max(wall_s, 1e-6):4.1f}x, {detail}"

class Run:
    """One scenario run: the stack under a supervisor thread, the eval node in this thread.

    A route scenario drives ``route`` from its start; navigation starts at ``--start`` and
    sends ``goals`` (world frame) instead. What the eval node does is a chain of behaviours
    acting on its ticks (:mod:`pppbot_eval.ros.behaviors`); this thread spins it and
    watches the wall clock (interrupts, a stack that stopped or stalled).
    """

    def __init__(self, config: EvalConfig, world_file: Path, route: Route | None,
                 out: Path, truth_map: OccupancyGrid, goals: list[tuple[float, float, float]] | None = None, *,
                 scored: ScoredParameters) -> None:
        self.config = config
        #: Nav2's parameters, read once: the stack is given this file and the scores use these values.
        self.scored = scored
        self.scenario = config.scenario
        self.world_file = world_file
        self.route = route
        self.start: tuple[float, float, float] = route.start if route is not None else config.start
        self.out = out
        self.truth_map = truth_map
        self.goals = goals or []
        #: Navigation without a map: in odom, which starts at the spawn pose; else in the map, at --map-pose.
        self.map_free = config.no_map
        self.frame_in_world = self.start if self.map_free else config.map_pose
        #: The speed limit goals are timed against: the goal loop and the report agree.
        self.max_speed_mps = self.scored.max_speed_mps
        self.recording = Recording()
        self.interrupted = False
        self.stop = threading.Event()

    def interrupt(self, signum: int, frame: object) -> None:
        """Signal handler (installed by :func:`main` for the whole run): stop, then report."""
        self.interrupted = True
        self.stop.set()

    def _launch_args(self) -> LaunchArgs:
        """The bringup this scenario runs: launch_sim's arguments as a user would give them."""
        x, y, yaw = self.start
        navigates = self.scenario is Scenario.NAVIGATION
        return LaunchArgs(
            world=str(self.world_file), x=x, y=y, yaw=yaw, use_teleop=False, use_rviz=False, use_viz=False,
            headless=True,
            record=False, real_time_factor=self.config.target_real_time_factor, lockstep=self.config.lockstep,
            seed=self.config.seed, wheel_slip=self.config.wheel_slip, log_level=self.config.log_level,
            use_slam=self.scenario is Scenario.SLAM,
            localization=self.scenario in (Scenario.LOCALIZATION, Scenario.NAVIGATION) and not self.map_free,
            # The route scenarios drive themselves: no navigation nodes to share the CPU.
            navigation=NavigationMode.TRUE if navigates else NavigationMode.FALSE,
            map=str(self.config.map or ""), params_file=str(self._nav2_params()),
            slam_params_file=str(self._slam_params()) if self.scenario is Scenario.SLAM else "")

    def _nav2_params(self) -> Path:
        """The file the stack's Nav2 nodes read: ``--params-file`` (or the default), made map-free with
        ``--no-map`` (:func:`map_free_params`: the global costmap's window holds start and goal with
        :data:`WINDOW_MARGIN_M` around them); the scored parameters are the same in both."""
        if not self.map_free:
            return self.scored.file
        reach = max(math.dist(self.start[:2], goal[:2]) for goal in self.goals)
        return map_free_params(self.scored.file, self.out / "logs" / "nav2_params_map_free.yaml", window_size_m(reach))

    def _slam_params(self) -> Path:
        """The bringup's slam parameters with ``map_save_name`` in ``--out``: serialize_map writes
        the pose graph next to the report."""
        params = yaml.safe_load((config_directory() / "mapper_params_online_async.yaml").read_text())
        params["slam_toolbox"]["ros__parameters"]["map_save_name"] = str((self.out / "map").resolve())
        path = self.out / "logs" / "slam_params.yaml"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(yaml.safe_dump(params, sort_keys=False))
        return path

    def execute(self, progress: Progress) -> None:
        urdf_file = self.out / "logs" / "robot.urdf"
        urdf_file.parent.mkdir(parents=True, exist_ok=True)
        urdf_file.write_text(process_xacro(mappings={"controllers_file": str(controllers_file())}))
        probe = GraphProbe()
        try:
            running = probe.running_stack()
            if running is not None:
                self.recording.failure = f"cannot start the stack: {domain_taken_message(running)}"
                return
            try:
                the_plan = plan(self._launch_args(), self.world_file, urdf_file,
                                lambda p, e: str(find_executable(p, e)), probe, terminal=False, rviz=None,
                                extra_participants=(PARTICIPANT,),
                                view_recording=self.out / VIEW_FILE if self.config.view else None)
            except (ArgumentError, RunError) as exc:
                self.recording.failure = f"cannot start the stack: {exc}"
                return
            output = Output(progress.lines(), log_dir=self.out / "logs")
            supervisor = Supervisor(the_plan.nodes, output)
            self._run_stack(supervisor, [n.name for n in the_plan.nodes], probe, progress)
        finally:
            probe.close()

    def _behavior(self) -> Behavior:
        if self.route is None:
            return NavigateGoals(self.goals, self.truth_map, self.frame_in_world, self.max_speed_mps)
        driver = RouteDriver(self.route.points, DriverSettings(speed_mps=self.config.speed))
        limit_s = self.config.timeout or 2.5 * self.route.length_m / self.config.speed + 60.0
        drive = DriveRoute(driver, limit_s)
        if self.scenario is not Scenario.LOCALIZATION:
            return drive
        offset = None if self.config.global_localization else self.config.initial_offset
        return Chain([StartLocalization(self.start, offset, INITIAL_POSE_COVARIANCE), drive])

    def _run_stack(self, supervisor: Supervisor, names: list[str], probe: GraphProbe, progress: Progress) -> None:
        thread = threading.Thread(target=supervisor.run, kwargs={"until": self.stop.is_set}, name="supervisor")
        node = EvalNode(MAP_FREE_ESTIMATE if self.map_free else ESTIMATES[self.scenario], self.recording,
                        wants_map=self.scenario is Scenario.SLAM,
                        localizes=self.scenario in (Scenario.LOCALIZATION, Scenario.NAVIGATION) and not self.map_free,
                        navigates=self.scenario is Scenario.NAVIGATION, lockstep=self.config.lockstep,
                        goal_frame="odom" if self.map_free else "map", through_poses=self.config.through_poses)
        behavior = node.behavior = self._behavior()
        if self.config.lockstep:
            # Time starts only once every participant (this node among them) has joined: the
            # behaviour runs from the first tick, at the same sim time on every run.
            node.start()
        wall0 = time.monotonic()
        thread.start()
        try:
            progress.message(f"starting the stack in '{self.world_file.stem}' (logs in {self.out / 'logs'})")
            if not self._wait_ready(supervisor, names, thread, node):
                return
            probe.close()
            if self.scenario is Scenario.LOCALIZATION:
                dx, dy, dyaw = self.config.initial_offset
                progress.message("global localization: particles over the whole map" if self.config.global_localization
                                 else f"initial pose off by ({dx:g} m, {dy:g} m, {dyaw:g} rad)")
            if self.scenario is Scenario.NAVIGATION:
                progress.message("one goal without a map, in odom" if self.map_free else
                                 f"{len(self.goals)} goal(s)" + ("" if self.config.goal else
                                                                f", drawn with seed {self.config.seed}"))
            node.start()
            self._run(node, behavior, thread, progress)
            if self.scenario is Scenario.SLAM and self.recording.failure is None:
                self._wait_for_final_map(node, thread, progress)
                self._serialize(node, thread, progress)
        finally:
            if isinstance(behavior, NavigateGoals):
                behavior.cancel()
            node.stop_robot()
            node.spin_pending(0.0)
            self.recording.wall_seconds = time.monotonic() - wall0
            node.close()  # leaves lockstep first: the stack is not held waiting for it while it stops
            self.stop.set()
            thread.join()
            progress.finish()

    def _wait_ready(self, supervisor: Supervisor, names: list[str], thread: threading.Thread,
                    node: EvalNode) -> bool:
        deadline = time.monotonic() + READY_TIMEOUT_S
        while (not all(supervisor.is_ready(n) for n in names) or node.sim_now_s is None
               or not all(ready() for ready in node.servers.values())):
            if self.interrupted:
                self.recording.failure = "interrupted"
                return False
            if not thread.is_alive():
                self.recording.failure = f"the stack stopped while starting (see {self.out / 'logs'})"
                return False
            if time.monotonic() > deadline:
                waiting = ([n for n in names if not supervisor.is_ready(n)]
                           or [what for what, ready in node.servers.items() if not ready()] or ["/ground_truth/odom"])
                self.recording.failure = f"not ready after {READY_TIMEOUT_S:.0f} s: {', '.join(waiting)}"
                return False
            node.spin_pending(0.05)
        return True

    def _run(self, node: EvalNode, behavior: Behavior, thread: threading.Thread, progress: Progress) -> None:
        """Spin the eval node until its behaviour ends; the wall clock's watch on the way."""
        rec = self.recording
        while behavior.outcome is None:
            node.spin_pending(0.05)
            rec.drive_wall_seconds = node.drive_wall_seconds()
            fraction, detail = behavior.progress()
            line = functools.partial(_progress_line, rec.sim_seconds, rec.drive_wall_seconds, detail)
            progress.update(fraction, line)  # formatted only when drawn
            if self.interrupted:
                rec.failure = "interrupted"
                return
            if not thread.is_alive():
                rec.failure = f"the stack stopped during the run (see {self.out / 'logs'})"
                return
            if rec.not_upright is not None:  # a robot on its side is not scored
                rec.failure = rec.not_upright
                return
            if time.monotonic() - node.last_truth_wall_s > STALL_TIMEOUT_S:
                rec.failure = f"no ground truth for {STALL_TIMEOUT_S:.0f} s (the simulator stalled)"
                return
        rec.drive_wall_seconds = node.drive_wall_seconds()
        if behavior.outcome:
            rec.failure = behavior.outcome
        progress.update(1.0, f"sim {rec.sim_seconds:6.1f} s")

    def _wait_for_final_map(self, node: EvalNode, thread: threading.Thread, progress: Progress) -> None:
        """Stand still until a /map built after the route's end arrives (the map updates every few seconds)."""
        node.stop_robot()
        end_s = self.recording.end_sim_s
        deadline = time.monotonic() + FINAL_MAP_TIMEOUT_S
        progress.message("waiting for the final map")
        while self.recording.final_map_stamp_s <= end_s:
            node.spin_pending(0.05)
            if self.interrupted or not thread.is_alive() or time.monotonic() > deadline:
                self.recording.failure = self.recording.failure or (
                    "interrupted" if self.interrupted else f"no /map after the route's end within "
                                                          f"{FINAL_MAP_TIMEOUT_S:.0f} s")
                return


    def _serialize(self, node: EvalNode, thread: threading.Thread, progress: Progress) -> None:
        """Have the slam node write its pose graph (``map.posegraph``, what ``serialize_map``
        writes): the graph, keyframes and scans, for a later session or an offline replay. A
        by-product: when it cannot be written the run says so and goes on (no ``posegraph``)."""
        progress.message("serializing the pose graph")
        path = self.out / "map.posegraph"
        future = node.serialize(str(path.with_suffix("").resolve()))
        deadline = time.monotonic() + FINAL_MAP_TIMEOUT_S
        while not future.done():
            node.spin_pending(0.05)
            if self.interrupted:
                self.recording.failure = self.recording.failure or "interrupted"
                return
            if not thread.is_alive() or time.monotonic() > deadline:
                progress.message("no pose graph: /slam_toolbox/serialize_map did not answer within "
                                 f"{FINAL_MAP_TIMEOUT_S:.0f} s")
                return
        reply = future.result()
        if reply.result != reply.RESULT_SUCCESS:
            progress.message(f"no pose graph: /slam_toolbox/serialize_map could not write {path} "
                             f"(result {reply.result}; the slam node's log says why)")
        elif not path.is_file():  # another slam node answered
            progress.message(f"no pose graph: the slam node answered but {path} is not there")
        else:
            self.recording.posegraph = str(path.resolve())


def default_nav2_params() -> Path:
    """The parameter file the bringup gives Nav2's nodes when ``--params-file`` names none."""
    return config_directory() / "nav2_params.yaml"


# ------------------------------------------------------------ command line
def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = __doc__.strip().splitlines()[0]
    parser.add_argument("scenario", choices=[s.value for s in Scenario],
                        help="map: score a saved map; drive: odometry drift along a route; slam: mapping "
                             "along a route (trajectory and map); localization: AMCL on a saved map from a wrong "
                             "initial pose; navigation: random reachable goals through navigate_to_pose")
    parser.add_argument("--world", default="maze", help="world name or path (default maze)")
    parser.add_argument("--route", default=None, help="route name in the world's routes file (default: the first)")
    parser.add_argument("--route-file", type=Path, default=None,
                        help="routes YAML (default <world>.routes.yaml next to the world)")
    parser.add_argument("--lockstep", action=argparse.BooleanOptionalAction, default=True,
                        help="time advances only when the nodes have done their work for it: the same run on "
                             "any machine, as fast as the machine allows (default; --no-lockstep runs the stack "
                             "against the wall clock at --real-time-factor)")
    parser.add_argument("--real-time-factor", type=float, default=None,
                        help="at most this many sim seconds per wall second (default: 0, as fast as possible, in "
                             "lockstep; without lockstep 3 for the route scenarios and 1 for navigation, what the "
                             "nodes keep up with on 2 cores)")
    parser.add_argument("--seed", type=int, default=0, help="seed of sensor noise and wheel slip (default 0)")
    parser.add_argument("--wheel-slip", type=float, default=0.01,
                        help="wheel slip standard deviation, fraction of travel (default 0.01)")
    parser.add_argument("--speed", type=float, default=0.3, help="route driving speed in m/s (default 0.3)")
    parser.add_argument("--timeout", type=float, default=None,
                        help="give up after this many sim seconds (default 2.5 × route time + 60)")
    parser.add_argument("--out", type=Path, default=None,
                        help="report directory (default eval_<scenario>_<world>_YYYY_MM_DD-HH_MM_SS)")
    parser.add_argument("--map", type=Path, default=None,
                        help="map: the Nav2 map YAML to score; localization: the map to localize on "
                             "(default maps/<world>.yaml)")
    parser.add_argument("--params-file", type=Path, default=None,
                        help="localization, navigation: Nav2's parameters (launch_sim's params_file:=; default "
                             "config/nav2_params.yaml), e.g. to compare planners and controllers")
    parser.add_argument("--map-pose", type=float, nargs=3, default=(0.0, 0.0, 0.0), metavar=("X", "Y", "YAW"),
                        help="map, localization: where the map's frame is in the world (default 0 0 0: the "
                             "world's own frame, which is the default spawn pose where mapping starts)")
    parser.add_argument("--initial-offset", type=float, nargs=3, default=(0.35, 0.35, 0.3),
                        metavar=("DX", "DY", "DYAW"),
                        help="localization: how far off the initial pose sent to AMCL is (default 0.35 0.35 0.3: "
                             "0.5 m and 0.3 rad)")
    parser.add_argument("--global", dest="global_localization", action="store_true",
                        help="localization: start AMCL with global localization (particles over the whole map)")
    parser.add_argument("--goals", type=int, default=50, help="navigation: how many goals (default 50)")
    parser.add_argument("--goal-distance", type=float, default=2.0,
                        help="navigation: each goal at least this far (m, straight line) from the one before "
                             "(default 2)")
    parser.add_argument("--start", type=float, nargs=3, default=(0.0, 0.0, 0.0), metavar=("X", "Y", "YAW"),
                        help="navigation: the spawn pose in the world, also AMCL's initial pose (default 0 0 0)")
    parser.add_argument("--goal", type=float, nargs=3, default=None, metavar=("X", "Y", "YAW"),
                        help="navigation: this one goal (world frame) instead of random ones; with --no-map the "
                             "default is the end of the world's first route (a clutter world's crossing)")
    parser.add_argument("--no-map", action="store_true",
                        help="navigation: no map_server or AMCL; Nav2 navigates in odom, its global costmap "
                             "rolling with the robot from the lidar, and a goal counts when the robot comes within "
                             "1 m of it without touching anything (BARN's rule; scored with BARN's metric)")
    parser.add_argument("--through-poses", action="store_true",
                        help="navigation: send each goal as a one-pose navigate_through_poses goal (bt_navigator's "
                             "through-poses tree) instead of navigate_to_pose")
    parser.add_argument("--min-success-rate", type=float, default=0.98,
                        help="navigation: the report is ok from this success rate on (default 0.98)")
    parser.add_argument("--view", action=argparse.BooleanOptionalAction, default=False,
                        help="save the live view of the run (map, scan, robot, plans, particles, SLAM graph, "
                             "on sim time) as a rerun recording, view.rrd beside the plots: open it with "
                             "./pppbot view view.rrd (off by default: it costs CPU and disk)")
    parser.add_argument("--json", action="store_true", help="print the report as one JSON object on the last line")
    parser.add_argument("--log-level", default="info", choices=("debug", "info", "warn", "error", "fatal"),
                        help="log level of the stack's nodes (default info; their output goes to the log "
                             "directory, warnings and errors also to stderr; below info, twist_mux's "
                             "readiness line is not printed)")


def _output_dir(config: EvalConfig, world_file: Path) -> Path:
    """``--out`` or a new name; an existing file or non-empty directory is refused.

    Raises:
        ArgumentError: ``--out`` exists and is not an empty directory.
    """
    stamp = time.strftime("%Y_%m_%d-%H_%M_%S")
    out: Path = config.out or Path(f"eval_{config.scenario.value}_{world_file.stem}_{stamp}")
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ArgumentError(f"--out {out}: exists and is not an empty directory; a report is never overwritten")
    return out


def _print_report(result: dict[str, Any], line: str, as_json: bool) -> None:
    if as_json:
        print(line)
    else:
        for key, value in result.items():
            print(f"{key:>26}: {value:.4g}" if isinstance(value, float) else f"{key:>26}: {value}")


def _score_map(config: EvalConfig, world_file: Path) -> int:
    out = _output_dir(config, world_file)
    created = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
        assert config.map is not None  # EvalConfig.checked: the map scenario has one
        result = score_saved_map(config.map, world_file, config.map_pose, out)
    except (MapFileError, MapQualityError) as exc:
        print(f"pppbot eval map: {exc}", file=sys.stderr)
        if created and out.is_dir() and not any(out.iterdir()):
            out.rmdir()  # no report: leave no empty folder behind
        return 2
    _print_report(result, write_json(out / "report.json", result), config.json)
    return 0


def _one_goal(goal: tuple[float, float, float], config: EvalConfig,
              truth_map: OccupancyGrid) -> tuple[float, float, float]:
    """``goal``, checked: reachable from the start, and (without a map) within the rolling window's reach.

    Raises:
        ArgumentError: naming the goal and what is wrong.
    """
    x, y = goal[:2]
    if shortest_path_m(truth_map, config.start[:2], (x, y)) is None:
        raise ArgumentError(f"goal ({x:g}, {y:g}): ppp_bot cannot reach it from the start ({config.start[0]:g}, "
                            f"{config.start[1]:g}) in this world (no path keeps its footprint clear)")
    reach = math.dist(config.start[:2], (x, y))
    if config.no_map and window_size_m(reach) > MAX_WINDOW_M:
        raise ArgumentError(f"goal ({x:g}, {y:g}) is {reach:.1f} m from the start: without a map the global costmap "
                            f"is a window holding both, at most {MAX_WINDOW_M} m across (goals within "
                            f"{MAX_WINDOW_M / 2 - WINDOW_MARGIN_M:g} m)")
    return goal


def _route_end(config: EvalConfig, world_file: Path) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """The start and goal of a map-less run without ``--goal``: the world's route (``--route``, or the
    first: a clutter world's crossing) from its start to where it ends, facing along its last leg.

    Raises:
        RouteError: no routes file, or no such route (the message says to give ``--goal``).
    """
    path = config.route_file or routes_file(world_file)
    if not path.is_file():
        raise RouteError(f"--no-map without --goal takes the goal from the world's route, but {path} does not "
                         "exist: give --goal X Y YAW")
    route = select_route(load_routes(path), config.route, path)
    (x0, y0), (x1, y1) = route.points[-2], route.points[-1]
    return route.start, (float(x1), float(y1), math.atan2(y1 - y0, x1 - x0))


def _own_domain(tries: int = 8) -> int:
    """A ROS domain for this run: claimed (a lock no other pppbot run, a batch's among them, takes) and
    without nodes on it (a stack started by hand holds no lock).

    Raises:
        RuntimeError: ``tries`` claimed domains all have nodes on them.
    """
    for _ in range(tries):
        try:
            return free_domain([claim_domain_id()])
        except RuntimeError:
            continue
    raise RuntimeError(f"the {tries} ROS domains tried have nodes on them")


def main(args: argparse.Namespace) -> int:
    goals = None
    try:
        config = EvalConfig.from_flags(args, MAX_SLIP_STDDEV)
        scenario = config.scenario
        world_file = find_world(config.world)
        if scenario is Scenario.MAP:
            return _score_map(config, world_file)
        if scenario is Scenario.NAVIGATION:
            route = None
            truth_map = world_truth(world_file)
            if config.goal is not None or config.no_map:
                if config.goal is None:
                    start, goal = _route_end(config, world_file)
                    config = dataclasses.replace(config, start=start)
                goals = [_one_goal(config.goal or goal, config, truth_map)]
            else:
                goals = sample_goals(truth_map, config.start[:2], config.goals, np.random.default_rng(config.seed),
                                     min_distance_m=config.goal_distance)
        else:
            route_path = config.route_file or routes_file(world_file)
            route = select_route(load_routes(route_path), config.route, route_path)
            truth_map = world_truth(world_file, route)
        scored = ScoredParameters.read(config.params_file or default_nav2_params())
        out = _output_dir(config, world_file)
        out.mkdir(parents=True, exist_ok=True)
    except (ArgumentError, RouteError, GoalSamplingError, WorldError, DescriptionError, ValueError) as exc:
        print(f"pppbot eval: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"pppbot eval: --out {exc.filename or args.out}: {exc.strerror or exc}", file=sys.stderr)
        return 2
    os.environ["PYTHONUNBUFFERED"] = "1"
    if "ROS_DOMAIN_ID" not in os.environ:  # a domain of its own: nothing else's nodes mix with the run's
        try:
            domain = _own_domain()
        except RuntimeError as exc:
            print(f"pppbot eval: {exc}; set ROS_DOMAIN_ID to one that is free", file=sys.stderr)
            return 2
        os.environ["ROS_DOMAIN_ID"] = str(domain)
        print(f"pppbot eval: on ROS_DOMAIN_ID={domain}, which nothing else uses (set ROS_DOMAIN_ID to choose)",
              file=sys.stderr)
    progress = Progress(sys.stderr, f"{scenario.value} {world_file.stem}/{route.name if route else 'goals'}")
    run = Run(config, world_file, route, out, truth_map, goals, scored=scored)
    # Ctrl-C, SIGTERM, SIGHUP: stop the stack and still write the report.
    previous = {s: signal.signal(s, run.interrupt) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
    try:
        run.execute(progress)
        result = report(run, truth_map)
        line = write_json(out / "report.json", result)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    _print_report(result, line, config.json)
    if run.interrupted:
        return 130
    return 0 if result["ok"] else 1


def main_argv(argv: list[str]) -> int:
    """``pppbot eval``: a scenario, or ``batch`` (:mod:`pppbot_eval.ros.batch_cli`)."""
    if argv[:1] == ["batch"]:
        from pppbot_eval.ros import batch_cli
        parser = argparse.ArgumentParser(prog="pppbot eval batch")
        batch_cli.add_arguments(parser)
        try:
            return batch_cli.main(parser.parse_args(argv[1:]))
        except KeyboardInterrupt:  # before the batch's own handler is in place: nothing runs yet
            return 130
    parser = argparse.ArgumentParser(prog="pppbot eval", formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog="pppbot eval batch SPEC.yaml runs many scenarios, several at once or on "
                                            "a Ray cluster (pppbot eval batch --help)")
    add_arguments(parser)
    try:
        return main(parser.parse_args(argv))
    except KeyboardInterrupt:  # before the run's own handler is in place
        return 130
