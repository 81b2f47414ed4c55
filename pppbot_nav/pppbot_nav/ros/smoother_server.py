"""``smoother_server``: smooths given paths, in Nav2's ``smoother_server`` place.

Serves ``smooth_path`` (nav2_msgs/action/SmoothPath) while active and publishes each smoothed
path on ``plan_smoothed`` (nav_msgs/Path), as Nav2's server does. Smoothers are chosen by name:
``smoother_plugins`` names them, ``<name>.plugin`` gives each one's Nav2 plugin type, looked up
in :data:`SMOOTHERS` at configure (an unknown type fails the configure, naming the known ones).
pppbot has ``nav2_smoother::SimpleSmoother`` (:mod:`pppbot_nav.planner.simple_smoother`) under
the name ``simple_smoother``; a goal's empty ``smoother_id`` picks it.

The costmap is the latched ``costmap_topic`` (nav_msgs/OccupancyGrid, 0-100): the smoother keeps
points off its inscribed and lethal cells, and a goal with ``check_for_collisions`` fails with
SMOOTHED_PATH_IN_COLLISION when a smoothed pose is on one (or off the map). Poses are taken in
the costmap's frame, as Nav2 takes them. Failures come back as the action's error codes:
INVALID_SMOOTHER (an unknown ``smoother_id``), INVALID_PATH (no poses, or a non-finite one),
TIMEOUT (longer than ``max_smoothing_duration`` of compute time: a zero duration times out, as
in Nav2), SMOOTHED_PATH_IN_COLLISION, UNKNOWN (no costmap yet). A path too short to smooth
(segments of :data:`~pppbot_nav.planner.simple_smoother.MIN_SEGMENT_POSES` poses or fewer) comes
back unchanged. ``was_completed`` is False when a collision or ``max_its`` stopped the smoothing
early: the goal still succeeds, with the path smoothed that far.

``robot_base_frame`` is declared for Nav2's configurations; pppbot's collision check needs no
footprint (an inscribed cell is where the robot's circle touches an obstacle).
"""
from __future__ import annotations

import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from geometry_msgs.msg import PoseStamped
from nav2_msgs.action import SmoothPath
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from nav_msgs.msg import Path
from rclpy.action.server import ServerGoalHandle
from rclpy.duration import Duration

from pppbot_common.maps import OccupancyGrid
from pppbot_common.params import ParameterError, param
from pppbot_common.ros.maps import grid_from_message
from pppbot_common.ros.params import declare_parameters, fixed_parameters
from pppbot_common.ros.qos import LATCHED
from pppbot_common.se2 import quaternion_from_yaw, yaw_from_quaternion
from pppbot_lockstep.ros.lifecycle import ManagedNode
from pppbot_lockstep.ros.node import StepActionServer
from pppbot_lockstep.ros.runner import guarded, run_nodes
from pppbot_nav.errors import SmootherError, SmootherTimedOut
from pppbot_nav.planner.simple_smoother import (
    SimpleSmootherSettings,
    SmoothedPath,
    blocked_cells,
    first_collision,
    smooth_path,
)

SIMPLE_SMOOTHER = "simple_smoother"
SIMPLE_SMOOTHER_TYPE = "nav2_smoother::SimpleSmoother"

#: A smoother: (x, y) points (N, 2), headings (N,), the costmap, the time allowed (s) → the smoothed path.
Smoother = Callable[[np.ndarray, np.ndarray, OccupancyGrid, float], SmoothedPath]


def _simple_smoother(settings: SimpleSmootherSettings) -> Smoother:
    def smooth(points_xy: np.ndarray, yaws_rad: np.ndarray, costmap: OccupancyGrid, max_s: float) -> SmoothedPath:
        return smooth_path(points_xy, yaws_rad, settings, clock_s=time.monotonic, max_duration_s=max_s,
                           blocked=blocked_cells(costmap))
    return smooth


#: Smoothers by Nav2 plugin type, each made from its settings.
SMOOTHERS: dict[str, Callable[[SimpleSmootherSettings], Smoother]] = {
    SIMPLE_SMOOTHER_TYPE: _simple_smoother,
}


