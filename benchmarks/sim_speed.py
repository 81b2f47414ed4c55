"""Achieved real-time factor of the simulator at real_time_factor:=0.

For each world (maze, office): the simulation core alone (MuJoCo stepping, the
640-beam lidar at 10 Hz, IMU at 100 Hz, wheel and ground-truth readings, no ROS);
the simulator node publishing everything over DDS with nobody listening; the same
while a plain second process subscribes to /scan and /clock (it is not waited for, so
it may miss scans); and in lockstep with a participant that subscribes to /scan (time
waits for it: it receives every scan). Prints one JSON object on its last line.

    ./pppbot env python benchmarks/sim_speed.py [--sim-seconds 60] [--worlds maze office]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

from pppbot_common.dds_isolation import isolate_dds

ROOT = Path(__file__).resolve().parent.parent
SUBSCRIBER = """
import rclpy, sys
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import LaserScan
from rosgraph_msgs.msg import Clock
rclpy.init(); n = rclpy.create_node('bench_subscriber'); count = [0]
n.create_subscription(LaserScan, '/scan', lambda m: count.__setitem__(0, count[0] + 1), 10)
n.create_subscription(Clock, '/clock', lambda m: None, 10)
print('ready', flush=True)
try:
    rclpy.spin(n)
except BaseException:
    pass
print('scans', count[0], flush=True)
"""
#: A lockstep participant counting /scan; after ``target`` scans it prints the count, the sim
#: seconds and the wall seconds from its first scan, and stops.
PARTICIPANT = """
import os, signal, sys, time
from rclpy.node import Node
from sensor_msgs.msg import LaserScan
from pppbot_lockstep.ros.participant import require_match
from pppbot_lockstep.ros.runner import run_nodes
target = int(sys.argv[1])
class Counter(Node):
    def __init__(self):
        super().__init__('bench_scan_counter')
        self.count, self.first = 0, None
        require_match(self, self.create_subscription(LaserScan, '/scan', self.on_scan, 10))
    def on_scan(self, msg):
        stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        if self.first is None:
            self.first = (stamp, time.perf_counter())
        self.count += 1
        if self.count == target:
            print('done', self.count, stamp - self.first[0], time.perf_counter() - self.first[1], flush=True)
            os.kill(os.getpid(), signal.SIGINT)
