"""``robot_state_publisher``: Jazzy's node of that name, for pppbot.

Publishes the URDF on ``/robot_description`` (transient local), every fixed joint
on ``/tf_static`` once, and the moving joints on ``/tf`` from ``/joint_states``
(stamped with the message's stamp). Parameters as Jazzy's: ``robot_description``,
``publish_frequency``, ``ignore_timestamp``, ``frame_prefix``; in addition,
``robot_description`` may be the path of a ``.urdf`` or ``.xacro`` file, and when it
is empty ppp_bot's own ``robot.urdf.xacro`` is used. Setting ``robot_description``
at run time republishes everything.
"""
from __future__ import annotations

import functools
import math
import sys
from dataclasses import dataclass
from pathlib import Path

from geometry_msgs.msg import TransformStamped
from rclpy.time import Time
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage

from pppbot_common.params import ParameterError, check_finite_range, param
from pppbot_common.ros.params import declare_parameters, on_valid_update
from pppbot_common.ros.qos import LATCHED
from pppbot_description.errors import DescriptionError
from pppbot_description.kinematics import FrameTransform, KinematicTree
from pppbot_description.urdf_model import RobotModel, parse_urdf
from pppbot_description.xacro_model import read_robot_description
from pppbot_lockstep.ros.node import StepNode
from pppbot_lockstep.ros.runner import guarded, run_node

#: What tf2's StaticTransformBroadcaster uses: reliable, transient local, depth 1.
TF_STATIC_QOS = LATCHED
WARN_PERIOD_S = 5.0


def load_description(value: str) -> tuple[str, str, RobotModel]:
    """``(urdf_xml, source, model)`` from the parameter: XML, a file path, or empty for ppp_bot.

    Cached by value and file modification time, so validating a value and then
    applying it parses once, and an edited file is read again.

    Raises:
        DescriptionError: unreadable file, xacro error, or a malformed URDF.
    """
    path = Path(value.strip()) if value.strip() and not value.strip().startswith("<") else None
    try:
        mtime = path.stat().st_mtime_ns if path is not None else 0
    except OSError:
        mtime = -1
    return _load_description(value, mtime)


@functools.lru_cache(maxsize=4)
def _load_description(value: str, mtime: int) -> tuple[str, str, RobotModel]:
    urdf, source = read_robot_description(value)
    return urdf, source, parse_urdf(urdf, source)


@dataclass(frozen=True)
class RspParameters:
    robot_description: str = param("", "URDF XML, or a .urdf/.xacro path; empty = ppp_bot's robot.urdf.xacro")
    publish_frequency: float = param(20.0, "maximum rate (Hz) of /tf for moving joints")
    ignore_timestamp: bool = param(False, "publish a /tf for every /joint_states message regardless of rate")
    frame_prefix: str = param("", "prefix added to every published frame")

    def validate(self) -> None:
        check_finite_range("publish_frequency", self.publish_frequency, 0.0, 1000.0)
        if any(c.isspace() for c in self.frame_prefix):
            raise ParameterError("frame_prefix", self.frame_prefix, "must not contain white space")
        try:
            load_description(self.robot_description)
        except DescriptionError as exc:
            raise ParameterError("robot_description", _abbreviate(self.robot_description), str(exc)) from exc


def _abbreviate(text: str, limit: int = 60) -> str:
    return text if len(text) <= limit else text[:limit] + "..."


def to_msg(t: FrameTransform, stamp: Time) -> TransformStamped:
    msg = TransformStamped()
    msg.header.stamp = stamp.to_msg()
    msg.header.frame_id = t.parent
    msg.child_frame_id = t.child
    msg.transform.translation.x, msg.transform.translation.y, msg.transform.translation.z = t.translation
    r = msg.transform.rotation
    r.x, r.y, r.z, r.w = t.rotation
    return msg


class RobotStatePublisher(StepNode):
    def __init__(self, **kwargs: object) -> None:
        super().__init__("robot_state_publisher", **kwargs)  # type: ignore[arg-type]
        self.params = declare_parameters(self, RspParameters)
        self.description_pub = self.create_publisher(String, "robot_description", LATCHED)
        self.tf_static_pub = self.create_publisher(TFMessage, "/tf_static", TF_STATIC_QOS)
        # Wheel transforms: for RViz; nobody in lockstep reacts to them (no extra round).
        self.tf_pub = self.create_publisher(TFMessage, "/tf", 100, aside=True)
        self._last_published: Time | None = None
        self._load(self.params)
        # In lockstep (launch_sim lockstep:=true) its wheel transforms are part of each step's /tf.
        self.create_subscription(JointState, "joint_states", guarded(self, self.on_joint_states, "JointState"), 10,
                                 data_path=True, needs_publisher=False)
        on_valid_update(self, lambda: self.params, self._load)

    def _load(self, params: RspParameters) -> None:
        urdf, source, self.model = load_description(params.robot_description)
        self.tree = KinematicTree(self.model, params.frame_prefix)
        self.params = params
        self._last_published = None
        self.description_pub.publish(String(data=urdf))
        now = self.get_clock().now()
        self.tf_static_pub.publish(TFMessage(transforms=[to_msg(t, now) for t in self.tree.fixed_transforms()]))
        self.get_logger().info(
            f"robot '{self.model.name}' from {source}: {len(self.model.links)} links, "
            f"{len(self.tree.fixed_joints)} fixed and {len(self.tree.moving_joints)} moving joints"
        )

    def on_joint_states(self, msg: JointState) -> None:
        if len(msg.name) != len(msg.position):
            self.get_logger().warning(
                f"dropping a JointState with {len(msg.name)} names but {len(msg.position)} positions",
                throttle_duration_sec=WARN_PERIOD_S)
            return
        positions = dict(zip(msg.name, msg.position, strict=False))
        unknown = self.tree.unknown_names(positions)
        if unknown:
            self.get_logger().warning(f"ignoring unknown joint(s) {', '.join(sorted(unknown))}",
                                      throttle_duration_sec=WARN_PERIOD_S)
        bad = sorted(n for n, q in positions.items() if n in self.tree.moving_joints and not math.isfinite(q))
        if bad:
            self.get_logger().warning(f"ignoring non-finite position(s) of {', '.join(bad)}",
                                      throttle_duration_sec=WARN_PERIOD_S)
        if msg.header.stamp.sec < 0:
            self.get_logger().warning(f"dropping a JointState with a negative stamp ({msg.header.stamp.sec} s)",
                                      throttle_duration_sec=WARN_PERIOD_S)
            return
        stamp = Time.from_msg(msg.header.stamp, clock_type=self.get_clock().clock_type)
        if not self._due(stamp):
            return
        transforms = self.tree.moving_transforms(positions)
        if transforms:
            self.tf_pub.publish(TFMessage(transforms=[to_msg(t, stamp) for t in transforms]))
            self._last_published = stamp

    def _due(self, stamp: Time) -> bool:
        """Rate limit by message time, as Jazzy's node does; a jump back in time resets it."""
        if self.params.ignore_timestamp or self._last_published is None or self.params.publish_frequency == 0.0:
            return True
        elapsed_s = (stamp - self._last_published).nanoseconds * 1e-9
        if elapsed_s < 0:
            self.get_logger().warning("moved backwards in time, re-publishing joint transforms")
            return True
        return elapsed_s >= 1.0 / self.params.publish_frequency


def main(args: list[str] | None = None) -> int:
    return run_node(RobotStatePublisher, "robot_state_publisher", args, fatal=(ParameterError, DescriptionError))


if __name__ == "__main__":
    sys.exit(main())
