"""``map_saver``: saves a map topic to Nav2 map files on request (nav2_map_server's map_saver_server).

Service ``~/save_map`` (nav2_msgs/srv/SaveMap, so ``/map_saver/save_map``): each
request subscribes to its ``map_topic`` (default ``map``), waits up to
``save_map_timeout`` seconds (wall clock) for one map, and writes
``<map_url>.yaml`` and ``<map_url>.<image_format>`` with the request's
``map_mode`` and thresholds (:mod:`pppbot_nav.map_saving` fills in Nav2's defaults
for empty and zero fields; an empty ``map_url`` saves to ``maps/map_<unix time>``).
The reply's ``result`` says whether the files were written; the log says why not.

The subscription is transient local (reliable, depth 1), so a latched map such as
``/map`` of slam or map_server arrives at once; ``map_subscribe_transient_local:
false`` subscribes volatile (depth 10) for publishers that do not latch.
"""
from __future__ import annotations

import sys
import threading
import time
from dataclasses import dataclass
from typing import Any

import rclpy
from nav2_msgs.srv import SaveMap
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.exceptions import InvalidTopicNameException
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile

from pppbot_common.maps import MapFileError, OccupancyGrid, save_map
from pppbot_common.params import ParameterError, check_finite_range, param
from pppbot_common.resources import maps_directory
from pppbot_common.ros.maps import grid_from_message
from pppbot_common.ros.params import declare_parameters, on_valid_update
from pppbot_common.ros.qos import DEFAULT, LATCHED
from pppbot_lockstep.ros.node import answering
from pppbot_lockstep.ros.runner import run_node
from pppbot_nav.errors import MapSaverError
from pppbot_nav.map_saving import (
    DEFAULT_FREE_THRESH,
    DEFAULT_OCCUPIED_THRESH,
    SaveSettings,
    resolve_save_settings,
    unset_if_zero,
)

DEFAULT_MAP_TOPIC = "map"


@dataclass(frozen=True)
class MapSaverParameters:
    save_map_timeout: float = param(2.0, "seconds (wall clock) a save request waits for a map on its topic")
    free_thresh_default: float = param(DEFAULT_FREE_THRESH, "free threshold of requests that leave it 0")
    occupied_thresh_default: float = param(DEFAULT_OCCUPIED_THRESH,
                                           "occupied threshold of requests that leave it 0")
    map_subscribe_transient_local: bool = param(
        True, "subscribe transient local, reliable, depth 1 (latched maps); false: volatile, depth 10")

    def validate(self) -> None:
        check_finite_range("save_map_timeout", self.save_map_timeout, 0.0, 3600.0, low_open=True)
        check_finite_range("free_thresh_default", self.free_thresh_default, 0.0, 1.0)
        check_finite_range("occupied_thresh_default", self.occupied_thresh_default, 0.0, 1.0)
        if not self.free_thresh_default < self.occupied_thresh_default:
            raise ParameterError("free_thresh_default", self.free_thresh_default,
                                 f"must be below occupied_thresh_default ({self.occupied_thresh_default})")


def map_qos(transient_local: bool) -> QoSProfile:
    """Nav2's map_saver subscription: latched (transient local, reliable, depth 1) or volatile depth 10."""
    return LATCHED if transient_local else DEFAULT


def write_map(msg: OccupancyGridMsg, settings: SaveSettings) -> OccupancyGrid:
    """Write ``msg`` as ``settings`` say (to ``settings.yaml_path`` and ``.image_path``);
    returns the grid written.

    Raises:
        ValueError: a malformed map message (data size, resolution).
        MapFileError, OSError: the files cannot be written.
    """
    grid = grid_from_message(msg)
    save_map(grid, settings.base_path, settings.mode, settings.occupied_thresh, settings.free_thresh,
             settings.image_format)
    return grid


def saved_summary(grid: OccupancyGrid, settings: SaveSettings) -> str:
    """One line on what was written, e.g. for the command line."""
    x, y, yaw = grid.origin
    return (f"saved {settings.yaml_path} and {settings.image_path.name}: {grid.width} x {grid.height} cells "
            f"of {grid.resolution:g} m, origin ({x:g}, {y:g}, {yaw:g}), {settings.describe()}")


class MapSaver(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__("map_saver", **kwargs)
        self.params = declare_parameters(self, MapSaverParameters)
        on_valid_update(self, lambda: self.params, self._set_params)
        # Requests run one at a time; the maps they wait for arrive in a group of their own,
        # so a multi-threaded executor delivers them while a request waits.
        self._map_group = MutuallyExclusiveCallbackGroup()
        self.create_service(SaveMap, "~/save_map", answering(self, "~/save_map", self._on_save_map),
                            callback_group=MutuallyExclusiveCallbackGroup())
        self.get_logger().info(
            f"ready: {self.get_fully_qualified_name()}/save_map waits up to {self.params.save_map_timeout:g} s "
            f"for a map ({'transient local' if self.params.map_subscribe_transient_local else 'volatile'})")

    def _set_params(self, params: MapSaverParameters) -> None:
        self.params = params

    def _on_save_map(self, request: SaveMap.Request, response: SaveMap.Response) -> SaveMap.Response:
        response.result = self.save_from_topic(request)
        return response

    def save_from_topic(self, request: SaveMap.Request) -> bool:
        """Carry out one request; False (with the reason logged) when nothing was saved."""
        p = self.params
        log = self.get_logger()
        try:
            settings = resolve_save_settings(
                request.map_url, request.image_format, request.map_mode,
                unset_if_zero(request.free_thresh), unset_if_zero(request.occupied_thresh),
                default_path=maps_directory() / f"map_{int(time.time())}",
                free_default=p.free_thresh_default, occupied_default=p.occupied_thresh_default)
        except MapSaverError as exc:
            log.error(f"not saving the map: {exc}")
            return False
        for warning in settings.warnings():
            log.warning(warning)
        topic = request.map_topic or DEFAULT_MAP_TOPIC
        try:
            msg = self._receive(topic, p)
        except InvalidTopicNameException as exc:
            log.error(f"not saving the map: map_topic '{topic}': {str(exc).splitlines()[0].rstrip(':')}")
            return False
        if msg is None:
            log.error(f"no map on '{self.resolve_topic_name(topic)}' within {p.save_map_timeout:g} s: nothing saved")
            return False
        try:
            grid = write_map(msg, settings)
        except (MapFileError, ValueError, OSError) as exc:
            log.error(f"could not save the map to {settings.yaml_path}: {exc}")
            return False
        log.info(saved_summary(grid, settings))
        return True

    def _receive(self, topic: str, p: MapSaverParameters) -> OccupancyGridMsg | None:
        """The first map on ``topic`` within the timeout, or None."""
        received: list[OccupancyGridMsg] = []
        arrived = threading.Event()

        def on_map(msg: OccupancyGridMsg) -> None:
            if not received:
                received.append(msg)
                arrived.set()

        subscription = self.create_subscription(OccupancyGridMsg, topic, on_map,
                                                map_qos(p.map_subscribe_transient_local),
                                                callback_group=self._map_group)
        try:
            arrived.wait(p.save_map_timeout)
        finally:
            self.destroy_subscription(subscription)
        return received[0] if received else None


def _spin(node: MapSaver) -> None:
    executor = MultiThreadedExecutor(num_threads=2)
    try:
        rclpy.spin(node, executor=executor)
    finally:
        executor.shutdown()


def main(args: list[str] | None = None) -> int:
    return run_node(MapSaver, "map_saver", args, spin=_spin, fatal=(ParameterError,))


if __name__ == "__main__":
    sys.exit(main())
