"""The highest message rates `pppbot bag record` records with zero loss on this machine.

For each kind of message (a 640-beam LaserScan, and a small std_msgs/Header) the rate
doubles until the recorder loses a message or the publisher can't keep the rate. The
publisher is a separate process publishing pre-serialized messages (reliable, depth
10, like a sensor driver) for a few seconds; the recorder runs as `pppbot bag record`;
the bag is read back with rosbags and its count compared with what was published.

    ./pppbot env python benchmarks/bag_throughput.py [--seconds 5]
"""
from __future__ import annotations

import argparse
import json
import math
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from pppbot_common.dds_isolation import isolate_dds

ROOT = Path(__file__).resolve().parents[1]
TOPIC = "/bench"
KINDS = {"scan_640": ("sensor_msgs/msg/LaserScan", 50.0), "small_header": ("std_msgs/msg/Header", 500.0)}


def publish(kind: str, rate_hz: float, seconds: float) -> None:
    """Child mode: publish ``rate_hz`` messages for ``seconds`` once the recorder listens."""
    import rclpy
    from rclpy.qos import QoSProfile
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import LaserScan
    from std_msgs.msg import Header

    rclpy.init()
    node = rclpy.create_node("bag_bench_publisher")
    if kind == "scan_640":
        msg_class, sample = LaserScan, LaserScan(ranges=[1.5] * 640, intensities=[], range_max=20.0)
        sample.header.frame_id = "lidar_frame"
    else:
        msg_class, sample = Header, Header(frame_id="base_link")
    pub = node.create_publisher(msg_class, TOPIC, QoSProfile(depth=10))
    deadline = time.monotonic() + 30
    while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(0.5)
    total = int(rate_hz * seconds)
    data = serialize_message(sample)
    start = time.monotonic()
    for i in range(total):
        due = start + i / rate_hz
        while (now := time.monotonic()) < due:
            time.sleep(min(due - now, 0.001))
        pub.publish(data)
    elapsed = time.monotonic() - start
    time.sleep(1.0)  # let reliable delivery finish
    print(json.dumps({"published": total, "achieved_hz": total / elapsed}), flush=True)
    node.destroy_node()
    rclpy.shutdown()


def one_run(kind: str, rate_hz: float, seconds: float, workdir: Path) -> dict[str, float]:
    bag = workdir / f"{kind}_{int(rate_hz)}"
    recorder = subprocess.Popen([str(ROOT / "pppbot"), "bag", "record", TOPIC, "-o", str(bag)],
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)
    try:
        publisher = subprocess.run([sys.executable, __file__, "--publish", kind, str(rate_hz), str(seconds)],
                                   capture_output=True, text=True, timeout=seconds * 4 + 60)
        sent = json.loads(publisher.stdout.strip().splitlines()[-1])
    finally:
        recorder.send_signal(signal.SIGINT)
        recorder.wait(60)
    from rosbags.rosbag2 import Reader

    with Reader(bag) as reader:
        recorded = reader.message_count
    return {"rate_hz": rate_hz, "published": sent["published"], "recorded": recorded,
            "lost": sent["published"] - recorded, "achieved_hz": round(sent["achieved_hz"], 1)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=5.0, help="publishing time per step")
    parser.add_argument("--publish", nargs=3, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.publish:
        publish(args.publish[0], float(args.publish[1]), float(args.publish[2]))
        return
    isolate_dds()
    results: dict[str, object] = {}
    with tempfile.TemporaryDirectory(prefix="bag_bench_") as tmp:
        for kind, (type_name, first_rate) in KINDS.items():
            best, steps, rate = 0.0, [], first_rate
            while True:
                run = one_run(kind, rate, args.seconds, Path(tmp))
                steps.append(run)
                print(f"{kind} ({type_name}) at {rate:g} Hz: published {run['published']} "
                      f"(achieved {run['achieved_hz']:g} Hz), recorded {run['recorded']}, lost {run['lost']}",
                      flush=True)
                publisher_limited = run["achieved_hz"] < 0.9 * rate
                if run["lost"] != 0 or publisher_limited:
                    break
                best = rate
                rate *= 2
                if math.isinf(rate):
                    break
            results[f"{kind}_max_zero_loss_hz"] = best
            results[f"{kind}_limited_by"] = "publisher" if publisher_limited and run["lost"] == 0 else "recorder"
            results[f"{kind}_mb_per_s"] = round(best * (2600 if kind == "scan_640" else 20) / 1e6, 2)
    print(json.dumps(results))


if __name__ == "__main__":
    main()
