"""The collision monitor in the bringup's velocity chain: a box the map does not have, straight in
the robot's way, stops it short.

launch_sim runs ``room_boxes`` (the room with boxes its map lacks) localized on the map without
them, the robot spawned facing the box ``box0`` (0.4 m square, its near face at y = 1.0 m) from
1.2 m. The test drives forward as a controller would, on ``cmd_vel_nav`` (into the
velocity_smoother, then the collision_monitor, then twist_mux), and keeps driving: only the
collision monitor stands between the command and the box.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from geometry_msgs.msg import PointStamped, PolygonStamped, Twist
from nav2_msgs.msg import CollisionMonitorState
from nav_msgs.msg import Odometry

from pppbot_common.ros.qos import LATCHED
from pppbot_common.ros.wait import wait_until

ROOT = Path(__file__).resolve().parents[2]
PPPBOT = str(ROOT / "pppbot")
#: box0's near face (y, m) and the robot's front from base_link (the footprint zone's, m).
BOX_FACE_Y = 1.0
FRONT_M = 0.21


@pytest.mark.ros
def test_a_box_in_the_way_stops_the_robot_short_of_it(ros_node: Any, spawn: Any) -> None:
    launch = spawn([PPPBOT, "launch_sim", "world:=room_boxes", "localization:=true", "x:=0.5", "y:=-0.2",
                    "yaw:=1.5708", "use_teleop:=false", "use_rviz:=false", "use_viz:=false", "lockstep:=true",
                    "real_time_factor:=1.0"], name="launch_sim")
    launch.wait_for_output(r"ppp_bot is up in 'room_boxes'", 90)
    truths: list[Odometry] = []
    states: list[CollisionMonitorState] = []
    zones: list[PolygonStamped] = []
    ros_node.create_subscription(Odometry, "/ground_truth/odom", truths.append, 10)
    ros_node.create_subscription(CollisionMonitorState, "/collision_monitor_state", states.append, 10)
    ros_node.create_subscription(PolygonStamped, "/polygon_footprint_approach", zones.append, LATCHED)
    contacts: list[PointStamped] = []
    ros_node.create_subscription(PointStamped, "/ground_truth/collisions", contacts.append, 10)
    forward = ros_node.create_publisher(Twist, "/cmd_vel_nav", 10)
    command = Twist()
    command.linear.x = 0.4
    ros_node.create_timer(0.05, lambda: forward.publish(command))

    def y() -> float:
        return truths[-1].pose.pose.position.y if truths else -0.2

    wait_until(lambda: y() > 0.0 or None, 60, "the robot driving forward", node=ros_node)
    wait_until(lambda: any(s.action_type == CollisionMonitorState.APPROACH for s in states) or None, 60,
               "the collision monitor slowing the robot", node=ros_node)

    def standing() -> bool:
        recent = [t.pose.pose.position.y for t in truths[-25:]]  # the last 0.5 s of ground truth (50 Hz)
        return len(recent) == 25 and max(recent) - min(recent) < 0.005
    wait_until(standing, 60, "the robot standing still before the box", node=ros_node)
    assert 0.3 < y() < BOX_FACE_Y - FRONT_M, f"stopped at y = {y():.3f}"
    assert states[-1].polygon_name == "FootprintApproach"
    # Its zone, published in base_link (visualize: true): the footprint's front edge at 0.21 m.
    assert zones and zones[-1].header.frame_id == "base_link"
    assert max(p.x for p in zones[-1].polygon.points) == pytest.approx(FRONT_M)
    # Still commanded forward, still standing: the monitor holds it there.
    stopped_at = y()
    marks = len(truths)
    wait_until(lambda: len(truths) > marks + 100 or None, 30, "two more seconds of ground truth", node=ros_node)
    assert abs(y() - stopped_at) < 0.01
    assert not contacts, f"the robot touched something at {contacts[0].point}"
