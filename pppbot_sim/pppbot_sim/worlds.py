"""Find worlds by name (``maze``) or path, and the models folder they use."""
from __future__ import annotations

from pathlib import Path

from pppbot_common.resources import share_directory
from pppbot_sim.errors import WorldError

PACKAGE = "pppbot_sim"
WORLD_SUFFIXES = (".sdf", ".world", ".xml")


def worlds_directory() -> Path:
    """``share/pppbot_sim/worlds`` when installed, else the checkout's ``worlds/``."""
    return share_directory(PACKAGE, "worlds", Path(__file__).resolve().parents[2] / "worlds")


def known_worlds(directory: Path | None = None) -> list[str]:
    folder = directory or worlds_directory()
    return sorted(p.stem for p in folder.iterdir() if p.suffix in WORLD_SUFFIXES) if folder.is_dir() else []


def find_world(name_or_path: str, directory: Path | None = None) -> Path:
    """The world file for a name in the worlds folder, or a path.

    Raises:
        WorldError: no such world; the message lists the known ones.
    """
    text = name_or_path.strip()
    path = Path(text).expanduser()
    folder = directory or worlds_directory()
    if path.suffix in WORLD_SUFFIXES or "/" in text:
        if path.is_file():
            return path
        if "/" not in text and (folder / text).is_file():
            return folder / text
        known = ", ".join(known_worlds(folder)) or "none"
        raise WorldError(f"world file '{text}' not found (known worlds in {folder}: {known})")
    for suffix in WORLD_SUFFIXES:
        candidate = folder / f"{text}{suffix}"
        if candidate.is_file():
            return candidate
    known = ", ".join(known_worlds(folder)) or "none"
    raise WorldError(f"unknown world '{text}'; known worlds: {known} (or give a path to an .sdf or MJCF file)")


def model_paths(world_file: Path) -> list[Path]:
    """Folders searched for ``model://`` includes: the world's ``models/`` and the shipped one."""
    paths = [world_file.parent / "models", worlds_directory() / "models"]
    return [p for i, p in enumerate(paths) if p.is_dir() and p not in paths[:i]]