@dataclass(frozen=True)
class SmootherServerParameters:
    smoother_plugins: list = param([SIMPLE_SMOOTHER], f"smoother names (pppbot has one: {SIMPLE_SMOOTHER})")
    plugin: str = param(SIMPLE_SMOOTHER_TYPE, "the smoother's Nav2 plugin type", f"{SIMPLE_SMOOTHER}.plugin")
    tolerance: float = param(1e-10, "a sweep moving the points less than this in sum ends the smoothing (m)",
                             f"{SIMPLE_SMOOTHER}.tolerance")
    max_its: int = param(1000, "sweeps before a segment is given up", f"{SIMPLE_SMOOTHER}.max_its")
    w_data: float = param(0.2, "pull toward the original path", f"{SIMPLE_SMOOTHER}.w_data")
    w_smooth: float = param(0.3, "pull toward the neighbours", f"{SIMPLE_SMOOTHER}.w_smooth")
    do_refinement: bool = param(True, "smooth the smoothed path again", f"{SIMPLE_SMOOTHER}.do_refinement")
    refinement_num: int = param(2, "refinements with do_refinement", f"{SIMPLE_SMOOTHER}.refinement_num")
    costmap_topic: str = param("global_costmap/costmap", "the costmap (nav_msgs/OccupancyGrid, latched)")
    robot_base_frame: str = param("base_link", "the robot's frame (Nav2's footprint frame; unused here)")

    def validate(self) -> None:
        if list(self.smoother_plugins) != [SIMPLE_SMOOTHER]:
            raise ParameterError("smoother_plugins", self.smoother_plugins, f"must be ['{SIMPLE_SMOOTHER}']")
        if not self.costmap_topic:
            raise ParameterError("costmap_topic", self.costmap_topic, "must name a topic")
        self.settings().validate(SIMPLE_SMOOTHER)

    def settings(self) -> SimpleSmootherSettings:
        return SimpleSmootherSettings(self.tolerance, self.max_its, self.w_data, self.w_smooth,
                                      self.do_refinement, self.refinement_num)


def load_smoother(plugin_type: str, settings: SimpleSmootherSettings) -> Smoother:
    """The smoother of Nav2 plugin type ``plugin_type``.

    Raises:
        SmootherError: an unknown type; the message lists the known ones.
    """
    factory = SMOOTHERS.get(plugin_type)
    if factory is None:
        raise SmootherError(f"{SIMPLE_SMOOTHER}.plugin '{plugin_type}' is not a smoother pppbot has: "
                            + ", ".join(f"'{name}'" for name in SMOOTHERS))
    return factory(settings)


class _Failure(Exception):  # noqa: N818 (a result code carrier, not an error record)
    def __init__(self, code: int, message: str) -> None:
        super().__init__(message)
        self.code = code


