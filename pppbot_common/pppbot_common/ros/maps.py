"""OccupancyGrid (core) ↔ nav_msgs/OccupancyGrid, for the map publishers (slam, map_server) and readers."""
from __future__ import annotations

import array

import numpy as np
from builtin_interfaces.msg import Time
from nav_msgs.msg import MapMetaData
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg

from pppbot_common.maps import OccupancyGrid
from pppbot_common.se2 import quaternion_from_yaw, yaw_from_quaternion


def map_metadata(grid: OccupancyGrid, stamp: Time) -> MapMetaData:
    meta = MapMetaData(map_load_time=stamp, resolution=float(grid.resolution), width=grid.width, height=grid.height)
    meta.origin.position.x, meta.origin.position.y = float(grid.origin[0]), float(grid.origin[1])
    qx, qy, qz, qw = quaternion_from_yaw(float(grid.origin[2]))
    o = meta.origin.orientation
    o.x, o.y, o.z, o.w = qx, qy, qz, qw
    return meta


def grid_message(grid: OccupancyGrid, stamp: Time) -> OccupancyGridMsg:
    """The message of ``grid`` (row-major from the lowest row, as both store it)."""
    msg = OccupancyGridMsg(info=map_metadata(grid, stamp))
    msg.header.stamp = stamp
    msg.header.frame_id = grid.frame_id
    msg.data = array.array("b", grid.data.astype("int8").tobytes())
    return msg


def grid_from_message(msg: OccupancyGridMsg) -> OccupancyGrid:
    """The core grid of a message (origin yaw from its quaternion).

    The resolution is a float32 in the message; it becomes the shortest decimal
    with that float32 value (0.05, not 0.05000000074505806), as written in map files.

    Raises:
        ValueError: the data length is not width × height, or a bad resolution.
    """
    info = msg.info
    if len(msg.data) != info.width * info.height:
        raise ValueError(f"map data has {len(msg.data)} cells, not width × height = {info.width * info.height}")
    o = info.origin.orientation
    data = np.array(msg.data, dtype=np.int8).reshape(info.height, info.width)
    return OccupancyGrid(data, float(str(np.float32(info.resolution))),
                         (info.origin.position.x, info.origin.position.y, yaw_from_quaternion(o.x, o.y, o.z, o.w)),
                         msg.header.frame_id)
