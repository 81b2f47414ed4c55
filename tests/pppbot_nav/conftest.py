"""A small known map, published from the test's node, and an independent reader of saved map files;
this folder's synthetic AMCL world (``amcl_synthetic``) on the import path."""
from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from PIL import Image

from pppbot_common.maps import OccupancyGrid
from pppbot_common.ros.maps import grid_message
from pppbot_common.ros.qos import LATCHED

sys.path.insert(0, str(Path(__file__).resolve().parent))

RESOLUTION = 0.1
ORIGIN = (-1.5, 2.0, 0.0)

#: (row, col) → cell value; row 0 is the map's bottom row. Every other cell is free (0).
CELLS = {(1, 1): 30, (1, 2): 20, (2, 3): 50, (3, 3): 70, (3, 4): 101, (4, 6): -1}


def known_grid() -> OccupancyGrid:
    """5 rows × 7 columns: the bottom row occupied, the cells of ``CELLS``, the rest free."""
    data = np.zeros((5, 7), dtype=np.int8)
    data[0, :] = 100
    for (row, col), value in CELLS.items():
        data[row, col] = value
    return OccupancyGrid(data, RESOLUTION, ORIGIN)


class Published:
    """A map publisher of the test's node and the message it sent."""

    def __init__(self, publisher: Any, message: Any) -> None:
        self.publisher, self.message = publisher, message

    def again(self) -> None:
        self.publisher.publish(self.message)


@pytest.fixture
def publish_map(ros_node: Any) -> Callable[..., Published]:
    """``publish_map(topic="/map", qos=LATCHED, grid=known_grid())``: publish the map once."""
    def publish(topic: str = "/map", qos: Any = LATCHED, grid: OccupancyGrid | None = None) -> Published:
        from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg

        publisher = ros_node.create_publisher(OccupancyGridMsg, topic, qos)
        published = Published(publisher, grid_message(grid or known_grid(), ros_node.get_clock().now().to_msg()))
        published.again()
        return published
    return publish


class SavedMap:
    """A saved map read with PIL and PyYAML only (not pppbot's loader)."""

    def __init__(self, yaml_path: Path) -> None:
        self.meta = yaml.safe_load(yaml_path.read_text())
        with Image.open(yaml_path.parent / self.meta["image"]) as image:
            self.image_mode = image.mode
            self.image_format = image.format
            self.pixels = np.asarray(image)

    def at(self, row: int, col: int) -> Any:
        """The pixel of map cell (row, col): image rows run top down."""
        return self.pixels[self.pixels.shape[0] - 1 - row, col]

    def grey(self, row: int, col: int) -> int:
        value = self.at(row, col)
        return int(value[0] if np.ndim(value) else value)

    def alpha(self, row: int, col: int) -> int:
        return int(self.at(row, col)[-1])


@pytest.fixture
def read_saved() -> Callable[[Path], SavedMap]:
    return SavedMap
