"""Where the project's shared files are: ``config/`` and ``maps/``, in a checkout or installed."""
from __future__ import annotations

import os
from pathlib import Path

from pppbot_common.resources import checkout_root, maps_directory

__all__ = ["checkout_root", "config_directory", "log_root", "maps_directory"]

PACKAGE = "pppbot_bringup"


def config_directory() -> Path:
    root = checkout_root()
    if root is not None:
        return root / "config"
    from ament_index_python.packages import get_package_share_directory
    return Path(get_package_share_directory(PACKAGE)) / "config"


def log_root() -> Path:
    """Where runs keep their logs: the checkout's ``log/launch_sim``, else ROS_LOG_DIR or ~/.ros/log."""
    root = checkout_root()
    if root is not None:
        return root / "log" / "launch_sim"
    return Path(os.environ.get("ROS_LOG_DIR", Path.home() / ".ros" / "log"))


def new_run_dir(root: Path, name: str) -> Path:
    """A directory ``root/name`` made for this run alone: a launch started in the same second (on
    another domain) gets ``name-2``, ``name-3``, ..., never the other's directory."""
    root.mkdir(parents=True, exist_ok=True)
    for n in range(1, 1000):
        path = root / (name if n == 1 else f"{name}-{n}")
        try:
            path.mkdir()
        except FileExistsError:
            continue
        return path
    raise FileExistsError(f"{root / name}: a thousand runs in one second")
