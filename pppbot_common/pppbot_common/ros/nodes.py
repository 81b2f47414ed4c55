"""Nodes that no executor spins all the time: they offer no service."""
from __future__ import annotations

from typing import Any

import rclpy
from rclpy.node import Node
from rclpy.parameter import Parameter


def unspun_node(name: str, **kwargs: Any) -> Node:
    """``rclpy.create_node`` for a node that only publishes, or only calls services while it waits
    for their answers: no parameter services, and not rclpy's ``~/get_type_description`` either.
    A service that no executor serves leaves whoever asks it (``ros2 param list``, a tool looking a
    type up) waiting forever."""
    overrides = [*kwargs.pop("parameter_overrides", []), Parameter("start_type_description_service", value=False)]
    return rclpy.create_node(name, start_parameter_services=False, parameter_overrides=overrides, **kwargs)
