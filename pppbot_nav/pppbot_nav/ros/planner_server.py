"""``planner_server``: global paths on the global costmap, in Nav2's ``planner_server`` place.

Runs the ``global_costmap`` (:mod:`pppbot_nav.ros.costmap_node`) in the same process, as Nav2
does. Serves ``compute_path_to_pose`` (nav2_msgs/action/ComputePathToPose: from the robot's
pose, or ``start`` with ``use_start``) and ``compute_path_through_poses`` (through each of
``goals`` in turn, one plan per leg), and publishes each path on ``plan`` (nav_msgs/Path, in
the costmap's frame; each pose faces along the path, the last one the goal's heading, or the
last step's with the plugin's ``use_final_approach_orientation``).

Planners are Nav2's plugins by type, found in the ``pppbot_nav.planners`` entry-point group
(pppbot's own in :mod:`pppbot_nav.planner.plugin_settings`, a user's from their package:
:mod:`pppbot_nav.planner.interface`): each name of ``planner_plugins`` is loaded as its
``<name>.plugin`` says (``GridBased`` without one: NavFn,
Nav2's default), its parameters under ``<name>.``; a request's ``planner_id`` picks one (empty:
the only one), an unknown id fails with INVALID_PLANNER. Failures come back as the action's
error codes (START_OCCUPIED, GOAL_OCCUPIED, NO_VALID_PATH, TIMEOUT, START/GOAL_OUTSIDE_MAP,
TF_ERROR) with a message. A plan slower than ``1 / expected_planner_frequency`` is warned of.
Live parameters (``ros2 param set``) are each plugin's dynamic ones in Nav2 (NavFn's tolerance,
use_astar, allow_unknown; Smac's search limits and costs; all of pppbot's A*), applied to the
next plan; the rest are refused with the reason.
"""
from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from geometry_msgs.msg import PoseStamped
from nav2_msgs.action import ComputePathThroughPoses, ComputePathToPose
from nav2_msgs.srv import IsPathValid
from nav_msgs.msg import Path
from rclpy.action.server import ServerGoalHandle
from rclpy.duration import Duration

from pppbot_common.params import ParameterError, check_finite_range, param
from pppbot_common.ros.params import LiveParameters, declare_parameters, serve_live_parameters
from pppbot_common.se2 import quaternion_from_yaw, yaw_from_quaternion
from pppbot_common.transforms import TransformError, compose
from pppbot_lockstep.ros.lifecycle import ManagedNode
from pppbot_lockstep.ros.node import StepActionServer
from pppbot_lockstep.ros.runner import run_nodes
from pppbot_nav.costmap.costs import INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE, NO_INFORMATION
from pppbot_nav.planner import errors
from pppbot_nav.planner.plugin_settings import DEFAULT_PLANNER_TYPES
from pppbot_nav.plugins import plugins
from pppbot_nav.ros.costmap_node import CostmapNode
from pppbot_nav.ros.plugins import Plugin, live_plugin_parameters, load_plugin

#: Each planning failure's error code, by its name in both actions' results (Nav2's 2xx for
#: compute_path_to_pose, 3xx for compute_path_through_poses).
ERROR_NAMES: dict[type[errors.PlannerError], str] = {
    errors.StartOutsideMap: "START_OUTSIDE_MAP",
    errors.GoalOutsideMap: "GOAL_OUTSIDE_MAP",
    errors.StartOccupied: "START_OCCUPIED",
    errors.GoalOccupied: "GOAL_OCCUPIED",
    errors.NoValidPath: "NO_VALID_PATH",
    errors.PlannerTimedOut: "TIMEOUT",
}


class NoViapoints(errors.PlannerError):
    """compute_path_through_poses without goals (Nav2's NO_VIAPOINTS_GIVEN)."""


class InvalidPlanner(errors.PlannerError):
    """A planner_id the server does not have (Nav2's INVALID_PLANNER)."""


@dataclass(frozen=True)
class PlannerServerParameters:
    planner_plugins: list = param(["GridBased"], "planner names; each's type is its <name>.plugin")
    expected_planner_frequency: float = param(1.0, "a plan slower than 1 / this is warned of (Hz; 0: never)")

    def validate(self) -> None:
        if not self.planner_plugins or len(set(self.planner_plugins)) != len(self.planner_plugins):
            raise ParameterError("planner_plugins", self.planner_plugins, "must name at least one planner, each once")
        check_finite_range("expected_planner_frequency", self.expected_planner_frequency, 0.0, 1000.0)


