"""A node's clock on a time its host sets, as a simulator sets the clock of the controllers it
hosts (they run on the simulation itself, not on ``/clock``).

rclpy's public way: a :class:`rclpy.time_source.TimeSource` without a node (so no ``/clock``
subscription) attached to the node's clock, with ROS time active; each tick overrides the time.
"""
from __future__ import annotations

from rclpy.clock import ClockType, ROSClock
from rclpy.node import Node
from rclpy.time import Time
from rclpy.time_source import TimeSource


class DrivenClock:
    """``node``'s clock, set by :meth:`set`; its time before the first :meth:`set` is 0."""

    def __init__(self, node: Node) -> None:
        clock = node.get_clock()
        if not isinstance(clock, ROSClock):
            raise ValueError(f"node '{node.get_name()}' has a {clock.clock_type} clock: only a ROS_TIME clock "
                             "can be driven")
        self._clock = clock
        self._source = TimeSource()  # no node: it subscribes to nothing
        self._source.attach_clock(clock)
        self._source.ros_time_is_active = True

    def set(self, t_ns: int) -> None:
        """The node's time is ``t_ns`` (ns) from now on."""
        self._clock.set_ros_time_override(Time(nanoseconds=t_ns, clock_type=ClockType.ROS_TIME))
