"""launch_sim running: a headless drive recorded and stopped with SIGINT, the teleop in a terminal and
Ctrl-C there, and a second launch on a busy domain refused."""
from __future__ import annotations

import math
import os
import re
import signal
import struct
import subprocess
import time
from pathlib import Path
from typing import Any

import pytest
import zstandard
from geometry_msgs.msg import Twist
from mcap.exceptions import McapError
from mcap.records import Channel, Message
from mcap.stream_reader import StreamReader
from nav_msgs.msg import Odometry
from rosbags.rosbag2 import Reader

from pppbot_common.ros.wait import wait_until

ROOT = Path(__file__).resolve().parents[2]
PPPBOT = str(ROOT / "pppbot")


@pytest.mark.ros
def test_end_to_end_headless_drive_record_and_clean_sigint(ros_node, spawn, tmp_path):
    bag = tmp_path / "drive_bag"
    launch = spawn([PPPBOT, "launch_sim", "world:=empty", "use_teleop:=false", "use_rviz:=false", "use_viz:=false",
                    "real_time_factor:=2.0", "record:=true", f"bag_path:={bag}"], name="launch_sim")
    launch.wait_for_output(r"ppp_bot is up in 'empty'", 60)
    pids = [int(p) for p in re.findall(r"process started with pid \[(\d+)\]", launch.output)]
    assert len(pids) == 3  # simulator (with the controller, robot_state_publisher and twist_mux), bag_record, slam
    truths: list[Odometry] = []
    ros_node.create_subscription(Odometry, "/ground_truth/odom", truths.append, 10)
    pub = ros_node.create_publisher(Twist, "/cmd_vel_teleop", 10)
    # Two subscribers: twist_mux and the recorder, which finds new topics by polling the graph.
    wait_until(lambda: truths and pub.get_subscription_count() >= 2, 20, "ground truth, twist_mux and the recorder",
               node=ros_node)
    start = truths[-1].pose.pose.position
    forward = Twist()
    forward.linear.x = 0.4
    wait_until(lambda: (pub.publish(forward), math.hypot(truths[-1].pose.pose.position.x - start.x,
                                                         truths[-1].pose.pose.position.y - start.y) > 0.5)[1],
               30, "the robot to drive 0.5 m", node=ros_node)
    # Driving until the recorder has written the drive to disk (it closes a chunk every second): a
    # match seen by the test's publisher is not yet a subscription the recorder's busy executor
    # has taken messages from.
    wait_until(lambda: (pub.publish(forward), written(bag).get("/cmd_vel_teleop", 0) > 0)[1], 60,
               "the recorder to write /cmd_vel_teleop", node=ros_node)
    os.kill(launch.pid, signal.SIGINT)
    assert launch.wait(15) == 0
    assert launch.output.count("process has finished cleanly") == 3, \
        "\n".join(line for line in launch.output.splitlines() if "[launch]" in line or "process has" in line)
    for pid in pids:
        stat = Path(f"/proc/{pid}/stat")
        assert not stat.exists() or stat.read_text().rsplit(")", 1)[-1].split()[0] == "Z"  # gone, or a zombie
    # Stopping the launch finished the bag: the drive and the latched description are in it.
    with Reader(bag) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
    assert counts["/cmd_vel_teleop"] > 0 and counts["/odom"] > 0 and counts["/scan"] > 0
    assert counts["/robot_description"] == 1 and counts["/tf_static"] >= 1


def written(bag: Path) -> dict[str, int]:
    """Messages per topic in the complete records of a bag's MCAP files so far, read by the mcap
    library as a stream: what a running recorder has written (its open chunk is not yet there)."""
    counts: dict[str, int] = {}
    for path in sorted(bag.glob("*.mcap")):
        topics: dict[int, str] = {}
        with path.open("rb") as stream:
            try:
                for record in StreamReader(stream).records:
                    if isinstance(record, Channel):
                        topics[record.id] = record.topic
                    elif isinstance(record, Message) and record.channel_id in topics:
                        counts[topics[record.channel_id]] = counts.get(topics[record.channel_id], 0) + 1
            except (McapError, EOFError, ValueError, struct.error, zstandard.ZstdError):
                pass  # the chunk being written
    return counts


