"""Publish tf2_msgs/TFMessage on /tf and nav2_msgs/ParticleCloud on /particle_cloud.

Message k (k = 0, 1, ...) carries k in its stamp's nanosec field and k·0.01 m in
its x positions, so a subscriber can check contents and order. Prints "ready"
once both publishers exist. Stops on SIGINT.
"""
from __future__ import annotations

import sys

import rclpy
from geometry_msgs.msg import Pose, TransformStamped
from nav2_msgs.msg import Particle, ParticleCloud
from rclpy.executors import ExternalShutdownException
from tf2_msgs.msg import TFMessage


def main() -> None:
    rate_hz = float(sys.argv[1]) if len(sys.argv) > 1 else 20.0
    rclpy.init()
    node = rclpy.create_node("tf_particle_talker")
    tf_pub = node.create_publisher(TFMessage, "/tf", 10)
    cloud_pub = node.create_publisher(ParticleCloud, "/particle_cloud", 10)
    k = 0

    def tick() -> None:
        nonlocal k
        t = TransformStamped()
        t.header.stamp.nanosec = k
        t.header.frame_id = "odom"
        t.child_frame_id = "base_link"
        t.transform.translation.x = 0.01 * k
        t.transform.rotation.w = 1.0
        cloud = ParticleCloud()
        cloud.header.stamp.nanosec = k
        cloud.header.frame_id = "map"
        for i in range(3):
            pose = Pose()
            pose.position.x = 0.01 * k
            pose.position.y = float(i)
            pose.orientation.w = 1.0
            cloud.particles.append(Particle(pose=pose, weight=1.0 / 3.0))
        tf_pub.publish(TFMessage(transforms=[t]))
        cloud_pub.publish(cloud)
        k += 1

    node.create_timer(1.0 / rate_hz, tick)
    print("ready", flush=True)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