def path_message(points_xy: np.ndarray, goal_yaw: float, frame: str, stamp: Any) -> Path:
    """A nav_msgs/Path: each pose faces the next point; the last one ``goal_yaw``."""
    msg = Path()
    msg.header.frame_id = frame
    msg.header.stamp = stamp
    d = np.diff(points_xy, axis=0)
    yaws = np.append(np.arctan2(d[:, 1], d[:, 0]), goal_yaw) if len(points_xy) > 1 else np.array([goal_yaw])
    poses = []
    for (x, y), yaw in zip(points_xy.tolist(), yaws.tolist(), strict=True):
        pose = PoseStamped()
        pose.header = msg.header
        pose.pose.position.x, pose.pose.position.y = x, y
        o = pose.pose.orientation
        o.x, o.y, o.z, o.w = quaternion_from_yaw(yaw)
        poses.append(pose)
    msg.poses = poses
    return msg


def planar_pose(msg: PoseStamped) -> tuple[float, float, float]:
    o = msg.pose.orientation
    return msg.pose.position.x, msg.pose.position.y, yaw_from_quaternion(o.x, o.y, o.z, o.w)


class PlannerServer(ManagedNode):
    """A lifecycle node, as Nav2's: it plans only while active."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("planner_server", **kwargs)
        self.params = p = declare_parameters(self, PlannerServerParameters)
        self.plugins = {name: load_plugin(self, name, plugins("planner"), DEFAULT_PLANNER_TYPES.get(name))
                        for name in p.planner_plugins}
        self.planners = {name: plugin.params.make() for name, plugin in self.plugins.items()}
        self.costmap_node = CostmapNode("global_costmap", port=self.port)
        self.composed_nodes = [self.costmap_node]
        self.plan_pub = self.create_publisher(Path, "plan", 1)
        self.server = StepActionServer(self, ComputePathToPose, "compute_path_to_pose",
                                   lambda handle: self._execute(handle, ComputePathToPose, self.compute),
                                   goal_callback=self.gated())
        self.through_server = StepActionServer(self, ComputePathThroughPoses, "compute_path_through_poses",
                                           lambda handle: self._execute(handle, ComputePathThroughPoses,
                                                                        self.compute_through),
                                           goal_callback=self.gated())
        self.create_service(IsPathValid, "is_path_valid", self._is_path_valid)
        serve_live_parameters(self, [LiveParameters("", lambda: self.params, self._set_params,
                                                    {"expected_planner_frequency"}),
                                     *live_plugin_parameters(self.plugins, self._set_planner_params)])
        kinds = ", ".join(f"'{name}' ({plugin.type_name})" for name, plugin in self.plugins.items())
        self.get_logger().info(f"planners {kinds} ready on global_costmap")

    def _set_params(self, new: PlannerServerParameters) -> None:
        self.params = new

    def _set_planner_params(self, name: str, new: Any) -> None:
        """A planner's new settings; the next plan uses them (a planner keeps no state between plans)."""
        old = self.plugins[name]
        self.plugins[name] = Plugin(name, old.type_name, new)
        self.planners[name] = new.make()

    def destroy_node(self) -> None:
        self.server.destroy()
        self.through_server.destroy()
        self.costmap_node.destroy_node()
        super().destroy_node()

    def _in_costmap_frame(self, msg: PoseStamped) -> tuple[float, float, float]:
        frame = self.costmap_node.params.global_frame
        pose = planar_pose(msg)
        source = msg.header.frame_id.lstrip("/") or frame
        if source == frame:
            return pose
        return compose(self.costmap_node.tf.lookup(frame, source), pose)

    def _is_path_valid(self, request: IsPathValid.Request, response: IsPathValid.Response) -> IsPathValid.Response:
        """Nav2's ``is_path_valid``: the path from its pose closest to the robot on is valid unless one
        of those poses is on a lethal or inscribed cell of the global costmap (an unknown cell or
        one off the map does not count), or it is empty; ``invalid_pose_indices`` lists each that is."""
        costmap = self.costmap_node.update() if self.active else None
        robot = self.costmap_node.robot_pose()
        if costmap is None or not request.path.poses:  # an empty path is no path (Nav2's)
            response.is_valid = False
            return response
        try:
            xy = np.array([self._in_costmap_frame(pose)[:2] for pose in request.path.poses])
        except TransformError as exc:
            self.get_logger().warning(f"is_path_valid: the path's frame is not known: {exc}")
            response.is_valid = False
            return response
        first = int(np.argmin(np.hypot(xy[:, 0] - robot[0], xy[:, 1] - robot[1]))) if robot is not None else 0
        costs = costmap.cost_at(xy[first:, 0], xy[first:, 1], outside=NO_INFORMATION)
        blocked = np.flatnonzero((costs == LETHAL_OBSTACLE) | (costs == INSCRIBED_INFLATED_OBSTACLE)) + first
        response.invalid_pose_indices = [int(i) for i in blocked]
        response.is_valid = len(blocked) == 0
        return response

    def _execute(self, goal_handle: ServerGoalHandle, action: Any, compute: Any) -> Any:
        """One goal of ``action`` (either planning action), planned by ``compute``, with its error codes."""
        request = goal_handle.request
        result = action.Result()
        t0 = time.perf_counter()
        try:
            result.path, result.error_msg = compute(request)
            result.error_code = result.NONE
        except NoViapoints as exc:
            result.error_code, result.error_msg = result.NO_VIAPOINTS_GIVEN, str(exc)
        except InvalidPlanner as exc:
            result.error_code, result.error_msg = result.INVALID_PLANNER, str(exc)
        except errors.PlannerError as exc:
            result.error_code = getattr(result, ERROR_NAMES.get(type(exc), "UNKNOWN"))
            result.error_msg = str(exc)
        except TransformError as exc:
            result.error_code, result.error_msg = result.TF_ERROR, str(exc)
        except RuntimeError as exc:  # no costmap yet
            result.error_code, result.error_msg = result.UNKNOWN, str(exc)
        took_s = time.perf_counter() - t0
        result.planning_time = Duration(seconds=took_s).to_msg()
        rate = self.params.expected_planner_frequency
        if rate > 0 and took_s > 1.0 / rate:
            self.get_logger().warning(f"planning took {took_s:.3f} s, longer than 1 / expected_planner_frequency "
                                      f"({1.0 / rate:.3f} s)")
        if result.error_code == result.NONE:
            goal_handle.succeed()
        else:
            self.get_logger().warning(f"planning failed: {result.error_msg}")
            goal_handle.abort()
        return result

    def _planner_name(self, planner_id: str) -> str:
        return planner_id or next(iter(self.planners))

    def planner_for(self, planner_id: str) -> Any:
        """The planner a request names; with one planner, an empty id names it (as Nav2).

        Raises:
            InvalidPlanner: an id the server does not have.
        """
        if planner_id in self.planners:
            return self.planners[planner_id]
        if not planner_id and len(self.planners) == 1:
            return next(iter(self.planners.values()))
        raise InvalidPlanner(f"planner_id '{planner_id}' is not one of this server's: {', '.join(self.planners)}")

    def compute(self, request: ComputePathToPose.Goal) -> tuple[Path, str]:
        """The path for a request and a note ('' or where the goal moved to).

        Raises:
            PlannerError: a typed planning failure. TransformError: a pose cannot be placed
            in the costmap's frame. RuntimeError: no costmap yet.
        """
        return self._plan_through(request, [request.goal])

    def compute_through(self, request: ComputePathThroughPoses.Goal) -> tuple[Path, str]:
        """A path through every goal of a compute_path_through_poses request, in order: one plan
        per leg, each from where the last one ended (as Nav2's planner server chains them)."""
        if not request.goals:
            raise NoViapoints("no goals to plan through")
        return self._plan_through(request, list(request.goals))

    def _plan_through(self, request: Any, goals: list[PoseStamped]) -> tuple[Path, str]:
        planner = self.planner_for(request.planner_id)
        final_approach = getattr(self.plugins[self._planner_name(request.planner_id)].params,
                                 "use_final_approach_orientation", False)
        costmap = self.costmap_node.update()
        if costmap is None:
            raise RuntimeError("the global costmap has no map yet")
        planner.set_costmap(costmap)
        if request.use_start:
            start = self._in_costmap_frame(request.start)
        else:
            pose = self.costmap_node.robot_pose()
            if pose is None:
                raise TransformError(f"no robot pose in '{costmap.frame_id}'")
            start = pose
        legs: list[np.ndarray] = []
        notes: list[str] = []
        here = (start[0], start[1])
        for i, goal_msg in enumerate(goals):
            goal = self._in_costmap_frame(goal_msg)
            plan = planner.plan(here, (goal[0], goal[1]))
            if final_approach and len(plan.points_xy) > 1:
                step = plan.points_xy[-1] - plan.points_xy[-2]
                goal = (goal[0], goal[1], math.atan2(step[1], step[0]))
            legs.append(plan.points_xy if not legs else plan.points_xy[1:])
            moved = math.hypot(plan.goal_xy[0] - goal[0], plan.goal_xy[1] - goal[1])
            if moved > 1e-6:
                notes.append(f"goal{f' {i + 1}' if len(goals) > 1 else ''} moved {moved:.2f} m to a reachable cell")
            here = (float(plan.goal_xy[0]), float(plan.goal_xy[1]))
        points = np.vstack([leg for leg in legs if len(leg)])
        msg = path_message(points, goal[2], costmap.frame_id, self.get_clock().now().to_msg())
        self.plan_pub.publish(msg)
        return msg, "; ".join(notes)


def main(args: list[str] | None = None) -> int:
    return run_nodes([PlannerServer], "planner_server", args)


if __name__ == "__main__":
    sys.exit(main())
