"""``planner_server``: global paths on the global costmap, in Nav2's ``planner_server`` place.

Runs the ``global_costmap`` (:mod:`pppbot_nav.ros.costmap_node`) in the same process, as Nav2
does. Serves ``compute_path_to_pose`` (nav2_msgs/action/ComputePathToPose: from the robot's
pose, or ``start`` with ``use_start``) and ``compute_path_through_poses`` (through each of
``goals`` in turn, one plan per leg), and publishes each path on ``plan`` (nav_msgs/Path, in
the costmap's frame; each pose faces along the path, the last one the goal's heading). The
planner is :mod:`pppbot_nav.planner.grid_astar` under the plugin name ``GridBased``; its
failures come back as the action's error codes (START_OCCUPIED, GOAL_OCCUPIED, NO_VALID_PATH,
TIMEOUT, START/GOAL_OUTSIDE_MAP, TF_ERROR) with a message.
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
from nav_msgs.msg import Path
from rclpy.action import ActionServer
from rclpy.action.server import ServerGoalHandle
from rclpy.duration import Duration

from pppbot_common.params import ParameterError, param
from pppbot_common.ros.lifecycle import ManagedNode
from pppbot_common.ros.node_main import run_nodes
from pppbot_common.ros.params import declare_parameters
from pppbot_common.se2 import quaternion_from_yaw, yaw_from_quaternion
from pppbot_common.transforms import TransformError, compose
from pppbot_nav.planner import errors
from pppbot_nav.planner.grid_astar import GridPlanner, PlannerSettings
from pppbot_nav.planner.smoother import SmootherSettings
from pppbot_nav.ros.costmap_node import CostmapNode

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
PLANNER_ID = "GridBased"


@dataclass(frozen=True)
class PlannerServerParameters:
    planner_plugins: list = param([PLANNER_ID], f"planner names (pppbot has one: {PLANNER_ID})")
    tolerance: float = param(0.5, "how far the goal may move to a reachable cell (m)", "GridBased.tolerance")
    allow_unknown: bool = param(True, "plan through unknown space", "GridBased.allow_unknown")
    cost_travel_multiplier: float = param(2.0, "travel cost of a cell: 1 + this · cost / 252",
                                          "GridBased.cost_travel_multiplier")
    max_planning_time: float = param(2.0, "a plan taking longer fails with TIMEOUT (s)", "GridBased.max_planning_time")
    near_obstacle_cost: int = param(180, "cells of this cost or more (below inscribed) weigh near_obstacle_penalty "
                                    "times more", "GridBased.near_obstacle_cost")
    near_obstacle_penalty: float = param(10.0, "weight factor of the near-obstacle band (1: no band)",
                                         "GridBased.near_obstacle_penalty")
    smooth_path: bool = param(True, "straighten and smooth the cell path", "GridBased.smooth_path")
    w_data: float = param(0.2, "smoother: pull toward the original path", "GridBased.smoother.w_data")
    w_smooth: float = param(0.3, "smoother: pull toward the neighbours", "GridBased.smoother.w_smooth")

    def validate(self) -> None:
        if list(self.planner_plugins) != [PLANNER_ID]:
            raise ParameterError("planner_plugins", self.planner_plugins, f"must be ['{PLANNER_ID}']")
        self.settings().validate()

    def settings(self) -> PlannerSettings:
        return PlannerSettings(self.tolerance, self.allow_unknown, self.cost_travel_multiplier,
                               self.max_planning_time, self.near_obstacle_cost, self.near_obstacle_penalty,
                               self.smooth_path, SmootherSettings(w_data=self.w_data, w_smooth=self.w_smooth))


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
        self.params = declare_parameters(self, PlannerServerParameters)
        self.costmap_node = CostmapNode("global_costmap")
        self.composed_nodes = [self.costmap_node]
        self.planner = GridPlanner(self.params.settings())
        self.plan_pub = self.create_publisher(Path, "plan", 1)
        self.server = ActionServer(self, ComputePathToPose, "compute_path_to_pose",
                                   lambda handle: self._execute(handle, ComputePathToPose, self.compute),
                                   goal_callback=self.gated())
        self.through_server = ActionServer(self, ComputePathThroughPoses, "compute_path_through_poses",
                                           lambda handle: self._execute(handle, ComputePathThroughPoses,
                                                                        self.compute_through),
                                           goal_callback=self.gated())
        self.get_logger().info(f"planner '{PLANNER_ID}' ready on global_costmap")

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
        except errors.PlannerError as exc:
            result.error_code = getattr(result, ERROR_NAMES.get(type(exc), "UNKNOWN"))
            result.error_msg = str(exc)
        except TransformError as exc:
            result.error_code, result.error_msg = result.TF_ERROR, str(exc)
        except RuntimeError as exc:  # no costmap yet
            result.error_code, result.error_msg = result.UNKNOWN, str(exc)
        result.planning_time = Duration(seconds=time.perf_counter() - t0).to_msg()
        if result.error_code == result.NONE:
            goal_handle.succeed()
        else:
            self.get_logger().warning(f"planning failed: {result.error_msg}")
            goal_handle.abort()
        return result

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
        if request.planner_id not in ("", PLANNER_ID):
            raise errors.PlannerError(f"unknown planner_id '{request.planner_id}' (pppbot has '{PLANNER_ID}')")
        costmap = self.costmap_node.update()
        if costmap is None:
            raise RuntimeError("the global costmap has no map yet")
        self.planner.set_costmap(costmap)
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
            plan = self.planner.plan(here, (goal[0], goal[1]))
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
