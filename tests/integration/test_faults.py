"""A process of a running stack (free running, or in lockstep, where the others wait for it)
killed with SIGKILL at a moment drawn from a seed (as a segfault or the OOM killer would end
it): the launch names the dead process at once; without
``respawn:=true`` it stops everything else, leaving no process and no shared memory behind;
with it the node is started again and the stack carries on (a goal is reached), while the
simulator's death still ends the stack; a SLAM node killed mid-run maps on from its autosave, and
its final map scores F1 ≥ 0.95 against the world's ground truth."""
from __future__ import annotations

import math
import os
import random
import re
import signal
import urllib.request
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from action_msgs.msg import GoalStatus
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import TransformStamped, Twist, Vector3
from nav2_msgs.action import NavigateToPose
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from nav_msgs.msg import Odometry
from rclpy.action import ActionClient
from rosgraph_msgs.msg import Clock
from tf2_msgs.msg import TFMessage

from pppbot_common.dds_shm import segments_of
from pppbot_common.maps import OCCUPIED
from pppbot_common.ros.maps import grid_from_message
from pppbot_common.ros.qos import LATCHED
from pppbot_common.ros.wait import send_goal, wait_until
from pppbot_common.se2 import yaw_from_quaternion
from pppbot_eval.map_quality import compare_maps
from pppbot_eval.scenarios import world_truth
from pppbot_slam.serialization import load_posegraph

from .test_navigation import LAUNCH_STOP, PPPBOT, goal_pose, truth_pose

pytestmark = [pytest.mark.ros, pytest.mark.heavy]
SEED = 55
#: A box with nothing inside: a robot turning on the spot at its centre sees every wall.
BOX_ROOM = Path(__file__).resolve().parents[1] / "pppbot_sim" / "data" / "box_room.sdf"
#: Seconds the launch may take from the death to its own end (its shutdown escalates 5 s apart).
STOPPED_WITHIN_S = 30.0


def pids(output: str) -> dict[str, int]:
    """Each process the launch started (``name-N``) and its pid."""
    return {m[1]: int(m[2]) for m in re.finditer(r"\[INFO\] \[([\w-]+)\]: process started with pid \[(\d+)\]", output)}


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"


def kill_after_a_drawn_moment(ros_node: Any, launch: Any, name: str,
                              rng: random.Random) -> tuple[int, set[str], float]:
    """SIGKILL ``name``'s process once the simulation has run a drawn 1 to 6 s longer; its pid, the
    DDS shared-memory segments it alone had (not the ports every participant shares) and the
    simulation's time at the kill."""
    clock: list[float] = []
    subscription = ros_node.create_subscription(Clock, "/clock", lambda m: clock.append(
        m.clock.sec + m.clock.nanosec * 1e-9), 10)
    wait_until(lambda: clock, 20, "/clock", node=ros_node)
    until = clock[-1] + rng.uniform(1.0, 6.0)
    wait_until(lambda: clock[-1] >= until, 30, "the drawn moment", node=ros_node)
    ros_node.destroy_subscription(subscription)
    pid = max(p for label, p in pids(launch.output).items() if label.rsplit("-", 1)[0] == name)
    own = {s for s in segments_of(pid) if not s.startswith("fastrtps_port")}
    os.kill(pid, signal.SIGKILL)
    return pid, own, clock[-1]


def kill_and_see_respawned(ros_node: Any, launch: Any, victim: str, rng: random.Random,
                           limit: str = "no limit") -> float:
    """SIGKILL ``victim`` at a drawn moment and wait for the launch to start it again (respawn:=true,
    ``limit`` as the launch says it: "no limit", or the recorder's "1 of 3"); the simulation's time
    at the kill."""
    *_, killed_at = kill_after_a_drawn_moment(ros_node, launch, victim, rng)
    launch.wait_for_output(rf"\[INFO\] \[{victim}-1\]: respawning in 0.5 s \({limit}\)", 10)
    launch.wait_for_output(rf"\[INFO\] \[{victim}-2\]: process started with pid", 20)
    return killed_at


@pytest.mark.parametrize("bringup, victim", [("localization:=true", "navigation"),
                                             ("localization:=false", "slam_toolbox"),
                                             ("localization:=true lockstep:=true", "localization")])
