"""``pppbot foxglove`` with a WebSocket client speaking ``foxglove.sdk.v1``, as Foxglove does:
/scan arrives byte for byte with a ``ros2msg`` schema that an independent reader (rosbags)
decodes; a goal the client publishes reaches ROS; a topic off the client whitelist does not."""
from __future__ import annotations

import json
import math
import struct
import time
from pathlib import Path
from typing import Any

import pytest
from geometry_msgs.msg import PoseStamped, Twist
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from sensor_msgs.msg import LaserScan
from websockets.sync.client import connect
from websockets.typing import Subprotocol

from pppbot_common.process import listening_addresses, process_tree
from pppbot_common.ros.wait import wait_until

PPPBOT = str(Path(__file__).resolve().parents[2] / "pppbot")
pytestmark = pytest.mark.ros


def next_json(ws: Any, op: str, timeout_s: float = 20.0, where: Any = None) -> dict[str, Any]:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        frame = ws.recv(timeout=max(0.1, deadline - time.monotonic()))
        if isinstance(frame, str):
            message = json.loads(frame)
            if message.get("op") == op and (where is None or where(message)):
                return message
    raise TimeoutError(f"no '{op}' from the bridge within {timeout_s} s")


def first_message(ws: Any, channel_id: int, publish: Any, has_scan: Any, timeout_s: float = 30.0) -> bytes | None:
    """Subscribe to ``channel_id`` and return the first message's payload, calling ``publish``
    meanwhile. As Foxglove does, a /scan channel advertised again (the topic left the graph for
    a moment: another /scan publisher of the test process went) is subscribed again."""
    subscription_id = 7
    ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": subscription_id, "channelId": channel_id}]}))
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        publish()
        try:
            frame = ws.recv(timeout=0.5)
        except TimeoutError:
            continue
        if isinstance(frame, str):
            message = json.loads(frame)
            if message.get("op") == "advertise" and has_scan(message):
                channel_id = next(c for c in message["channels"] if c["topic"] == "/scan")["id"]
                subscription_id += 1
                ws.send(json.dumps({"op": "subscribe",
                                    "subscriptions": [{"id": subscription_id, "channelId": channel_id}]}))
        elif frame[0] == 0x01:
            subscription, _stamp = struct.unpack_from("<IQ", frame, 1)
            assert subscription == subscription_id
            return bytes(frame[13:])
    return None


def test_bridge_forwards_scans_and_takes_goals(ros_node, spawn):
    bridge = spawn([PPPBOT, "foxglove", "--port", "0"], name="foxglove")
    url = bridge.wait_for_output(r"Foxglove bridge: (ws://127\.0\.0\.1:\d+)", 60).group(1)
    assert listening_addresses(process_tree(bridge.pid)) == [("127.0.0.1", int(url.rsplit(":", 1)[1]))]

    scan_pub = ros_node.create_publisher(LaserScan, "/scan", 10)
    scan = LaserScan(angle_min=-1.0, angle_increment=0.5, range_min=0.1, range_max=12.0,
                     ranges=[1.0, 2.5, math.inf, 4.0, 0.25])
    scan.header.frame_id = "lidar_frame"
    goals: list[PoseStamped] = []
    ros_node.create_subscription(PoseStamped, "/goal_pose", goals.append, 10)
    scan_pub.publish(scan)

    with connect(url, subprotocols=[Subprotocol("foxglove.sdk.v1")], open_timeout=20) as ws:
        assert ws.subprotocol == "foxglove.sdk.v1"
        info = next_json(ws, "serverInfo")
        assert "clientPublish" in info["capabilities"] and "cdr" in info["supportedEncodings"]

        def has_scan(message: dict[str, Any]) -> bool:
            return any(c["topic"] == "/scan" for c in message["channels"])

        channel = next(c for c in next_json(ws, "advertise", where=has_scan)["channels"] if c["topic"] == "/scan")
        assert (channel["encoding"], channel["schemaName"], channel["schemaEncoding"]) == \
            ("cdr", "sensor_msgs/msg/LaserScan", "ros2msg")
        # The schema is the full definition: an independent reader builds the type from it.
        typestore = get_typestore(Stores.EMPTY)
        typestore.register(get_types_from_msg(channel["schema"], "sensor_msgs/msg/LaserScan"))
        payload = first_message(ws, channel["id"], lambda: scan_pub.publish(scan), has_scan)
        assert payload is not None, "no /scan message within 30 s"
        decoded: Any = typestore.deserialize_cdr(payload, "sensor_msgs/msg/LaserScan")
        assert decoded.header.frame_id == "lidar_frame"
        assert list(decoded.ranges) == pytest.approx([1.0, 2.5, math.inf, 4.0, 0.25])
        assert decoded.angle_increment == pytest.approx(0.5)

        # The client publishes a goal (CDR it serialized itself) and a command it may not send.
        jazzy = get_typestore(Stores.ROS2_JAZZY)
        ws.send(json.dumps({"op": "advertise", "channels": [
            {"id": 1, "topic": "/goal_pose", "encoding": "cdr", "schemaName": "geometry_msgs/msg/PoseStamped"},
            {"id": 2, "topic": "/cmd_vel", "encoding": "cdr", "schemaName": "geometry_msgs/msg/Twist"}]}))
        Pose = jazzy.types["geometry_msgs/msg/PoseStamped"]
        Header = jazzy.types["std_msgs/msg/Header"]
        Time = jazzy.types["builtin_interfaces/msg/Time"]
        PoseMsg = jazzy.types["geometry_msgs/msg/Pose"]
        Point = jazzy.types["geometry_msgs/msg/Point"]
        Quaternion = jazzy.types["geometry_msgs/msg/Quaternion"]
        goal = Pose(header=Header(stamp=Time(sec=0, nanosec=0), frame_id="map"),
                    pose=PoseMsg(position=Point(x=2.5, y=-1.0, z=0.0), orientation=Quaternion(x=0, y=0, z=0, w=1)))
        goal_bytes = bytes(jazzy.serialize_cdr(goal, "geometry_msgs/msg/PoseStamped"))
        twist_bytes = bytes(jazzy.serialize_cdr(jazzy.types["geometry_msgs/msg/Twist"](
            linear=jazzy.types["geometry_msgs/msg/Vector3"](x=1.0, y=0.0, z=0.0),
            angular=jazzy.types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)), "geometry_msgs/msg/Twist"))
        commands: list[Twist] = []
        ros_node.create_subscription(Twist, "/cmd_vel", commands.append, 10)

        def send_goal() -> PoseStamped | None:
            ws.send(b"\x01" + struct.pack("<I", 1) + goal_bytes)
            ws.send(b"\x01" + struct.pack("<I", 2) + twist_bytes)
            return goals[-1] if goals else None

        received = wait_until(send_goal, 30, "the client's goal on /goal_pose", node=ros_node)
        assert received.header.frame_id == "map"
        assert (received.pose.position.x, received.pose.position.y) == (2.5, -1.0)
        assert commands == []
        assert not any(p.node_name == "foxglove_bridge" for p in ros_node.get_publishers_info_by_topic("/cmd_vel"))
    assert "a client may not publish on /cmd_vel" in bridge.output
