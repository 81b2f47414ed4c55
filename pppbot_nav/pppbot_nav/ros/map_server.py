"""``map_server``: serves a Nav2 map file on ``/map`` (nav2_map_server's map_server).

Loads ``yaml_filename`` (a Nav2 map YAML and its image) at startup and publishes it on
``topic_name`` (default ``map``) transient local, reliable, depth 1, so late subscribers
(RViz, AMCL, costmaps, ``map_saver``) get it at once, stamped with the load time in
``frame_id``. Services, as Nav2's:

* ``~/map`` (nav_msgs/srv/GetMap): the current map;
* ``~/load_map`` (nav2_msgs/srv/LoadMap): load another map file and publish it; the
  reply carries the map and a result code (``RESULT_MAP_DOES_NOT_EXIST``,
  ``RESULT_INVALID_MAP_METADATA`` for a bad YAML, ``RESULT_INVALID_MAP_DATA`` for an
  unreadable image); on failure the current map stays.

A relative file name is looked up in the working directory, then in ppp_bot's ``maps/``
(``yaml_filename:=maze`` finds ``maps/maze.yaml``). As Nav2's, it is a lifecycle node
(:class:`~pppbot_lockstep.ros.lifecycle.ManagedNode`) that a lifecycle manager brings up
(``lifecycle_manager_localization``): *configure* loads ``yaml_filename`` — a file that
cannot be loaded fails the transition with one line naming the file and the problem — and
*activate* publishes it; an empty ``yaml_filename`` waits for ``~/load_map``.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from nav2_msgs.srv import LoadMap
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg
from nav_msgs.srv import GetMap

from pppbot_common.maps import MapFileError, load_map_image, read_map_metadata
from pppbot_common.params import ParameterError, param
from pppbot_common.resources import maps_directory
from pppbot_common.ros.maps import grid_message
from pppbot_common.ros.params import declare_parameters, fixed_parameters
from pppbot_common.ros.qos import LATCHED
from pppbot_lockstep.ros.lifecycle import ManagedNode
from pppbot_lockstep.ros.runner import run_node
from pppbot_nav.errors import MapLoadError


@dataclass(frozen=True)
class MapServerParameters:
    yaml_filename: str = param("", "the Nav2 map YAML to serve (relative: the working directory, then maps/); "
                                   "empty: wait for ~/load_map")
    topic_name: str = param("map", "the topic the map is published on (transient local)")
    frame_id: str = param("map", "the frame of the published map")

    def validate(self) -> None:
        for name in ("topic_name", "frame_id"):
            value = getattr(self, name)
            if not value or any(ch.isspace() for ch in value):
                raise ParameterError(name, value, "must be a non-empty name without white space")


def resolve_map_path(name: str) -> Path:
    """The map YAML a name means: as given (``file://`` stripped), else in ``maps/``, with
    ``.yaml`` added when it has no suffix.

    Raises:
        MapLoadError: no such file (RESULT_MAP_DOES_NOT_EXIST), naming the places looked in.
    """
    text = name.removeprefix("file://")
    try:
        given = Path(text).expanduser()
    except RuntimeError:  # ~user of no user
        given = Path(text)
    candidates = [given]
    if not given.suffix:
        candidates.append(given.with_suffix(".yaml"))
    if not given.is_absolute():
        candidates += [maps_directory() / c for c in list(candidates)]
    for candidate in candidates:
        try:
            if candidate.is_file():
                return candidate
        except (OSError, ValueError):  # a name too long, a NUL in it: no such file either
            continue
    raise MapLoadError(f"map file '{name}' not found (looked for {', '.join(str(c) for c in candidates)})",
                       LoadMap.Response.RESULT_MAP_DOES_NOT_EXIST)


def load_map_file(name: str) -> tuple[Path, Any]:
    """The path and grid of a map name (see :func:`resolve_map_path`).

    Raises:
        MapLoadError: missing file, bad YAML (RESULT_INVALID_MAP_METADATA) or unreadable
            image (RESULT_INVALID_MAP_DATA); the message names the file and the problem.
    """
    path = resolve_map_path(name)
    try:
        meta = read_map_metadata(path)
    except MapFileError as exc:
        raise MapLoadError(str(exc), LoadMap.Response.RESULT_INVALID_MAP_METADATA) from exc
    try:
        grid = load_map_image(path, meta)
    except MapFileError as exc:
        raise MapLoadError(str(exc), LoadMap.Response.RESULT_INVALID_MAP_DATA) from exc
    return path, grid


class MapServer(ManagedNode):
    def __init__(self, name: str = "map_server", **kwargs: Any) -> None:
        """``name``: the node's (a filter mask's server has its own, as Nav2's bringup names it)."""
        super().__init__(name, **kwargs)
        self.params = p = declare_parameters(self, MapServerParameters)
        fixed_parameters(self, lambda: self.params)  # Nav2's has no dynamic parameters
        self.map_pub = self.create_publisher(OccupancyGridMsg, p.topic_name, LATCHED)
        self.current: OccupancyGridMsg | None = None
        self.create_service(GetMap, "~/map", self._on_get_map)
        self.create_service(LoadMap, "~/load_map", self._on_load_map)

    def configure(self) -> None:
        if self.params.yaml_filename:
            self.serve(*load_map_file(self.params.yaml_filename))
        else:
            self.get_logger().info(f"no yaml_filename: waiting for {self.get_fully_qualified_name()}/load_map")

    def activate(self) -> None:
        if self.current is not None:
            self.map_pub.publish(self.current)

    def cleanup(self) -> None:
        self.current = None

    def serve(self, path: Path, grid: Any) -> None:
        """Take a loaded map: published at once when active, else on activation."""
        msg = grid_message(grid, self.get_clock().now().to_msg())
        msg.header.frame_id = self.params.frame_id
        self.current = msg
        self.map_pub.publish(msg)
        x, y, yaw = grid.origin
        self.get_logger().info(f"serving {path} on {self.map_pub.topic_name}: {grid.width} x {grid.height} cells "
                               f"of {grid.resolution:g} m, origin ({x:g}, {y:g}, {yaw:g})")

    def _on_get_map(self, request: GetMap.Request, response: GetMap.Response) -> GetMap.Response:
        if self.current is None:
            self.get_logger().warning("~/map: no map loaded yet; replying with an empty map")
        else:
            response.map = self.current
        return response

    def _on_load_map(self, request: LoadMap.Request, response: LoadMap.Response) -> LoadMap.Response:
        try:
            self.serve(*load_map_file(request.map_url))
        except MapLoadError as exc:
            self.get_logger().error(f"load_map: {exc}; still serving the previous map")
            response.result = exc.result
            return response
        assert self.current is not None
        response.map = self.current
        response.result = LoadMap.Response.RESULT_SUCCESS
        return response


def main(args: list[str] | None = None) -> int:
    return run_node(MapServer, "map_server", args, fatal=(ParameterError,))


if __name__ == "__main__":
    sys.exit(main())
