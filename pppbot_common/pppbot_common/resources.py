"""Files a package installs under ``share/<package>/``, found installed or in the source tree."""
from __future__ import annotations

import os
from pathlib import Path


def share_directory(package: str, subfolder: str, source_fallback: Path) -> Path:
    """``share/<package>/<subfolder>`` when the package is installed (ament index), else
    ``source_fallback`` (running from a checkout without an install)."""
    try:
        from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
    except ImportError:
        return source_fallback
    try:
        installed = Path(get_package_share_directory(package)) / subfolder
    except PackageNotFoundError:
        return source_fallback
    return installed if installed.is_dir() else source_fallback


def checkout_root() -> Path | None:
    """The checkout, when running from one (``./pppbot`` sets PPPBOT_ROOT)."""
    root = os.environ.get("PPPBOT_ROOT")
    if root and Path(root, "config").is_dir():
        return Path(root)
    guess = Path(__file__).resolve().parents[2]
    return guess if (guess / "config").is_dir() and (guess / "pppbot").is_file() else None


def maps_directory() -> Path:
    """The checkout's ``maps/``, else ``maps/`` in the working directory."""
    root = checkout_root()
    return (root / "maps") if root is not None else Path.cwd() / "maps"
