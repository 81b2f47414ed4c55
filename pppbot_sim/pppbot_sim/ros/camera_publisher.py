"""The simulator's cameras on ROS: Image, CameraInfo and (depth cameras) PointCloud2, as Gazebo and
ros_gz_bridge publish them (:mod:`pppbot_sim.cameras` has the topics, frames and values).

A camera is rendered only while someone subscribes to one of its topics (a point cloud only while
someone subscribes to it); the OpenGL context is made when the first frame is wanted. Frames are
rendered and published from the camera thread (:mod:`pppbot_sim.camera_worker`), stamped with the
sim time of the state they show, by a node of their own in a DDS participant of their own (see
:class:`CameraPublisher`): a plain rclpy node, outside lockstep's counting: no lockstep
participant waits for them and they never make another round, so cameras cannot change what
lidar, odometry or the controllers do.
"""
from __future__ import annotations

from collections.abc import Callable

import rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import CameraInfo, Image, PointCloud2, PointField

from pppbot_common.ros.nodes import unspun_node
from pppbot_common.ros.wire import MessageTemplate, stamp_fields, stamp_values
from pppbot_sim.camera_worker import CameraFrame, CameraWorker, FrameRequest
from pppbot_sim.cameras import POINT_FIELDS, POINT_STEP, CameraKind, CameraSpec
from pppbot_sim.render import backend_name, refused_backend
from pppbot_sim.runner import CameraReading
from pppbot_sim.simulation import Simulation

#: Camera messages are large (a 640 x 480 point cloud is 7 MB): few are kept for late readers.
CAMERA_QOS = QoSProfile(depth=2)


def _ns(seconds: float) -> int:
    return int(round(seconds * 1e9))


class _CameraTopics:
    """One camera's publishers (on the topics ``resolve`` gives) and message templates."""

    def __init__(self, node: Node, spec: CameraSpec, resolve: Callable[[str], str]) -> None:
        self.spec = spec
        self.image = node.create_publisher(Image, resolve(spec.topic), CAMERA_QOS)
        self.info = node.create_publisher(CameraInfo, resolve(spec.info_topic), CAMERA_QOS)
        self.points = (node.create_publisher(PointCloud2, resolve(spec.points_topic), CAMERA_QOS)
                       if spec.kind is CameraKind.DEPTH else None)
        fmt = spec.pixel_format
        image = Image(height=spec.height, width=spec.width, encoding=fmt.encoding, is_bigendian=0,
                      step=spec.width * fmt.bytes_per_pixel)
        image.header.frame_id = spec.frame_id
        image.data = bytes(spec.height * spec.width * fmt.bytes_per_pixel)
        self.image_wire = MessageTemplate(image, [*stamp_fields(), "data"])
        info = CameraInfo(height=spec.height, width=spec.width, distortion_model="plumb_bob",
                          d=list(spec.distortion), k=spec.k_matrix(),
                          r=[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0], p=spec.p_matrix())
        info.header.frame_id = spec.frame_id
        self.info_wire = MessageTemplate(info, stamp_fields())
        self.points_wire: MessageTemplate | None = None
        if self.points is not None:
            cloud = PointCloud2(height=spec.height, width=spec.width, is_bigendian=False, point_step=POINT_STEP,
                                row_step=POINT_STEP * spec.width, is_dense=True,
                                fields=[PointField(name=n, offset=o, datatype=PointField.FLOAT32, count=1)
                                        for n, o in POINT_FIELDS])
            cloud.header.frame_id = spec.frame_id
            cloud.data = bytes(POINT_STEP * spec.width * spec.height)
            self.points_wire = MessageTemplate(cloud, [*stamp_fields(), "data", "is_dense"])

    def names(self) -> list[str]:
        return [p.topic_name for p in (self.image, self.info, self.points) if p is not None]

    def subscribed(self) -> bool:
        return any(p is not None and p.get_subscription_count() > 0 for p in (self.image, self.info, self.points))

    def wants_points(self) -> bool:
        return self.points is not None and self.points.get_subscription_count() > 0

    def publish(self, frame: CameraFrame) -> None:
        """``frame``'s messages, outside lockstep's counting (nothing in lockstep waits for them)."""
        stamp = stamp_values(_ns(frame.stamp_s))
        pixels = frame.image if frame.image is not None else frame.depth
        if pixels is not None:
            self.image.publish(self.image_wire.serialize({**stamp, "data": pixels.reshape(-1).view("<B")}))
        self.info.publish(self.info_wire.serialize(stamp))
        if frame.points is not None and self.points is not None and self.points_wire is not None:
            self.points.publish(self.points_wire.serialize(
                {**stamp, "data": frame.points, "is_dense": frame.dense}))


