"""The evaluation node's record ends with its behaviour: what happens after (the steps the process
still answers while it stops its stack, as many as the machine's speed allows) is not recorded."""
from __future__ import annotations

from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from nav_msgs.msg import Odometry

from pppbot_eval.ros.behaviors import EvalActions
from pppbot_eval.ros.node import EvalNode
from pppbot_eval.scenarios import ESTIMATES, Recording, Scenario


class FinishesOnSecondTick:
    outcome: str | None = None

    def __init__(self) -> None:
        self.ticks = 0

    def tick(self, node: EvalActions) -> None:
        self.ticks += 1
        node.driving = True
        if self.ticks == 2:
            node.recording.end_sim_s = 1.05
            self.outcome = ""

    def progress(self) -> tuple[float, str]:
        return 0.0, ""


def odometry(t_s: float, x: float) -> Odometry:
    msg = Odometry()
    msg.header.stamp.sec, msg.header.stamp.nanosec = int(t_s), int(round((t_s % 1) * 1e9))
    msg.pose.pose.position.x = x
    msg.pose.pose.orientation.w = 1.0
    return msg


def grid_message(t_s: float, value: int) -> OccupancyGridMsg:
    msg = OccupancyGridMsg()
    msg.header.stamp.sec, msg.header.stamp.nanosec = int(t_s), int(round((t_s % 1) * 1e9))
    msg.info.resolution, msg.info.width, msg.info.height = 0.05, 2, 2
    msg.info.origin.orientation.w = 1.0
    msg.data = [value] * 4
    return msg


def test_nothing_is_recorded_after_the_behaviour_ends():
    recording = Recording()
    node = EvalNode(ESTIMATES[Scenario.DRIVE], recording)
    try:
        behavior = node.behavior = FinishesOnSecondTick()
        node.start()
        node._tick()
        node._on_truth(odometry(1.0, 0.1))
        node._on_estimate(odometry(1.0, 0.1))
        node._tick()  # the behaviour ends here
        assert behavior.outcome == "" and not node.driving
        node._on_truth(odometry(1.05, 0.2))
        node._on_estimate(odometry(1.05, 0.2))
        assert [row[0] for row in recording.truth_rows] == [1.0]
        assert [row[0] for row in recording.estimate_rows] == [1.0]
        # SLAM's map: the first after the end is the run's, whenever the process stops
        node._on_map(grid_message(1.0, 1))  # from before the end
        node._on_map(grid_message(1.1, 2))
        node._on_map(grid_message(1.2, 3))
        assert recording.final_map_stamp_s == 1.1 and recording.final_map is not None
        assert int(recording.final_map.data[0, 0]) == 2
    finally:
        node.close()