def test_a_killed_node_ends_the_launch_naming_it_and_leaves_nothing_behind(ros_node: Any, spawn: Any, bringup: str,
                                                                           victim: str) -> None:
    launch = spawn([PPPBOT, "launch_sim", "world:=room", *bringup.split(), "use_teleop:=false", "use_rviz:=false",
                    "use_viz:=false"], name="launch_sim")
    launch.wait_for_output(r"ppp_bot is up in 'room'", 120)
    pid, segments, _ = kill_after_a_drawn_moment(ros_node, launch, victim, random.Random(f"{SEED}{victim}"))
    launch.wait_for_output(rf"\[ERROR\] \[{victim}-1\]: process has died \[pid {pid}, exit code -9", 10)
    launch.wait_for_output(rf"shutting down \(required node '{victim}' exited\)", 10)
    assert launch.wait(STOPPED_WITHIN_S) == 1
    started = pids(launch.output)
    assert [label for label, p in started.items() if alive(p)] == [], started  # no orphan
    assert segments and not [s for s in segments if (Path("/dev/shm") / s).exists()]  # the launch removed them
    # Each of the others ended on the launch's SIGINT, cleanly.
    clean = re.findall(r"\[INFO\] \[([\w-]+)\]: process has finished cleanly", launch.output)
    assert sorted(clean) == sorted(label for label in started if label != f"{victim}-1"), launch.output[-2000:]


def test_respawn_starts_a_killed_node_again_and_the_stack_carries_on(ros_node: Any, spawn: Any) -> None:
    launch = spawn([PPPBOT, "launch_sim", "world:=room", "localization:=true", "respawn:=true", "respawn_delay:=0.5",
                    "use_teleop:=false", "use_rviz:=false", "use_viz:=false"], name="launch_sim")
    launch.wait_for_output(r"ppp_bot is up in 'room'", 120)
    rng = random.Random(SEED)
    for victim in ("navigation", "localization"):
        kill_and_see_respawned(ros_node, launch, victim, rng)
    truths: list[Odometry] = []
    ros_node.create_subscription(Odometry, "/ground_truth/odom", truths.append, 10)
    client = ActionClient(ros_node, NavigateToPose, "navigate_to_pose")
    assert client.wait_for_server(timeout_sec=60)
    wait_until(lambda: truths, 20, "ground truth", node=ros_node)
    x0, y0, _ = truth_pose(truths[-1])

    def reached() -> bool:  # the navigator may still be activating: a refused goal is sent again
        handle = send_goal(client, NavigateToPose.Goal(pose=goal_pose(x0 + 0.6, y0, 0.0)), ros_node, 20)
        if not handle.accepted:
            return False
        done = handle.get_result_async()
        wait_until(done.done, 120, "the goal's result", node=ros_node)
        return done.result().status == GoalStatus.STATUS_SUCCEEDED

    wait_until(reached, 300, "a goal reached after the restarts", node=ros_node)
    x, y, _ = truth_pose(truths[-1])
    assert math.hypot(x - x0 - 0.6, y - y0) < 0.35
    # The simulator is the world: its death ends the stack, respawn or not.
    kill_after_a_drawn_moment(ros_node, launch, "simulator", rng)
    launch.wait_for_output(r"shutting down \(required node 'simulator' exited\)", 10)
    assert launch.wait(STOPPED_WITHIN_S) == 1
    assert [label for label, p in pids(launch.output).items() if alive(p)] == []


