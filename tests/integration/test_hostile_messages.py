"""Hostile messages into every subscriber, action server and service of the navigation bringup:
for each topic a node of the stack subscribes to, each action it serves and each service it
offers, Hypothesis draws messages, goals and requests of its type with NaN, ±inf and huge floats,
empty and mismatched arrays, frames that do not exist and stamps in any order (:mod:`hostile`),
and the test sends them, as a stranger on the network could.

No node dies; each names what it drops at most once per kind in its throttle period; every goal
is refused, or ends (at once, or when canceled); the robot does not act on garbage (its speed
stays within the stack's limits); and afterwards the stack still works: the navigator takes a
goal and brings it to an end. /clock, /tf, /map and /initialpose get their garbage last, with the
service requests: a clock from another publisher, transforms at any time, another map or pose
change what time and where things are for every node (as they would for Nav2), and a service
may pause the world or shut the navigation down, as its caller asked; after them every request
must have been answered and every node must still be there.
"""
from __future__ import annotations

import math
import re
from collections import Counter
from pathlib import Path
from typing import Any

import pytest
import rclpy
from action_msgs.msg import GoalStatus
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st
from nav2_msgs.action import NavigateToPose
from nav_msgs.msg import Odometry
from rclpy.action import ActionClient
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from pppbot_common.errors import TimeoutExpired
from pppbot_common.ros.messages import get_interface
from pppbot_common.ros.wait import send_goal, wait_until

from .hostile import messages, of_the_stack, servers
from .test_navigation import LAUNCH_STOP, PPPBOT, goal_pose

pytestmark = [pytest.mark.ros, pytest.mark.heavy]
#: Drawn per topic (each draw is one message on every topic of its phase).
EXAMPLES = 40
#: Goals drawn per action server, and requests per service.
GOALS, REQUESTS = 4, 4
#: Wall seconds an accepted drawn goal may run before the test cancels it.
GOAL_PATIENCE_S = 1.0
#: Wall seconds for a canceled goal to end, and for a service to answer.
ANSWER_S = 30.0
#: Wall seconds the goal after the garbage may run before the test cancels it.
GOAL_PATIENCE_AFTER_S = 90.0
#: A goal or request that fails is reported as drawn: shrinking it would wait out a timeout per try.
UNSHRUNK = (Phase.explicit, Phase.generate)
#: Request fields that name a file the server writes: drawn names are kept inside the test's folder.
WRITTEN_FILES = ("map_url", "filename")
#: What the launch prints for a node it lost.
DIED = re.compile(r"\[(ERROR|FATAL)\] \[launch\].*(died|exited|exit code)|process has died", re.I)
#: Topics whose garbage changes time, place or the map for every node: fed last, survival asked
#: only. (AMCL refuses a drawn /initialpose off the map or spread wider than it, and has no pose after
#: a drawn /map that does not hold it; a pose on the map moves it there, as a user's would.)
LAST = ("/clock", "/tf", "/tf_static", "/map", "/initialpose")
#: The stack's speed limits (the velocity smoother's max_velocity), with room for the simulator.
MAX_SPEED_M_S, MAX_TURN_RAD_S = 0.5 * 1.2, 2.0 * 1.2
#: Sim seconds over which the robot's ground-truth travel and turn are held to the limits above.
SPEED_WINDOW_S = 0.5
#: Action servers the bringup must show before the garbage.
SERVED = {"/navigate_to_pose", "/follow_path", "/spin", "/compute_path_to_pose"}


def subscribed_topics(node: Any) -> dict[str, str]:
    """Every topic a node of the stack subscribes to, with its type (the first one named)."""
    topics: dict[str, str] = {}
    for name, namespace in node.get_node_names_and_namespaces():
        if not of_the_stack(name):
            continue
        for topic, types in node.get_subscriber_names_and_types_by_node(name, namespace):
            if not topic.startswith("/_") and "/_action/" not in topic and topic != "/parameter_events":
                topics.setdefault(topic, types[0])
    return topics


Pose = tuple[float, float, float, float]


def windows(truths: list[Odometry], span_s: float) -> list[tuple[Pose, Pose]]:
    """Each ground-truth pose (t, x, y, yaw) paired with the first one at least ``span_s`` later."""
    poses: list[Pose] = []
    for odom in truths:
        q, p = odom.pose.pose.orientation, odom.pose.pose.position
        yaw = math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))
        poses.append((odom.header.stamp.sec + odom.header.stamp.nanosec * 1e-9, p.x, p.y, yaw))
    poses.sort()
    pairs: list[tuple[Pose, Pose]] = []
    j = 0
    for start in poses:
        while j < len(poses) and poses[j][0] < start[0] + span_s:
            j += 1
        if j == len(poses):
            break
        pairs.append((start, poses[j]))
    return pairs