sys.exit(run_nodes([Counter], 'bench_scan_counter', sys.argv[2:]))
"""


def core_rtf(world: str, sim_seconds: float) -> float:
    from pppbot_description.urdf_model import parse_urdf
    from pppbot_description.xacro_model import process_xacro
    from pppbot_sim.simulation import Event, EventKind, Simulation, load_world
    from pppbot_sim.worlds import find_world, model_paths

    path = find_world(world)
    spec, _ = load_world(path, model_paths(path))
    sim = Simulation(spec, parse_urdf(process_xacro()))
    for kind, rate in ((EventKind.CLOCK, 100.0), (EventKind.JOINT_STATES, 100.0), (EventKind.GROUND_TRUTH, 50.0)):
        sim.schedule.add(Event(kind), rate)
    sim.set_wheel_velocities({"left_wheel_joint": 3.0, "right_wheel_joint": 2.5})
    start = time.perf_counter()
    while sim.time_s < sim_seconds:
        for event in sim.advance(1000):
            if event.kind is EventKind.LIDAR:
                sim.lidar_scan(event.index)
            elif event.kind is EventKind.IMU:
                sim.imu_sample(event.index)
            elif event.kind is EventKind.JOINT_STATES:
                sim.wheel_state()
            elif event.kind is EventKind.GROUND_TRUTH:
                sim.ground_truth()
    return sim_seconds / (time.perf_counter() - start)


def ros_rtf(world: str, sim_seconds: float, with_subscriber: bool) -> tuple[float, int]:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    from pppbot_lockstep.ros.runner import Process
    from pppbot_sim.ros.simulator import Simulator

    subscriber = None
    if with_subscriber:
        subscriber = subprocess.Popen([sys.executable, "-c", SUBSCRIBER], stdout=subprocess.PIPE, text=True,
                                      start_new_session=True)
        if subscriber.stdout is None or subscriber.stdout.readline().strip() != "ready":
            raise RuntimeError("the subscriber process did not start")
    try:
        rclpy.init(args=["--ros-args", "-p", f"world:={world}", "-p", "real_time_factor:=0.0",
                         "-p", "command_timeout:=0.0", "--log-level", "warn"])
        node = Simulator()
        node.runner.command({"left_wheel_joint": 3.0, "right_wheel_joint": 2.5})
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        start = time.perf_counter()
        node.run(Process(executor, None), until_s=sim_seconds)
        rtf = node.published_s / (time.perf_counter() - start)
        node.destroy_node()
        rclpy.shutdown()
    finally:
        out = ""
        if subscriber is not None:
            subscriber.send_signal(2)
            out, _ = subscriber.communicate(timeout=10)
    scans = int(out.split()[-1]) if out.strip() else 0
    return rtf, scans


def lockstep_rtf(world: str, sim_seconds: float) -> tuple[float, int, int]:
    """The simulator in lockstep with a participant counting /scan (10 Hz): (real-time factor
    over the participant's scans, scans received, scans expected)."""
    target = int(round(sim_seconds * 10))
    pppbot = str(ROOT / "pppbot")
    sim = subprocess.Popen([pppbot, "run", "pppbot_sim", "simulator", "--ros-args", "-p", f"world:={world}",
                            "-p", "lockstep:=true", "-p", "real_time_factor:=0.0",
                            "-p", "lockstep_participants:=[bench_scan_counter]", "-p", "command_timeout:=0.0",
                            "--log-level", "warn"], stdout=subprocess.DEVNULL, start_new_session=True)
    counter = subprocess.Popen([pppbot, "env", "python", "-c", PARTICIPANT, str(target), "--ros-args",
                                "-p", "use_sim_time:=true", "-p", "lockstep:=true", "--log-level", "warn"],
                               stdout=subprocess.PIPE, text=True, start_new_session=True)
    try:
        out, _ = counter.communicate(timeout=600)
    finally:
        for process in (counter, sim):
            if process.poll() is None:
                os.killpg(process.pid, 2)
                process.wait(timeout=30)
    done = [line.split() for line in out.splitlines() if line.startswith("done")]
    if not done:
        raise RuntimeError(f"the lockstep scan counter did not finish: {out!r}")
    _, count, sim_span, wall_span = done[-1]
    return float(sim_span) / float(wall_span), int(count), target


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sim-seconds", type=float, default=60.0)
    parser.add_argument("--worlds", nargs="+", default=["maze", "office"])
    args = parser.parse_args()
    isolate_dds()
    results = {"benchmark": "sim_speed", "sim_seconds": args.sim_seconds, "lidar_beams": 640,
               "lidar_rate_hz": 10, "cpu_count": os.cpu_count()}
    for world in args.worlds:
        core = core_rtf(world, args.sim_seconds)
        ros, _ = ros_rtf(world, args.sim_seconds, with_subscriber=False)
        ros_sub, scans = ros_rtf(world, args.sim_seconds, with_subscriber=True)
        lockstep, received, expected = lockstep_rtf(world, args.sim_seconds)
        results[f"{world}_lockstep_subscribed_real_time_factor"] = round(lockstep, 1)
        results[f"{world}_lockstep_scans_received"] = f"{received} of {expected}"
        results[f"{world}_core_real_time_factor"] = round(core, 1)
        results[f"{world}_ros_real_time_factor"] = round(ros, 1)
        results[f"{world}_ros_subscribed_real_time_factor"] = round(ros_sub, 1)
        results[f"{world}_scans_received"] = scans
        print(f"{world}: core {core:.1f}x, publishing {ros:.1f}x, publishing to a subscriber {ros_sub:.1f}x "
              f"({scans} scans received), in lockstep with a participant {lockstep:.1f}x ({received} of {expected} "
              "scans)", file=sys.stderr)
    results["real_time_factor"] = results.get("maze_ros_real_time_factor")
    results["target_lockstep_subscribed_real_time_factor"] = 50.0
    print(json.dumps(results))


if __name__ == "__main__":
    main()
