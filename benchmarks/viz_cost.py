"""What the live view costs: the viz node's CPU at 1× while the robot navigates, and the memory
of the viz node and the rerun server over a run of ``--seconds``.

Runs ``launch_sim localization:=true`` in ``--world`` (default room: map, both costmaps,
scan, TF, robot model, particles, amcl_pose; no camera topic, and no SLAM graph since it
localizes), or with ``--mapping`` ``launch_sim localization:=false navigation:=true`` (the
SLAM map growing, its pose graph, both costmaps, scan, TF, robot model; no particles), with
the live view on, on a DDS domain of its own, and sends the navigator goals back and forth
between two points (plans, local plans) while it measures. The real-time
factor reached is not checked: a slower simulation would make the share look smaller. A
browser is not needed: the server streams the same either way, and a viewer's cost is the
browser's, not the robot's.

Figures: the viz node's and the server's CPU (% of one core, /proc) over the run, their RSS
every ``--sample`` seconds and at its end, and the sim time reached; one JSON object with
the figures and the targets is the last line.

    ./pppbot env python benchmarks/viz_cost.py [--world room] [--seconds 120]
    ./pppbot env python benchmarks/viz_cost.py --mapping --seconds 3600   # memory after an hour
"""
from __future__ import annotations

import argparse
import json
import math
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from pppbot_common.dds_isolation import isolate_dds

ROOT = Path(__file__).resolve().parent.parent
PPPBOT = str(ROOT / "pppbot")
TICKS = os.sysconf("SC_CLK_TCK")
TARGETS = {"viz_cpu_per_1x_pct": 15.0}
#: two free points of the room world, in its map frame
GOALS = ((2.0, 1.0, 0.0), (-1.0, -1.0, math.pi))


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICKS


def rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return 0.0


def send_goals(stop: threading.Event, clock: dict[str, float]) -> None:
    """Publish /goal_pose, alternating between GOALS every 30 s, as RViz's tool would; keep the
    newest /clock in ``clock["sim_seconds"]``."""
    import rclpy
    from geometry_msgs.msg import PoseStamped
    from rosgraph_msgs.msg import Clock
    rclpy.init()
    node = rclpy.create_node("viz_cost_goals")
    publisher = node.create_publisher(PoseStamped, "/goal_pose", 10)
    node.create_subscription(Clock, "/clock", lambda m: clock.update(sim_seconds=m.clock.sec + m.clock.nanosec * 1e-9),
                             10)
    index, last = 0, -math.inf
    while not stop.is_set():
        if time.monotonic() - last >= 30.0:
            x, y, yaw = GOALS[index % len(GOALS)]
            goal = PoseStamped()
            goal.header.frame_id = "map"
            goal.pose.position.x, goal.pose.position.y = x, y
            goal.pose.orientation.z, goal.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
            publisher.publish(goal)
            index, last = index + 1, time.monotonic()
        rclpy.spin_once(node, timeout_sec=0.5)
    node.destroy_node()
    rclpy.try_shutdown()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--world", default="room")
    parser.add_argument("--seconds", type=float, default=120.0)
    parser.add_argument("--sample", type=float, default=300.0, help="seconds between RSS samples")
    parser.add_argument("--mapping", action="store_true", help="map with SLAM (and navigate on its map)")
    parser.add_argument("--real-time-factor", type=float, default=1.0,
                        help="sim speed (default 1: the CPU target's; 3 reaches an hour of sim time in 20 minutes "
                             "for the memory figure, at three times the CPU)")
    args = parser.parse_args()
    isolate_dds()
    mode = ["localization:=false", "navigation:=true"] if args.mapping else ["localization:=true"]
    proc = subprocess.Popen([PPPBOT, "launch_sim", f"world:={args.world}", *mode, "use_teleop:=false",
                             f"real_time_factor:={args.real_time_factor}",
                             "use_rviz:=false", "viz_port:=0", "viz_viewer:=web"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    output: list[str] = []
    up = threading.Event()

    def read() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            output.append(line)
            if "ppp_bot is up" in line:
                up.set()

    threading.Thread(target=read, daemon=True).start()
    stop = threading.Event()
    try:
        if not up.wait(180):
            sys.exit("the bringup did not come up in 180 s:\n" + "".join(output[-30:]))
        pids = {name: int(pid) for name, pid in re.findall(r"\[(viz|rerun)-1\]: process started with pid \[(\d+)\]",
                                                           "".join(output))}
        clock: dict[str, float] = {}
        goals = threading.Thread(target=send_goals, args=(stop, clock), daemon=True)
        goals.start()
        time.sleep(10.0)  # the first plan
        start = {name: cpu_seconds(pid) for name, pid in pids.items()}
        t0 = time.monotonic()
        samples: list[dict[str, float]] = []
        while (left := args.seconds - (time.monotonic() - t0)) > 0:
            time.sleep(min(args.sample, left))
            samples.append({"seconds": round(time.monotonic() - t0), **{f"{name}_rss_mb": round(rss_mb(pid), 1)
                                                                        for name, pid in pids.items()}})
            print(f"after {samples[-1]['seconds']} s: {samples[-1]}", file=sys.stderr, flush=True)
        elapsed = time.monotonic() - t0
        sim_seconds = clock.get("sim_seconds", 0.0)
        cpu = {name: round(100.0 * (cpu_seconds(pid) - start[name]) / elapsed, 1) for name, pid in pids.items()}
        rss = {name: round(rss_mb(pid), 1) for name, pid in pids.items()}
    finally:
        stop.set()
        proc.send_signal(signal.SIGINT)
        proc.wait(60)
    for name in sorted(pids):
        print(f"{name}: {cpu[name]} % of a core, {rss[name]} MB RSS after {elapsed:.0f} s")
    figures = {"world": args.world, "mode": "mapping" if args.mapping else "localization",
               "real_time_factor": args.real_time_factor,
               "seconds": round(elapsed, 1), "rss_samples": samples,
               "sim_seconds": round(sim_seconds, 1), "viz_cpu_pct": cpu["viz"],
               "viz_cpu_per_1x_pct": round(cpu["viz"] / args.real_time_factor, 1), "rerun_server_cpu_pct": cpu["rerun"],
               "viz_rss_mb": rss["viz"], "rerun_server_rss_mb": rss["rerun"],
               "targets": TARGETS, "cores": os.cpu_count()}
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