def test_a_restarted_slam_maps_on_from_its_autosave(ros_node: Any, spawn: Any) -> None:
    launch = spawn([PPPBOT, "launch_sim", f"world:={BOX_ROOM}", "localization:=false", "respawn:=true",
                    "respawn_delay:=0.5", "use_teleop:=false", "use_rviz:=false", "use_viz:=false"], name="launch_sim",
                   timeouts=LAUNCH_STOP)
    launch.wait_for_output(r"ppp_bot is up in 'box_room'", 120)
    said = re.search(r"slam saves its pose graph every [\d.]+ s to (\S+\.posegraph)", launch.output)
    assert said is not None
    autosave = Path(said[1])
    transforms: list[TransformStamped] = []
    maps: list[OccupancyGridMsg] = []
    ros_node.create_subscription(TFMessage, "/tf", lambda m: transforms.extend(
        t for t in m.transforms if (t.header.frame_id, t.child_frame_id) == ("map", "odom")), 100)
    ros_node.create_subscription(OccupancyGridMsg, "/map", maps.append, LATCHED)
    keyframes: list[int] = []  # the slam node's keyframes, from its /diagnostics
    ros_node.create_subscription(DiagnosticArray, "/diagnostics", lambda m: keyframes.extend(
        int(v.value) for s in m.status if s.name.endswith(": mapping") for v in s.values if v.key == "keyframes"), 10)
    odometry: list[Odometry] = []
    ros_node.create_subscription(Odometry, "/ground_truth/odom", odometry.append, 10)
    turn = ros_node.create_publisher(Twist, "/cmd_vel_teleop", 10)
    ros_node.create_timer(0.05, lambda: turn.publish(Twist(angular=Vector3(z=0.6))))  # turning on the spot
    # Turned far enough for keyframes (one each 0.5 rad) and an autosave of them.
    wait_until(lambda: autosave.is_file() and len(load_posegraph(autosave).keyframes) >= 6, 120,
               "an autosave of six keyframes", node=ros_node)
    before_kill = len(transforms)
    wait_until(lambda: len(transforms) > before_kill + 20, 20, "map → odom after the autosave", node=ros_node)
    # Turned (yaw between 0.5 and 2 rad, turning on at 0.6 rad/s): a map started afresh now, or
    # within the seconds of a restart, would be another. (The autosave may come a whole turn late.)
    wait_until(lambda: odometry and 0.5 < truth_pose(odometry[-1])[2] < 2.0, 30, "the robot turned 0.5 to 2 rad",
               node=ros_node)
    map_before = grid_from_message(maps[-1])
    last = transforms[-1]
    saved = load_posegraph(autosave).keyframes
    reported = len(keyframes)
    os.kill(max(p for label, p in pids(launch.output).items() if label.startswith("slam_toolbox")), signal.SIGKILL)
    launch.wait_for_output(r"\[slam_toolbox-2\]: process started with pid", 20)
    launch.wait_for_output(r"mapping on from the autosave .*this node was restarted", 30)
    stamp = (last.header.stamp.sec, last.header.stamp.nanosec)
    fresh = wait_until(lambda: [t for t in transforms if (t.header.stamp.sec, t.header.stamp.nanosec) > stamp
                                and t is not last][-20:], 30, "map → odom from the restarted node", node=ros_node)
    # The map frame stayed where it was: map → odom goes on from where the killed node left it
    # (a node starting afresh would put the map where the robot is now, turned by then).
    for t in (last, fresh[-1]):
        assert abs(t.transform.translation.x) < 0.1 and abs(t.transform.translation.y) < 0.1
    assert abs(yaw_from_quaternion(*_xyzw(fresh[-1])) - yaw_from_quaternion(*_xyzw(last))) < 0.1
    wait_until(lambda: len(maps) >= 2 and maps[-1].header.stamp.sec > last.header.stamp.sec, 30,
               "a map from the restarted node", node=ros_node)
    # It holds every keyframe the autosave had from its first report on, and maps on.
    wait_until(lambda: len(keyframes) > reported + 1, 30, "the restarted node's /diagnostics", node=ros_node)
    after = keyframes[reported:]
    assert min(after) >= len(saved) >= 6, (after, len(saved))
    # Its map holds the walls the killed node had mapped.
    map_after = grid_from_message(maps[-1])
    rows, cols = np.nonzero(map_before.data == OCCUPIED)
    xs, ys = map_before.origin[0] + (cols + 0.5) * map_before.resolution, \
        map_before.origin[1] + (rows + 0.5) * map_before.resolution
    r, c = map_after.cell_of(xs, ys)
    inside = (r >= 0) & (r < map_after.height) & (c >= 0) & (c < map_after.width)
    kept = np.mean([(map_after.data[max(0, i - 1):i + 2, max(0, j - 1):j + 2] == OCCUPIED).any()
                    for i, j in zip(r[inside], c[inside], strict=True)])
    assert inside.mean() > 0.95 and kept > 0.95, (inside.mean(), kept)
    # Once the robot has turned a whole round more, the final map scores against the world's ground
    # truth as an uninterrupted run's would (the map frame is the spawn pose, the box's centre).
    wait_until(lambda: len(keyframes) > reported and keyframes[-1] >= len(saved) + 13, 60,
               "a whole turn more of keyframes (one each 0.5 rad)", node=ros_node)
    wait_until(lambda: maps[-1].header.stamp.sec > fresh[-1].header.stamp.sec + 5, 30, "the final map",
               node=ros_node)
    quality = compare_maps(grid_from_message(maps[-1]), world_truth(BOX_ROOM), (0.0, 0.0, 0.0),
                           reachable_from=(0.0, 0.0))
    print(f"the map after the restart: F1 {quality.f1:.3f} (precision {quality.precision:.3f}, "
          f"recall {quality.recall:.3f})")
    assert quality.f1 >= 0.95, quality
    assert launch.stop() == 0