class CameraPublisher:
    """The cameras of ``sim`` for ``node``; ``enabled`` False: none (no topics either).

    The camera topics are published by a node of their own, ``<node>_cameras``, in an rclpy context
    of its own: a DDS participant of its own, as ros_gz_bridge is for Gazebo's cameras. Megabyte
    frames through the simulator's participant held up its small messages (lockstep's steps, the
    clock, scans) by seconds: the mapping stack in lockstep went from 3.9x to 0.3x real time
    with the camera watched; through their own participant it stays at 3.9x
    (``benchmarks/camera_speed.py``). Topic names are resolved by ``node`` (its namespace and
    remappings).

    Args:
        warn: a node's throttled warning (kind, text).
        error: the node's error log (once, when the cameras turn off).
    """

    def __init__(self, node: Node, sim: Simulation, seed: int, enabled: bool,
                 warn: Callable[[str, str], None], error: Callable[[str], None], *, every_frame: bool = False) -> None:
        self.sim = sim
        #: render every frame, waiting for the renderer (lockstep), instead of skipping what it cannot keep up with
        self.every_frame = every_frame
        self.seed = seed
        #: why the cameras are off although asked for (no OpenGL backend), if known at the start
        self.unavailable = refused_backend() if enabled and sim.cameras else None
        self.enabled = enabled and bool(sim.cameras) and self.unavailable is None
        self._warn = warn
        self._error = error
        self.worker: CameraWorker | None = None
        self._context: rclpy.Context | None = None
        self.node: Node | None = None
        self.topics: list[_CameraTopics] = []
        if self.enabled:
            self._context = rclpy.Context()
            rclpy.init(args=[], context=self._context, domain_id=node.context.get_domain_id(),
                       signal_handler_options=SignalHandlerOptions.NO)
            self.node = unspun_node(f"{node.get_name()}_cameras", namespace=node.get_namespace(),
                                    context=self._context)
            self.topics = [_CameraTopics(self.node, b.spec, node.resolve_topic_name) for b in sim.cameras]

    def describe(self) -> list[str]:
        """One line per camera for the start-up log."""
        if not self.sim.cameras:
            return []
        if self.unavailable is not None:
            return [f"cameras off: {self.unavailable}; everything else runs"]
        if not self.enabled:
            return [f"cameras off (cameras:=false): {', '.join(b.spec.name for b in self.sim.cameras)}"]
        lines = []
        for binding, topics in zip(self.sim.cameras, self.topics, strict=True):
            s = binding.spec
            lines.append(f"{s.kind.value} '{s.name}': {s.width}x{s.height} {s.pixel_format.encoding} at "
                         f"{s.rate_hz:g} Hz, hfov {s.hfov_rad:g} rad, clip {s.near_m:g}-{s.far_m:g} m on "
                         f"{', '.join(topics.names())} (frame {s.frame_id}); rendered while subscribed "
                         f"(MUJOCO_GL={backend_name()})")
        return lines

    def wanted(self, index: int) -> bool:
        """Whether camera ``index``'s frame is worth rendering now."""
        if not self.enabled:
            return False
        if self.worker is not None and self.worker.failed is not None:
            self._turn_off()
            return False
        return self.topics[index].subscribed()

    def submit(self, reading: CameraReading) -> None:
        """Render ``reading``'s frame in the camera thread (made at the first frame)."""
        if self.worker is None:
            self.worker = CameraWorker(self.sim.model, self.sim.cameras, self.seed, self._deliver,
                                       lambda text: self._warn("camera", text), every_frame=self.every_frame)
        self.worker.submit(FrameRequest(reading.index, reading.state, self.topics[reading.index].wants_points()))

    def _deliver(self, frame: CameraFrame) -> None:
        self.topics[frame.index].publish(frame)

    def _turn_off(self) -> None:
        assert self.worker is not None
        self._error(f"cameras off: {self.worker.failed}; everything else runs")
        self.enabled = False

    def close(self) -> None:
        """Stop rendering, then the cameras' node and context."""
        if self.worker is not None:
            self.worker.close()
        if self.node is not None:
            self.node.destroy_node()
            self.node = None
        if self._context is not None:
            rclpy.try_shutdown(context=self._context)
            self._context = None