class Screen:
    """What a pseudo-terminal's master reads: the screen of a program run on its slave."""

    def __init__(self, master: int) -> None:
        self.master = master
        self.data = bytearray()

    def text(self) -> str:
        return self.data.decode(errors="replace")

    def read_until(self, text: str, timeout_s: float) -> str:
        import select
        deadline = time.monotonic() + timeout_s
        while text not in self.text():
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise AssertionError(f"'{text}' not on the screen:\n{self.text()[-3000:]}")
            ready, _, _ = select.select([self.master], [], [], min(remaining, 0.2))
            if ready:
                try:
                    self.data.extend(os.read(self.master, 65536))
                except OSError:
                    break
        return self.text()

    def read_until_published(self, text: str, publisher: Any, msg: Any, timeout_s: float) -> str:
        """Publish ``msg`` (now and then) until ``text`` is on the screen."""
        deadline = time.monotonic() + timeout_s
        while True:
            publisher.publish(msg)
            try:
                return self.read_until(text, 1.0)
            except AssertionError:
                if time.monotonic() > deadline:
                    raise

    def read_rest(self) -> str:
        """What is left once the program has ended."""
        import select
        while select.select([self.master], [], [], 0.5)[0]:
            try:
                chunk = os.read(self.master, 65536)
            except OSError:
                break
            if not chunk:
                break
            self.data.extend(chunk)
        return self.text()


@pytest.mark.ros
def test_in_a_terminal_the_teleop_drives_and_ctrl_c_ends_everything(ros_node):
    """launch_sim on a pseudo-terminal that is its controlling terminal, as in a shell."""
    import fcntl
    import pty
    import termios

    from pppbot_common.process import stop_process_group

    master, slave = pty.openpty()

    def own_terminal() -> None:
        os.setsid()
        fcntl.ioctl(0, termios.TIOCSCTTY, 0)

    proc = subprocess.Popen([PPPBOT, "launch_sim", "world:=empty", "use_rviz:=false", "use_viz:=false",
                             "real_time_factor:=2.0"],
                            stdin=slave, stdout=slave, stderr=slave, preexec_fn=own_terminal)
    os.close(slave)
    screen = Screen(master)
    try:
        screen.read_until("ppp_bot is up in 'empty': drive with the teleop keys", 90)
        text = screen.read_until("CTRL-C to quit", 30)
        assert "node output goes to the log directory" in text
        assert "[simulator-1] [INFO]" not in text  # node output went to the log files
        where = re.search(r"log directory: (\S+)", text)
        assert where is not None, text
        log_dir = Path(where.group(1))
        truths: list[Odometry] = []
        ros_node.create_subscription(Odometry, "/ground_truth/odom", truths.append, 10)
        wait_until(lambda: truths, 20, "ground truth", node=ros_node)
        start = truths[-1].pose.pose.position
        # A held key: the terminal repeats it until the robot has gone 0.2 m.
        wait_until(lambda: (os.write(master, b"i"), truths[-1].pose.pose.position.x - start.x > 0.2)[1], 30,
                   "driving forward", node=ros_node)
        # A node's warning while the teleop owns the terminal: written above the teleop's prompt,
        # which is drawn again as the terminal's last line (never split, never buried).
        bad = Twist()
        bad.linear.x = math.nan
        command = ros_node.create_publisher(Twist, "/diff_drive_base_controller/cmd_vel_unstamped", 10)
        text = screen.read_until_published("dropping a velocity command with non-finite values", command, bad, 30)
        after = text[text.rindex("dropping a velocity command"):]
        assert after.partition("\n")[2].startswith("currently:"), repr(after[:300])
        os.write(master, b"\x03")  # Ctrl-C: SIGINT to the terminal's foreground group
        assert proc.wait(timeout=20) == 0
        screen.read_until("teleop_keyboard-1]: process has finished cleanly", 5)
        text = screen.read_rest()
        assert text.count("process has finished cleanly") == 3  # simulator (rsp, twist_mux in it), slam, teleop
        assert (log_dir / "simulator-1.log").read_text().count("lidar 'laser'") == 1
    finally:
        stop_process_group(proc)
        os.close(master)


@pytest.mark.ros
def test_a_second_launch_on_a_busy_domain_is_refused_and_the_first_runs_on(ros_node, spawn):
    first = spawn([PPPBOT, "launch_sim", "world:=empty", "use_teleop:=false", "use_rviz:=false", "use_viz:=false",
                   "use_slam:=false"], name="launch_sim")
    first.wait_for_output(r"ppp_bot is up in 'empty'", 60)
    second = spawn([PPPBOT, "launch_sim", "world:=room", "use_teleop:=false", "use_rviz:=false", "use_viz:=false"],
                   name="second launch_sim")
    assert second.wait(timeout_s=60) == 2
    domain = os.environ["ROS_DOMAIN_ID"]
    assert f"launch_sim: ROS_DOMAIN_ID={domain} already has a simulation running (something publishes /clock" \
        in second.output
    assert f"ROS_DOMAIN_ID={1 if domain != '1' else 2} make run" in second.output
    assert "process started" not in second.output  # refused before anything started
    truths: list[Odometry] = []
    ros_node.create_subscription(Odometry, "/ground_truth/odom", truths.append, 10)
    wait_until(lambda: len(truths) > 20, 20, "the first stack's ground truth", node=ros_node)
    assert first.running() and "moved backwards in time" not in first.output