def test_the_live_view_and_the_recorder_respawn_and_go_on(ros_node: Any, spawn: Any, tmp_path: Path) -> None:
    """The respawn matrix's last two: the live view's node (which serves the page) and the bag
    recorder, each killed at a drawn moment, are started again; the page answers again on its
    port, and the recorder records on into the same bag, which holds /clock from before the kill
    and after it (read by rosbags, an independent reader)."""
    bag = tmp_path / "bag"
    launch = spawn([PPPBOT, "launch_sim", "world:=room", "localization:=true", "respawn:=true", "respawn_delay:=0.5",
                    "record:=true", f"bag_path:={bag}", "use_viz:=true", "viz_viewer:=web", "viz_port:=0",
                    "use_teleop:=false", "use_rviz:=false"], name="launch_sim", timeouts=LAUNCH_STOP)
    launch.wait_for_output(r"ppp_bot is up in 'room'", 120)
    # The page's address is printed with the lines after "is up" (a busy machine's reader may not
    # have them yet).
    page = launch.wait_for_output(r"live view: http://127\.0\.0\.1:(\d+)/", 30)
    url = f"http://127.0.0.1:{page[1]}/"
    wait_until(lambda: _page_answers(url), 30, "the live view's page", node=ros_node)
    rng = random.Random(f"{SEED}view")
    clock: list[float] = []
    ros_node.create_subscription(Clock, "/clock", lambda m: clock.append(m.clock.sec + m.clock.nanosec * 1e-9), 10)
    killed_at = kill_and_see_respawned(ros_node, launch, "bag_record", rng, limit="1 of 3")
    wait_until((bag / "bag_1.mcap").is_file, 60, "the respawned recorder's file", node=ros_node)
    wait_until(lambda: clock, 20, "/clock", node=ros_node)
    restarted_at = clock[-1]
    wait_until(lambda: clock[-1] > restarted_at + 6.0, 60, "6 s more of recording", node=ros_node)
    kill_and_see_respawned(ros_node, launch, "viz", rng)
    wait_until(lambda: _page_answers(url), 60, "the respawned live view's page", node=ros_node)
    assert launch.stop() == 0
    assert not re.search(r"\[(bag_record|viz)-2\]: process has died", launch.output), launch.output[-3000:]
    stamps = _recorded_clock(bag)
    assert np.all(np.diff(stamps) > 0), "the bag's /clock goes back or repeats"  # one clock, in order
    # One gap, the kill's: what the first recorder kept reaches to within its last second or two (a
    # killed writer loses its open chunk), and the second recorded on from after the kill to the end.
    gap = int(np.argmax(np.diff(stamps)))
    end_first, start_second = stamps[gap], stamps[gap + 1]
    said = (f"kill at {killed_at:.2f} s; the first recorder's last {end_first:.2f} s, the second's first "
            f"{start_second:.2f} s")
    print(said)
    assert killed_at - 2.0 < end_first <= killed_at + 0.5 < start_second, said
    assert stamps[-1] - start_second > 5.0, said


def _page_answers(url: str) -> bool:
    try:
        with urllib.request.urlopen(url, timeout=5) as reply:
            return reply.status == 200 and b"<html" in reply.read(4096).lower()
    except OSError:
        return False


def _recorded_clock(bag: Path) -> np.ndarray:
    """Every /clock time the bag holds, in the order recorded, by rosbags' reader."""
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    with Reader(bag) as reader:
        connections = [c for c in reader.connections if c.topic == "/clock"]
        clocks: list[Any] = [store.deserialize_cdr(raw, c.msgtype) for c, _, raw in reader.messages(connections)]
    return np.array([m.clock.sec + m.clock.nanosec * 1e-9 for m in clocks])


def _xyzw(t: TransformStamped) -> tuple[float, float, float, float]:
    q = t.transform.rotation
    return q.x, q.y, q.z, q.w
