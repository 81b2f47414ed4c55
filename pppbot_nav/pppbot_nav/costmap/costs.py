"""Nav2's cost values and their OccupancyGrid mapping (``nav2_costmap_2d/cost_values.hpp``).

A cell's cost is 0 (free) … 252 (ever closer to an obstacle), 253 (the robot's centre here
puts its footprint on an obstacle: inscribed), 254 (an obstacle: lethal) or 255 (unknown).
Published as nav_msgs/OccupancyGrid, as Nav2's costmap publisher does: 0 → 0, 1…252 →
1 + 97·(c − 1)/251 (integer division, so 1…98), 253 → 99, 254 → 100, 255 → −1.
"""
from __future__ import annotations

import numpy as np

FREE_SPACE = 0
MAX_NON_OBSTACLE = 252
INSCRIBED_INFLATED_OBSTACLE = 253
LETHAL_OBSTACLE = 254
NO_INFORMATION = 255


def _translation_table() -> np.ndarray:
    table = np.empty(256, dtype=np.int8)
    table[FREE_SPACE] = 0
    costs = np.arange(1, MAX_NON_OBSTACLE + 1)
    table[1:MAX_NON_OBSTACLE + 1] = 1 + (97 * (costs - 1)) // 251
    table[INSCRIBED_INFLATED_OBSTACLE] = 99
    table[LETHAL_OBSTACLE] = 100
    table[NO_INFORMATION] = -1
    return table


COST_TO_OCCUPANCY = _translation_table()


def to_occupancy(costs: np.ndarray) -> np.ndarray:
    """OccupancyGrid values (int8) of costs (uint8)."""
    return COST_TO_OCCUPANCY[np.asarray(costs, dtype=np.uint8)]
