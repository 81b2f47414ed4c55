"""``BasicNavigator`` for environments without ``nav2_simple_commander`` (it is not on PyPI).

The examples import Nav2's own ``nav2_simple_commander.robot_navigator`` when it is installed
(a ROS 2 Jazzy install) and this module otherwise. It has the same class, methods, arguments,
defaults and return values as Jazzy's, and makes the same calls on the same public interfaces:
lifecycle ``get_state`` services, the ``initialpose`` topic and ``amcl_pose``, Nav2's action
names (navigate_to_pose, navigate_through_poses, follow_waypoints, compute_path_to_pose,
compute_path_through_poses, smooth_path, spin, backup, drive_on_heading, assisted_teleop),
map_server's ``load_map``, the costmaps' ``clear_entirely_*`` and ``get_costmap`` services,
and the lifecycle managers' ``manage_nodes``. It imports nothing of pppbot: a script that
works with it works with Nav2's.
"""
from __future__ import annotations

import time
from enum import Enum
from typing import Any

import rclpy
from action_msgs.msg import GoalStatus
from builtin_interfaces.msg import Duration
from geometry_msgs.msg import Point, PoseStamped, PoseWithCovarianceStamped
from lifecycle_msgs.srv import GetState
from nav2_msgs.action import (
    AssistedTeleop,
    BackUp,
    ComputePathThroughPoses,
    ComputePathToPose,
    DriveOnHeading,
    FollowWaypoints,
    NavigateThroughPoses,
    NavigateToPose,
    SmoothPath,
    Spin,
)
from nav2_msgs.srv import ClearEntireCostmap, GetCostmap, LoadMap, ManageLifecycleNodes
from nav_msgs.msg import Path
from rclpy.action import ActionClient
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

#: seconds a node's get_state answer is waited for before it is asked again
GET_STATE_WAIT_S = 5.0


class TaskResult(Enum):
    UNKNOWN = 0
    SUCCEEDED = 1
    CANCELED = 2
    FAILED = 3


def _duration(seconds: float) -> Duration:
    return Duration(sec=int(seconds), nanosec=int((seconds - int(seconds)) * 1e9))