def feed(node: Any, topics: dict[str, str]) -> int:
    """Publish :data:`EXAMPLES` drawn messages on each of ``topics``; returns how many went out."""
    # Reliable and transient local: what every subscriber accepts (latched /map and costmaps too).
    qos = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    publishers = {t: (node.create_publisher(get_interface(kind), t, qos), get_interface(kind))
                  for t, kind in topics.items()}
    wait_until(lambda: all(p.get_subscription_count() for p, _ in publishers.values()), 20,
               "the stack's subscriptions to hear the test", node=node)
    sent = Counter[str]()

    @settings(max_examples=EXAMPLES, derandomize=True, deadline=None, database=None,
              suppress_health_check=list(HealthCheck))
    @given(st.data())
    def one_round(data: st.DataObject) -> None:
        for topic, (publisher, cls) in publishers.items():
            publisher.publish(data.draw(messages(cls), label=topic))
            sent[topic] += 1
        rclpy.spin_once(node, timeout_sec=0.0)  # what the test watches (ground truth) comes in meanwhile

    one_round()
    for publisher, _ in publishers.values():
        node.destroy_publisher(publisher)
    return sum(sent.values())


def goals(node: Any, actions: dict[str, str]) -> Counter[tuple[str, str]]:
    """Up to :data:`GOALS` drawn goals to each action server, one at a time: each is refused, or ends,
    at once or when canceled after :data:`GOAL_PATIENCE_S`. Each outcome counted per action."""
    outcomes = Counter[tuple[str, str]]()
    for action, kind in actions.items():
        cls = get_interface(kind)
        client = ActionClient(node, cls, action)
        assert client.wait_for_server(timeout_sec=20), action
        _drawn_goals(node, action, client, cls, outcomes)
        client.destroy()
    return outcomes


def _drawn_goals(node: Any, action: str, client: ActionClient, cls: Any, outcomes: Counter[tuple[str, str]]) -> None:
    status_names = {v: k.removeprefix("STATUS_") for k, v in vars(GoalStatus).items() if k.startswith("STATUS_")}

    @settings(max_examples=GOALS, derandomize=True, deadline=None, database=None, phases=UNSHRUNK,
              suppress_health_check=list(HealthCheck))
    @given(goal=messages(cls.Goal))
    def one_goal(goal: Any) -> None:
        handle = send_goal(client, goal, node, ANSWER_S)
        if not handle.accepted:
            outcomes[action, "REFUSED"] += 1
            return
        done = handle.get_result_async()
        try:
            wait_until(done.done, GOAL_PATIENCE_S, "", node=node)
        except TimeoutExpired:
            handle.cancel_goal_async()
            wait_until(done.done, ANSWER_S, f"a drawn goal of {action} to end once canceled", node=node)
        outcomes[action, status_names[done.result().status]] += 1

    one_goal()


def requests(node: Any, services: dict[str, str], folder: Path) -> Counter[str]:
    """Up to :data:`REQUESTS` drawn requests to each service (one, for a request without fields): each
    must be answered. Files a request asks to write go into ``folder``, under the drawn name. The
    answers counted per service."""
    answered = Counter[str]()
    for service, kind in services.items():
        cls = get_interface(kind)
        client = node.create_client(cls, service)
        assert client.wait_for_service(timeout_sec=20), service
        _drawn_requests(node, service, client, cls, folder, answered)
        node.destroy_client(client)
    return answered


def _drawn_requests(node: Any, service: str, client: Any, cls: Any, folder: Path, answered: Counter[str]) -> None:
    @settings(max_examples=REQUESTS, derandomize=True, deadline=None, database=None, phases=UNSHRUNK,
              suppress_health_check=list(HealthCheck))
    @given(request=messages(cls.Request))
    def one_request(request: Any) -> None:
        for field in WRITTEN_FILES:
            if hasattr(request, field):
                name = Path(getattr(request, field)).name
                setattr(request, field, str(folder / (name if name.strip(".") else "dots")))
        wait_until(client.call_async(request).done, ANSWER_S, f"an answer from {service}", node=node)
        answered[service] += 1

    one_request()


#: The bringups attacked: navigating on a map (AMCL, the map server), and navigating while mapping
#: (SLAM's topics and services), each with the topics a node of it must subscribe to.
BRINGUPS = {"localization:=true": {"/scan", "/cmd_vel_nav", "/initialpose", "/goal_pose", "/map", "/tf", "/clock"},
            "localization:=false navigation:=true": {"/scan", "/cmd_vel_nav", "/goal_pose", "/map", "/tf", "/clock"}}


