"""``smoother_server``: smooths given paths, in Nav2's ``smoother_server`` place.

Serves ``smooth_path`` (nav2_msgs/action/SmoothPath) while active and publishes each smoothed
path on ``plan_smoothed`` (nav_msgs/Path), as Nav2's server does. Smoothers are Nav2's plugins
by type, found in the ``pppbot_nav.smoothers`` entry-point group (pppbot's
``nav2_smoother::SimpleSmoother``, :mod:`pppbot_nav.planner.simple_smoother`; a user's from
their package: :mod:`pppbot_nav.planner.smoother_interface`): each name of ``smoother_plugins``
is loaded as its ``<name>.plugin`` says (``simple_smoother`` without one: the SimpleSmoother,
Nav2's default), its parameters under ``<name>.``. A type no installed package exports fails the
configure, naming the group and what is installed in it, as pluginlib fails Nav2's. A goal's
``smoother_id`` picks one; an empty id picks the only one (Nav2's rule: with several, an empty
id is no smoother).

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
footprint (an inscribed cell is where the robot's circle touches an obstacle). Nav2's smoother
server has no dynamic parameters: a set is refused with the reason.
"""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from functools import partial
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
from pppbot_common.ros.params import LiveParameters, declare_parameters, refuse_sets, serve_live_parameters
from pppbot_common.ros.qos import LATCHED
from pppbot_common.se2 import quaternion_from_yaw, yaw_from_quaternion
from pppbot_lockstep.ros.lifecycle import ManagedNode
from pppbot_lockstep.ros.node import StepActionServer
from pppbot_lockstep.ros.runner import guarded, run_nodes
from pppbot_nav.errors import SmootherError, SmootherTimedOut
from pppbot_nav.planner.simple_smoother import first_collision
from pppbot_nav.planner.smoother_interface import Smoother
from pppbot_nav.plugins import plugins
from pppbot_nav.ros.plugins import Plugin, plugin_class, plugin_type

SIMPLE_SMOOTHER = "simple_smoother"
#: Nav2's default smoother type, for ``simple_smoother`` without a ``plugin``.
DEFAULT_SMOOTHER_TYPES = {SIMPLE_SMOOTHER: "nav2_smoother::SimpleSmoother"}


@dataclass(frozen=True)
class SmootherServerParameters:
    smoother_plugins: list = param([SIMPLE_SMOOTHER], "smoother names; each's type is its <name>.plugin")
    costmap_topic: str = param("global_costmap/costmap", "the costmap (nav_msgs/OccupancyGrid, latched)")
    robot_base_frame: str = param("base_link", "the robot's frame (Nav2's footprint frame; unused here)")

    def validate(self) -> None:
        if not self.smoother_plugins or len(set(self.smoother_plugins)) != len(self.smoother_plugins):
            raise ParameterError("smoother_plugins", self.smoother_plugins,
                                 "must name at least one smoother, each once")
        if not all(isinstance(name, str) and name for name in self.smoother_plugins):
            raise ParameterError("smoother_plugins", self.smoother_plugins, "must be names (strings)")
        if not self.costmap_topic:
            raise ParameterError("costmap_topic", self.costmap_topic, "must name a topic")


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


def _params_of(plugin: Plugin) -> Any:
    return plugin.params


def _keep(_: Any) -> None:
    """Nothing to apply: every parameter of the server and its smoothers is fixed while it runs."""


class SmootherServer(ManagedNode):
    """Nav2's ``smoother_server``: a lifecycle node that smooths only while active."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("smoother_server", **kwargs)
        self.params = declare_parameters(self, SmootherServerParameters)
        #: Each smoother's type and parameters, by name; a name whose type is not installed is in
        #: ``type_failures`` instead and fails the configure, as pluginlib fails Nav2's.
        self.plugins: dict[str, Plugin] = {}
        self.type_failures: dict[str, ParameterError] = {}
        group = plugins("smoother")
        for name in self.params.smoother_plugins:
            try:
                type_name = plugin_type(self, name, group, DEFAULT_SMOOTHER_TYPES.get(name))
                cls = plugin_class(name, group, type_name)
            except ParameterError as exc:
                self.type_failures[name] = exc
                continue
            self.plugins[name] = Plugin(name, type_name, declare_parameters(self, cls, prefix=f"{name}."))
        # Nav2's has no dynamic parameters: each group is refused whole.
        serve_live_parameters(self, [LiveParameters("", lambda: self.params, _keep, ()),
                                     *(LiveParameters(f"{name}.", partial(_params_of, plugin), _keep, ())
                                       for name, plugin in self.plugins.items())])
        types = {f"{name}.plugin" for name in self.params.smoother_plugins}
        refuse_sets(self, "a smoother's type is read once, at start-up (as in Nav2); restart the node to change it",
                    allowed=lambda key: key not in types)
        self.smoothers: dict[str, Smoother] = {}
        self.costmap: OccupancyGrid | None = None
        self.plan_pub = self.create_publisher(Path, "plan_smoothed", 1)
        self.create_subscription(OccupancyGridMsg, self.params.costmap_topic,
                                 guarded(self, self._on_costmap, "OccupancyGrid"), LATCHED)
        self.server = StepActionServer(self, SmoothPath, "smooth_path", self._execute, goal_callback=self.gated())
        kinds = ", ".join(f"'{name}' ({plugin.type_name})" for name, plugin in self.plugins.items())
        self.get_logger().info(f"smoothers {kinds} on {self.params.costmap_topic} once active")

    def destroy_node(self) -> None:
        self.server.destroy()
        super().destroy_node()

    def configure(self) -> None:
        """Make each smoother.

        Raises:
            ParameterError: a smoother whose ``<name>.plugin`` names no installed type.
        """
        if self.type_failures:
            raise next(iter(self.type_failures.values()))
        self.smoothers = {name: plugin.params.make() for name, plugin in self.plugins.items()}

    def cleanup(self) -> None:
        self.smoothers = {}

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
        names = self.params.smoother_plugins
        name = request.smoother_id
        if not name and len(names) == 1:
            name = names[0]
        if name not in names:
            given = f"unknown smoother_id '{name}'" if name else "no smoother_id"
            raise _Failure(r.INVALID_SMOOTHER, f"{given}: this server has " + ", ".join(f"'{n}'" for n in names))
        smoother = self.smoothers.get(name)
        if smoother is None:
            raise _Failure(r.UNKNOWN, "the smoother is not configured")
        if not request.path.poses:
            raise _Failure(r.INVALID_PATH, "the path to smooth is empty")
        costmap = self.costmap
        if costmap is None:
            raise _Failure(r.UNKNOWN, f"no costmap yet on {self.params.costmap_topic}")
        points, yaws = path_arrays(request.path)
        max_s = Duration.from_msg(request.max_smoothing_duration).nanoseconds * 1e-9
        try:
            smoothed = smoother.smooth(points, yaws, costmap, clock_s=time.monotonic, max_duration_s=max_s)
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
