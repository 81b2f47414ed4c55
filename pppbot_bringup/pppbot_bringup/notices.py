"""Notes said once: what an optional tool's absence means is worth reading the first time, not at
every start. Each note's key is remembered in a folder of the checkout's ``build/`` (installed:
``$ROS_HOME/pppbot``), never in the user's home beyond ROS's own."""
from __future__ import annotations

import os
import re
from pathlib import Path

from pppbot_bringup.paths import checkout_root

_KEY = re.compile(r"^[a-z0-9_]+$")


def notices_directory() -> Path:
    """Where the keys of notes already said are kept."""
    root = checkout_root()
    if root is not None:
        return root / "build" / "notices"
    return Path(os.environ.get("ROS_HOME", Path.home() / ".ros")) / "pppbot" / "notices"


def first_time(key: str, directory: Path | None = None) -> bool:
    """True the first time ``key`` is asked about (and remembered from then on); False after.
    A folder that can't be written makes every time the first: the note is said again.

    Raises:
        ValueError: ``key`` is not lower-case letters, digits and underscores.
    """
    if not _KEY.match(key):
        raise ValueError(f"a note's key is lower-case letters, digits and _, got {key!r}")
    marker = (directory or notices_directory()) / key
    if marker.exists():
        return False
    try:
        marker.parent.mkdir(parents=True, exist_ok=True)
        marker.touch()
    except OSError:
        pass
    return True
