"""Where the project's shared files are: ``config/`` and ``maps/``, in a checkout or installed."""
from __future__ import annotations

import os
from pathlib import Path

PACKAGE = "pppbot_bringup"


def checkout_root() -> Path | None:
    """The checkout, when running from one (``./pppbot`` sets PPPBOT_ROOT)."""
    root = os.environ.get("PPPBOT_ROOT")
    if root and Path(root, "config").is_dir():
        return Path(root)
    guess = Path(__file__).resolve().parents[2]
    return guess if (guess / "config").is_dir() and (guess / "pppbot").is_file() else None


def config_directory() -> Path:
    root = checkout_root()
    if root is not None:
        return root / "config"
    from ament_index_python.packages import get_package_share_directory
    return Path(get_package_share_directory(PACKAGE)) / "config"


def maps_directory() -> Path:
    root = checkout_root()
    return (root / "maps") if root is not None else Path.cwd() / "maps"


def log_root() -> Path:
    """Where runs keep their logs: the checkout's ``log/launch_sim``, else ROS_LOG_DIR or ~/.ros/log."""
    root = checkout_root()
    if root is not None:
        return root / "log" / "launch_sim"
    return Path(os.environ.get("ROS_LOG_DIR", Path.home() / ".ros" / "log"))