class BasicNavigator(Node):
    """Nav2's simple commander: each task method sends a goal and returns whether it was accepted;
    ``isTaskComplete()``, ``getFeedback()`` and ``getResult()`` follow it."""

    def __init__(self, node_name: str = "basic_navigator", namespace: str = "") -> None:
        super().__init__(node_name=node_name, namespace=namespace)
        self.initial_pose = PoseStamped()
        self.initial_pose.header.frame_id = "map"
        self.goal_handle: Any = None
        self.result_future: Any = None
        self.feedback: Any = None
        self.status: int | None = None
        latched = QoSProfile(durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE,
                             history=HistoryPolicy.KEEP_LAST, depth=1)
        self.initial_pose_received = False
        self.nav_through_poses_client = ActionClient(self, NavigateThroughPoses, "navigate_through_poses")
        self.nav_to_pose_client = ActionClient(self, NavigateToPose, "navigate_to_pose")
        self.follow_waypoints_client = ActionClient(self, FollowWaypoints, "follow_waypoints")
        self.compute_path_to_pose_client = ActionClient(self, ComputePathToPose, "compute_path_to_pose")
        self.compute_path_through_poses_client = ActionClient(self, ComputePathThroughPoses,
                                                              "compute_path_through_poses")
        self.smoother_client = ActionClient(self, SmoothPath, "smooth_path")
        self.spin_client = ActionClient(self, Spin, "spin")
        self.backup_client = ActionClient(self, BackUp, "backup")
        self.drive_on_heading_client = ActionClient(self, DriveOnHeading, "drive_on_heading")
        self.assisted_teleop_client = ActionClient(self, AssistedTeleop, "assisted_teleop")
        self.localization_pose_sub = self.create_subscription(PoseWithCovarianceStamped, "amcl_pose",
                                                              self._amclPoseCallback, latched)
        self.initial_pose_pub = self.create_publisher(PoseWithCovarianceStamped, "initialpose", 10)
        self.change_maps_srv = self.create_client(LoadMap, "map_server/load_map")
        self.clear_costmap_global_srv = self.create_client(ClearEntireCostmap,
                                                           "global_costmap/clear_entirely_global_costmap")
        self.clear_costmap_local_srv = self.create_client(ClearEntireCostmap,
                                                          "local_costmap/clear_entirely_local_costmap")
        self.get_costmap_global_srv = self.create_client(GetCostmap, "global_costmap/get_costmap")
        self.get_costmap_local_srv = self.create_client(GetCostmap, "local_costmap/get_costmap")

    def destroyNode(self) -> None:  # noqa: N802 (Nav2's name)
        self.destroy_node()

    # -------------------------------------------------------------------- tasks
    def setInitialPose(self, initial_pose: PoseStamped) -> None:  # noqa: N802
        self.initial_pose_received = False
        self.initial_pose = initial_pose
        self._setInitialPose()

    def _send(self, client: ActionClient, goal: Any, what: str, feedback: bool = True) -> bool:
        self.debug(f"Waiting for '{client._action_name}' action server")
        while not client.wait_for_server(timeout_sec=1.0):
            self.info(f"'{client._action_name}' action server not available, waiting...")
        self.info(what)
        future = client.send_goal_async(goal, self._feedbackCallback if feedback else None)
        rclpy.spin_until_future_complete(self, future)
        self.goal_handle = future.result()
        if not self.goal_handle.accepted:
            self.error(f"{what} was rejected!")
            return False
        self.result_future = self.goal_handle.get_result_async()
        return True

    def goThroughPoses(self, poses: list[PoseStamped], behavior_tree: str = "") -> bool:  # noqa: N802
        goal = NavigateThroughPoses.Goal(poses=poses, behavior_tree=behavior_tree)
        return self._send(self.nav_through_poses_client, goal, f"Navigating with {len(poses)} goals....")

    def goToPose(self, pose: PoseStamped, behavior_tree: str = "") -> bool:  # noqa: N802
        goal = NavigateToPose.Goal(pose=pose, behavior_tree=behavior_tree)
        return self._send(self.nav_to_pose_client, goal,
                          f"Navigating to goal: {pose.pose.position.x} {pose.pose.position.y}...")

    def followWaypoints(self, poses: list[PoseStamped]) -> bool:  # noqa: N802
        goal = FollowWaypoints.Goal(poses=poses)
        return self._send(self.follow_waypoints_client, goal, f"Following {len(goal.poses)} goals....")

    def spin(self, spin_dist: float = 1.57, time_allowance: int = 10) -> bool:
        goal = Spin.Goal(target_yaw=float(spin_dist), time_allowance=_duration(time_allowance))
        return self._send(self.spin_client, goal, f"Spinning to angle {goal.target_yaw}....")

    def backup(self, backup_dist: float = 0.15, backup_speed: float = 0.025, time_allowance: int = 10) -> bool:
        goal = BackUp.Goal(target=Point(x=float(backup_dist)), speed=float(backup_speed),
                           time_allowance=_duration(time_allowance))
        return self._send(self.backup_client, goal, f"Backing up {goal.target.x} m at {goal.speed} m/s....")

    def driveOnHeading(self, dist: float = 0.15, speed: float = 0.025, time_allowance: int = 10) -> bool:  # noqa: N802
        goal = DriveOnHeading.Goal(target=Point(x=float(dist)), speed=float(speed),
                                   time_allowance=_duration(time_allowance))
        return self._send(self.drive_on_heading_client, goal, f"Drive {goal.target.x} m on heading at "
                                                               f"{goal.speed} m/s....")

    def assistedTeleop(self, time_allowance: int = 30) -> bool:  # noqa: N802
        goal = AssistedTeleop.Goal(time_allowance=_duration(time_allowance))
        return self._send(self.assisted_teleop_client, goal, "Running 'assisted_teleop'....")

    def cancelTask(self) -> None:  # noqa: N802
        self.info("Canceling current task.")
        if self.result_future:
            future = self.goal_handle.cancel_goal_async()
            rclpy.spin_until_future_complete(self, future)

    def isTaskComplete(self) -> bool:  # noqa: N802
        if not self.result_future:
            return True  # task was canceled or completed
        rclpy.spin_until_future_complete(self, self.result_future, timeout_sec=0.10)
        if self.result_future.result():
            self.status = self.result_future.result().status
            if self.status != GoalStatus.STATUS_SUCCEEDED:
                self.debug(f"Task with failed with status code: {self.status}")
                return True
        else:
            return False  # timed out, still processing
        self.debug("Task succeeded!")
        return True

    def getFeedback(self) -> Any:  # noqa: N802
        return self.feedback

    def getResult(self) -> TaskResult:  # noqa: N802
        if self.status == GoalStatus.STATUS_SUCCEEDED:
            return TaskResult.SUCCEEDED
        if self.status == GoalStatus.STATUS_ABORTED:
            return TaskResult.FAILED
        if self.status == GoalStatus.STATUS_CANCELED:
            return TaskResult.CANCELED
        return TaskResult.UNKNOWN

    def waitUntilNav2Active(self, navigator: str = "bt_navigator", localizer: str = "amcl") -> None:  # noqa: N802
        self._waitForNodeToActivate(localizer)
        if localizer == "amcl":
            self._waitForInitialPose()
        self._waitForNodeToActivate(navigator)
        self.info("Nav2 is ready for use!")

    # ---------------------------------------------------------- paths and maps
    def _result_of(self, client: ActionClient, goal: Any, what: str) -> Any:
        if not self._send(client, goal, what, feedback=False):
            return None
        rclpy.spin_until_future_complete(self, self.result_future)
        self.status = self.result_future.result().status
        if self.status != GoalStatus.STATUS_SUCCEEDED:
            self.warn(f"{what} failed with status code: {self.status}")
            return None
        return self.result_future.result().result

    def _getPathImpl(self, start: PoseStamped, goal: PoseStamped, planner_id: str = "",  # noqa: N802
                     use_start: bool = False) -> Any:
        request = ComputePathToPose.Goal(start=start, goal=goal, planner_id=planner_id, use_start=use_start)
        return self._result_of(self.compute_path_to_pose_client, request, "Getting path...")

    def getPath(self, start: PoseStamped, goal: PoseStamped, planner_id: str = "",  # noqa: N802
                use_start: bool = False) -> Path | None:
        result = self._getPathImpl(start, goal, planner_id, use_start)
        return None if result is None else result.path

    def getPathThroughPoses(self, start: PoseStamped, goals: list[PoseStamped], planner_id: str = "",  # noqa: N802
                            use_start: bool = False) -> Path | None:
        request = ComputePathThroughPoses.Goal(start=start, goals=goals, planner_id=planner_id, use_start=use_start)
        result = self._result_of(self.compute_path_through_poses_client, request, "Getting path...")
        return None if result is None else result.path

    def smoothPath(self, path: Path, smoother_id: str = "", max_duration: float = 2.0,  # noqa: N802
                   check_for_collision: bool = False) -> Path | None:
        request = SmoothPath.Goal(path=path, smoother_id=smoother_id, max_smoothing_duration=_duration(max_duration),
                                  check_for_collisions=check_for_collision)
        result = self._result_of(self.smoother_client, request, "Smoothing path...")
        return None if result is None else result.path

    def _call(self, client: Any, request: Any) -> Any:
        while not client.wait_for_service(timeout_sec=1.0):
            self.info(f"{client.srv_name} service not available, waiting...")
        future = client.call_async(request)
        rclpy.spin_until_future_complete(self, future)
        return future.result()

    def changeMap(self, map_filepath: str) -> bool:  # noqa: N802
        response = self._call(self.change_maps_srv, LoadMap.Request(map_url=map_filepath))
        if response.result != LoadMap.Response.RESULT_SUCCESS:
            self.error("Change map request failed!")
            return False
        self.info("Change map request was successful!")
        return True

    def clearAllCostmaps(self) -> None:  # noqa: N802
        self.clearLocalCostmap()
        self.clearGlobalCostmap()

    def clearLocalCostmap(self) -> None:  # noqa: N802
        self._call(self.clear_costmap_local_srv, ClearEntireCostmap.Request())

    def clearGlobalCostmap(self) -> None:  # noqa: N802
        self._call(self.clear_costmap_global_srv, ClearEntireCostmap.Request())

    def getGlobalCostmap(self) -> Any:  # noqa: N802
        return self._call(self.get_costmap_global_srv, GetCostmap.Request()).map

    def getLocalCostmap(self) -> Any:  # noqa: N802
        return self._call(self.get_costmap_local_srv, GetCostmap.Request()).map

    def _managers(self) -> list[str]:
        return [name for name, types in self.get_service_names_and_types()
                if "nav2_msgs/srv/ManageLifecycleNodes" in types]

    def lifecycleStartup(self) -> None:  # noqa: N802
        self._manage(ManageLifecycleNodes.Request.STARTUP, "Starting up lifecycle nodes based on lifecycle_manager.")

    def lifecycleShutdown(self) -> None:  # noqa: N802
        self._manage(ManageLifecycleNodes.Request.SHUTDOWN, "Shutting down lifecycle nodes based on "
                                                            "lifecycle_manager.")

    def _manage(self, command: int, what: str) -> None:
        self.info(what)
        for service in self._managers():
            self.info(f"{service}: {command}")
            self._call(self.create_client(ManageLifecycleNodes, service), ManageLifecycleNodes.Request(command=command))

    # -------------------------------------------------------------- internals
    def _waitForNodeToActivate(self, node_name: str) -> None:  # noqa: N802
        self.debug(f"Waiting for {node_name} to become active..")
        client = self.create_client(GetState, f"{node_name}/get_state")
        while not client.wait_for_service(timeout_sec=1.0):
            self.info(f"{node_name}/get_state service not available, waiting...")
        state = "unknown"
        while state != "active":
            self.debug(f"Getting {node_name} state...")
            future = client.call_async(GetState.Request())
            # Asked again when no answer comes: DDS drops the answer to a client the server has
            # not matched yet (this process just started). pppbot's servers send it again, but a
            # server that does not would leave Nav2's own wait hanging for good.
            rclpy.spin_until_future_complete(self, future, timeout_sec=GET_STATE_WAIT_S)
            if not future.done():
                client.remove_pending_request(future)
                self.info(f"{node_name}/get_state did not answer within {GET_STATE_WAIT_S:.0f} s, asking again")
                continue
            if future.result() is not None:
                state = future.result().current_state.label
                self.debug(f"Result of get_state: {state}")
            time.sleep(2)

    def _waitForInitialPose(self) -> None:  # noqa: N802
        while not self.initial_pose_received:
            self.info("Setting initial pose")
            self._setInitialPose()
            self.info("Waiting for amcl_pose to be received")
            rclpy.spin_once(self, timeout_sec=1.0)

    def _amclPoseCallback(self, msg: PoseWithCovarianceStamped) -> None:  # noqa: N802
        self.debug("Received amcl pose")
        self.initial_pose_received = True

    def _feedbackCallback(self, msg: Any) -> None:  # noqa: N802
        self.debug("Received action feedback message")
        self.feedback = msg.feedback

    def _setInitialPose(self) -> None:  # noqa: N802
        msg = PoseWithCovarianceStamped()
        msg.pose.pose = self.initial_pose.pose
        msg.header.frame_id = self.initial_pose.header.frame_id
        msg.header.stamp = self.initial_pose.header.stamp
        self.info("Publishing Initial Pose")
        self.initial_pose_pub.publish(msg)

    def info(self, msg: str) -> None:
        self.get_logger().info(msg)

    def warn(self, msg: str) -> None:
        self.get_logger().warning(msg)

    def error(self, msg: str) -> None:
        self.get_logger().error(msg)

    def debug(self, msg: str) -> None:
        self.get_logger().debug(msg)