@pytest.mark.parametrize("bringup", BRINGUPS)
def test_garbage_on_every_topic_and_server_kills_nothing_moves_nothing_and_the_stack_still_navigates(
        ros_node: Any, spawn: Any, tmp_path: Path, bringup: str) -> None:
    launch = spawn([PPPBOT, "launch_sim", "world:=room", *bringup.split(), "use_teleop:=false",
                    "use_rviz:=false", "use_viz:=false", "lockstep:=false"], name="launch_sim", timeouts=LAUNCH_STOP)
    launch.wait_for_output(r"ppp_bot is up in 'room'", 120)
    truths: list[Odometry] = []
    ros_node.create_subscription(Odometry, "/ground_truth/odom", truths.append, 50)
    wait_until(lambda: truths, 20, "ground truth", node=ros_node)
    expected = BRINGUPS[bringup]

    found: dict[str, str] = {}

    def all_subscribed() -> dict[str, str] | None:
        found.update(subscribed_topics(ros_node))
        return found if found.keys() >= expected else None

    topics = wait_until(all_subscribed, 30, f"the stack's subscriptions to {sorted(expected)} in the graph",
                        node=ros_node)
    nodes_before = {n for n, _ in ros_node.get_node_names_and_namespaces() if of_the_stack(n)}

    def all_served() -> tuple[dict[str, str], dict[str, str]] | None:  # discovery lags on a busy machine
        actions, services = servers(ros_node)
        return (actions, services) if actions.keys() >= SERVED else None

    actions, services = wait_until(all_served, 30, f"the stack's action servers {sorted(SERVED)}", node=ros_node)

    before = len(truths)
    sent = feed(ros_node, {t: k for t, k in topics.items() if t not in LAST})
    assert sent >= EXAMPLES * 10
    outcomes = goals(ros_node, actions)
    print(f"{len(actions)} action servers, drawn goals' outcomes: {dict(outcomes)}")
    assert {a for a, _ in outcomes} == actions.keys() and sum(outcomes.values()) >= GOALS * len(actions) // 2
    during = len(truths)
    wait_until(lambda: len(truths) >= during + 100, 30, "2 s of ground truth after the garbage", node=ros_node)
    assert len(truths) > before + 100  # the speed check below saw the robot during and after the garbage
    # The robot did not act on garbage: never faster than the stack lets it go, judged on where it went
    # over each window of sim time (a drawn valid command may drive it into a wall, and the contact's
    # impulse spins it faster than any command for an instant: physics, not the stack).
    assert all(math.isfinite(o.twist.twist.linear.x) and math.isfinite(o.pose.pose.position.x) for o in truths)
    for (t0, x0, y0, yaw0), (t1, x1, y1, yaw1) in windows(truths, SPEED_WINDOW_S):
        turned = abs(math.remainder(yaw1 - yaw0, math.tau))
        assert math.hypot(x1 - x0, y1 - y0) <= MAX_SPEED_M_S * (t1 - t0), (t0, t1, (x0, y0), (x1, y1))
        assert turned <= MAX_TURN_RAD_S * (t1 - t0), (t0, t1, yaw0, yaw1)
    assert not DIED.search(launch.output), launch.output[-3000:]

    # Still a working stack: the navigator takes a goal, runs its tree on it (its feedback counts the
    # navigation time), and brings it to an end: by itself, or canceled. (Whether it is reached depends on
    # where the drawn, valid, velocity commands left the robot: next to a wall, its start can be on an
    # obstacle, and the tree's recoveries then take minutes of sim time.)
    client = ActionClient(ros_node, NavigateToPose, "navigate_to_pose")
    assert client.wait_for_server(timeout_sec=20)
    feedback: list[Any] = []
    handle = send_goal(client, NavigateToPose.Goal(pose=goal_pose(0.0, 0.0, 0.0)), ros_node, 20,
                       feedback_callback=feedback.append)
    if not handle.accepted:  # the navigator may still be busy with a drawn /goal_pose: ask again
        handle = send_goal(client, NavigateToPose.Goal(pose=goal_pose(0.0, 0.0, 0.0)), ros_node, 20,
                           feedback_callback=feedback.append)
    assert handle.accepted
    done = handle.get_result_async()
    try:
        wait_until(done.done, GOAL_PATIENCE_AFTER_S, "the goal after the garbage", node=ros_node)
    except TimeoutExpired:
        assert feedback and max(f.feedback.navigation_time.sec for f in feedback) >= 5  # the tree ran on it
        handle.cancel_goal_async()
        wait_until(done.done, ANSWER_S, "the goal after the garbage, canceled", node=ros_node)
    assert done.result().status in (GoalStatus.STATUS_SUCCEEDED, GoalStatus.STATUS_ABORTED,
                                    GoalStatus.STATUS_CANCELED)

    # Time and place from a stranger: every node survives them.
    feed(ros_node, {t: k for t, k in topics.items() if t in LAST})
    answered = requests(ros_node, services, tmp_path)
    assert answered.keys() == services.keys() and max(answered.values()) == REQUESTS
    wait_until(lambda: {n for n, _ in ros_node.get_node_names_and_namespaces()} >= nodes_before, 20,
               "every node still in the graph", node=ros_node)
    assert not DIED.search(launch.output), launch.output[-3000:]
    # Each node names a kind of bad message at most once per 5 s throttle period (the test took minutes).
    drops = Counter(re.findall(r"\[([\w.]+)\]: dropping an? (\w+) message: (\w+)", launch.output))
    print(f"{len(topics)} topics, {sent} messages before /clock and /tf, {len(services)} services; "
          f"named drops: {dict(drops)}")
    assert drops and max(drops.values()) <= 60, drops.most_common(5)
    assert launch.stop() == 0
