"""``costmap_filter_info_server``: what a costmap filter's mask means, Nav2's node.

Publishes one ``nav2_msgs/CostmapFilterInfo`` (latched) on ``filter_info_topic`` once active:
the filter ``type`` (0 keepout, 1 speed in %, 2 speed in m/s, 3 binary), the ``mask_topic`` a
``map_server`` serves the mask on, and the conversion ``base + multiplier · mask value``. A
costmap's filter (:mod:`pppbot_nav.costmap.filters`) reads it, then the mask. A lifecycle node,
as Nav2's (``lifecycle_manager_costmap_filters`` brings it up with the mask's map_server).

    ./pppbot run pppbot_nav costmap_filter_info_server --ros-args -p type:=1 -p mask_topic:=/speed_filter_mask
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from typing import Any

from nav2_msgs.msg import CostmapFilterInfo

from pppbot_common.params import ParameterError, param
from pppbot_common.ros.params import declare_parameters, fixed_parameters
from pppbot_common.ros.qos import LATCHED
from pppbot_lockstep.ros.lifecycle import ManagedNode
from pppbot_lockstep.ros.runner import run_nodes
from pppbot_nav.costmap.filters import BINARY, KEEPOUT, SPEED_ABSOLUTE, SPEED_PERCENT

TYPES = {KEEPOUT: "keepout", SPEED_PERCENT: "speed (%)", SPEED_ABSOLUTE: "speed (m/s)", BINARY: "binary"}


@dataclass(frozen=True)
class CostmapFilterInfoParameters:
    type: int = param(0, "0 keepout / preferred lanes, 1 speed limit in %, 2 speed limit in m/s, 3 binary")
    filter_info_topic: str = param("costmap_filter_info", "where the info is published (latched)")
    mask_topic: str = param("filter_mask", "the mask's topic (its map_server's topic_name)")
    base: float = param(0.0, "filter value = base + multiplier · mask value")
    multiplier: float = param(1.0, "filter value = base + multiplier · mask value")

    def validate(self) -> None:
        if self.type not in TYPES:
            known = ", ".join(f"{k} ({v})" for k, v in TYPES.items())
            raise ParameterError("type", self.type, f"must be one of {known}")
        for name in ("filter_info_topic", "mask_topic"):
            if not getattr(self, name):
                raise ParameterError(name, getattr(self, name), "must name a topic")
        for name in ("base", "multiplier"):
            if not math.isfinite(getattr(self, name)):
                raise ParameterError(name, getattr(self, name), "must be a finite number")


class CostmapFilterInfoServer(ManagedNode):
    def __init__(self, name: str = "costmap_filter_info_server", **kwargs: Any) -> None:
        super().__init__(name, **kwargs)
        self.params = p = declare_parameters(self, CostmapFilterInfoParameters)
        fixed_parameters(self, lambda: self.params)  # Nav2's has no dynamic parameters
        self.pub = self.create_publisher(CostmapFilterInfo, p.filter_info_topic, LATCHED)

    def activate(self) -> None:
        p = self.params
        msg = CostmapFilterInfo(type=p.type, filter_mask_topic=p.mask_topic, base=float(p.base),
                                multiplier=float(p.multiplier))
        msg.header.stamp = self.get_clock().now().to_msg()
        self.pub.publish(msg)
        self.get_logger().info(f"{TYPES[p.type]} filter info on {self.pub.topic_name}: mask '{p.mask_topic}', "
                               f"value = {p.base:g} + {p.multiplier:g} · mask")


def main(args: list[str] | None = None) -> int:
    return run_nodes([CostmapFilterInfoServer], "costmap_filter_info_server", args)


if __name__ == "__main__":
    sys.exit(main())