def path_arrays(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(x, y) (N, 2) and yaw (N,) of a path's poses."""
    xy = np.array([[p.pose.position.x, p.pose.position.y] for p in path.poses], dtype=float).reshape(-1, 2)
    yaws = np.array([yaw_from_quaternion(p.pose.orientation.x, p.pose.orientation.y, p.pose.orientation.z,
                                         p.pose.orientation.w) for p in path.poses], dtype=float)
    return xy, yaws


def with_poses(path: Path, points_xy: np.ndarray, yaws_rad: np.ndarray) -> Path:
    """``path`` with its poses moved to ``points_xy`` and turned to ``yaws_rad`` (z and headers kept)."""
    out = Path(header=path.header)
    poses = []
    for original, (x, y), yaw in zip(path.poses, points_xy.tolist(), yaws_rad.tolist(), strict=True):
        pose = PoseStamped(header=original.header)
        pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = x, y, original.pose.position.z
        o = pose.pose.orientation
        o.x, o.y, o.z, o.w = quaternion_from_yaw(yaw)
        poses.append(pose)
    out.poses = poses
    return out


class SmootherServer(ManagedNode):
    """Nav2's ``smoother_server``: a lifecycle node that smooths only while active."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("smoother_server", **kwargs)
        self.params = declare_parameters(self, SmootherServerParameters)
        fixed_parameters(self, lambda: self.params)  # Nav2's has no dynamic parameters
        self.smoother: Smoother | None = None
        self.costmap: OccupancyGrid | None = None
        self.plan_pub = self.create_publisher(Path, "plan_smoothed", 1)
        self.create_subscription(OccupancyGridMsg, self.params.costmap_topic,
                                 guarded(self, self._on_costmap, "OccupancyGrid"), LATCHED)
        self.server = StepActionServer(self, SmoothPath, "smooth_path", self._execute, goal_callback=self.gated())
        self.get_logger().info(f"smoother '{SIMPLE_SMOOTHER}' on {self.params.costmap_topic} once active")

    def destroy_node(self) -> None:
        self.server.destroy()
        super().destroy_node()

    def configure(self) -> None:
        self.smoother = load_smoother(self.params.plugin, self.params.settings())

    def cleanup(self) -> None:
        self.smoother = None

    def _on_costmap(self, msg: OccupancyGridMsg) -> None:
        self.costmap = grid_from_message(msg)

    def _execute(self, goal_handle: ServerGoalHandle) -> SmoothPath.Result:
        request = goal_handle.request
        result = SmoothPath.Result()
        t0 = time.perf_counter()
        try:
            result.path, result.was_completed = self.smooth(request)
            result.error_code = result.NONE
        except _Failure as exc:
            result.error_code, result.error_msg = exc.code, str(exc)
        except Exception as exc:  # a bad goal must not end the node (Nav2: UNKNOWN)
            result.error_code, result.error_msg = result.UNKNOWN, f"{type(exc).__name__}: {exc}"
        result.smoothing_duration = Duration(seconds=time.perf_counter() - t0).to_msg()
        if result.error_code == result.NONE:
            goal_handle.succeed()
        else:
            self.get_logger().warning(f"smoothing failed: {result.error_msg}")
            goal_handle.abort()
        return result

    def smooth(self, request: SmoothPath.Goal) -> tuple[Path, bool]:
        """The smoothed path of a request and whether the smoothing completed.

        Raises:
            _Failure: with the result's error code and a message.
        """
        r = SmoothPath.Result
        if request.smoother_id not in ("", SIMPLE_SMOOTHER):
            raise _Failure(r.INVALID_SMOOTHER, f"unknown smoother_id '{request.smoother_id}': "
                                               f"this server has '{SIMPLE_SMOOTHER}'")
        if self.smoother is None:
            raise _Failure(r.UNKNOWN, "the smoother is not configured")
        if not request.path.poses:
            raise _Failure(r.INVALID_PATH, "the path to smooth is empty")
        costmap = self.costmap
        if costmap is None:
            raise _Failure(r.UNKNOWN, f"no costmap yet on {self.params.costmap_topic}")
        points, yaws = path_arrays(request.path)
        max_s = Duration.from_msg(request.max_smoothing_duration).nanoseconds * 1e-9
        try:
            smoothed = self.smoother(points, yaws, costmap, max_s)
        except SmootherTimedOut as exc:
            raise _Failure(r.TIMEOUT, str(exc)) from exc
        except SmootherError as exc:
            raise _Failure(r.INVALID_PATH, str(exc)) from exc
        path = with_poses(request.path, smoothed.points_xy, smoothed.yaws_rad)
        self.plan_pub.publish(path)
        if request.check_for_collisions:
            hit = first_collision(costmap, smoothed.points_xy)
            if hit is not None:
                x, y = smoothed.points_xy[hit]
                raise _Failure(r.SMOOTHED_PATH_IN_COLLISION, f"the smoothed path collides at pose {hit} "
                                                             f"({x:.2f}, {y:.2f})")
        return path, smoothed.completed


def main(args: list[str] | None = None) -> int:
    return run_nodes([SmootherServer], "smoother_server", args)


if __name__ == "__main__":
    sys.exit(main())
