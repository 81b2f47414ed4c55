"""Files a package installs under ``share/<package>/``, found installed or in the source tree."""
from __future__ import annotations

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
