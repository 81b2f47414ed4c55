"""The built interface packages work over real DDS between processes."""
from __future__ import annotations

import math

import pytest
from geometry_msgs.msg import PoseStamped
from nav2_msgs.action import NavigateToPose
from nav2_msgs.msg import ParticleCloud
from rclpy.action import ActionClient
from tf2_msgs.msg import TFMessage

from pppbot_common.ros.wait import send_goal, wait_for_messages, wait_for_topic, wait_until

pytestmark = pytest.mark.ros


@pytest.fixture
def talker(spawn, python_script):
    child = spawn(python_script("publish_tf_and_particles.py", "50"), name="talker")
    child.wait_for_output(r"^ready$", timeout_s=20)
    return child


def test_tf_message_crosses_processes(ros_node, talker):
    assert wait_for_topic(ros_node, "/tf", timeout_s=10) == "tf2_msgs/msg/TFMessage"
    msgs = wait_for_messages(ros_node, TFMessage, "/tf", count=5, timeout_s=10)
    stamps = [m.transforms[0].header.stamp.nanosec for m in msgs]
    assert stamps == sorted(stamps) and len(set(stamps)) == 5
    for m in msgs:
        (t,) = m.transforms
        assert (t.header.frame_id, t.child_frame_id) == ("odom", "base_link")
        assert t.transform.translation.x == pytest.approx(0.01 * t.header.stamp.nanosec)


def test_particle_cloud_crosses_processes(ros_node, talker):
    assert wait_for_topic(ros_node, "/particle_cloud", timeout_s=10) == "nav2_msgs/msg/ParticleCloud"
    (cloud,) = wait_for_messages(ros_node, ParticleCloud, "/particle_cloud", count=1, timeout_s=10)
    assert cloud.header.frame_id == "map"
    assert [p.pose.position.y for p in cloud.particles] == [0.0, 1.0, 2.0]
    assert math.fsum(p.weight for p in cloud.particles) == pytest.approx(1.0)
    k = cloud.header.stamp.nanosec
    assert all(p.pose.position.x == pytest.approx(0.01 * k) for p in cloud.particles)


def test_type_hash_on_the_wire_is_jazzys(ros_node, talker):
    """The hash our tf2_msgs build advertises is the one Jazzy's tf2_msgs has."""
    from rosbags.typesys import Stores, get_typestore

    jazzy = get_typestore(Stores.ROS2_JAZZY).hash_rihs01("tf2_msgs/msg/TFMessage")
    wait_for_topic(ros_node, "/tf", timeout_s=10)
    (info,) = ros_node.get_publishers_info_by_topic("/tf")
    assert str(info.topic_type_hash) == jazzy


def test_navigate_to_pose_goal_feedback_result(ros_node, spawn, python_script):
    server = spawn(python_script("navigate_to_pose_server.py"), name="nav_server")
    server.wait_for_output(r"^ready$", timeout_s=20)
    client = ActionClient(ros_node, NavigateToPose, "navigate_to_pose")
    assert client.wait_for_server(timeout_sec=10)

    goal = NavigateToPose.Goal(pose=PoseStamped())
    goal.pose.header.frame_id = "map"
    goal.pose.pose.position.x, goal.pose.pose.position.y = 3.0, 4.0
    messages: list[NavigateToPose.Impl.FeedbackMessage] = []
    handle = send_goal(client, goal, ros_node, feedback_callback=messages.append)
    assert handle.accepted
    get_result = handle.get_result_async()
    wrapped = wait_until(lambda: get_result.result() if get_result.done() else None, 10, "the result",
                         node=ros_node)

    # The accepted goal's feedback (on a busy machine an answer taken for lost sends the goal
    # again; the server runs the first too and its feedback comes with its own goal id).
    feedback = [m.feedback for m in messages if bytes(m.goal_id.uuid) == bytes(handle.goal_id.uuid)]
    assert wrapped.result.error_code == NavigateToPose.Result.NONE
    assert wrapped.result.error_msg == ""
    assert len(feedback) == 4
    assert [fb.distance_remaining for fb in feedback] == pytest.approx([3.75, 2.5, 1.25, 0.0])
    assert feedback[-1].current_pose.pose.position.x == pytest.approx(3.0)
    assert [fb.navigation_time.sec for fb in feedback] == [1, 2, 3, 4]
    client.destroy()
