"""SDF 1.7 pose frame semantics in one scope (a world or a model): named frames, each posed
relative to another frame of the scope, resolved into the scope's own frame (``world`` or
``__model__``), as sdformat's frame graph does.

A scope's frames are its links, nested models and includes (their model frames), joints, and
``<frame>`` elements. A ``<pose relative_to="x">`` is relative to frame ``x``; without it,
to the element's default frame: ``__model__`` (or ``world``) for links, models, includes and
frames without ``attached_to``, the ``attached_to`` frame for frames, the child link for
joints. An unknown frame or a cycle is an error naming the file, the line and the frames.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pppbot_sim.errors import WorldError


@dataclass(frozen=True)
class PlacedFrame:
    """A frame as written: its pose relative to ``relative_to``, and where it was written."""

    relative_to: str
    pose: np.ndarray
    file: Path
    line: int | None


class FrameGraph:
    """The named frames of one scope; :meth:`resolve` gives a frame's pose in the scope's frame."""

    def __init__(self, root: str, scope: str) -> None:
        self.root = root
        self.scope = scope  # for messages: "world 'w'", "model 'm'"
        self.frames: dict[str, PlacedFrame] = {}
        self._resolved: dict[str, np.ndarray] = {root: np.eye(4)}

    def add(self, name: str, relative_to: str, pose: np.ndarray, file: Path, line: int | None) -> None:
        """Raises WorldError: the name is taken in this scope, or reserved."""
        if name in self.frames or name == self.root:
            raise WorldError(f"{file}:{line}: the frame name '{name}' is used twice in {self.scope} (names of "
                             "links, models, joints and frames must differ)")
        if name.startswith("__") and name.endswith("__"):
            raise WorldError(f"{file}:{line}: the frame name '{name}' is reserved in SDF (names like __model__)")
        self.frames[name] = PlacedFrame(relative_to, pose, file, line)

    def resolve(self, name: str, where: str = "") -> np.ndarray:
        """``name``'s pose in the scope's frame (4×4); ``where`` (``file:line: ``) names who asked.

        Raises:
            WorldError: an unknown frame on the way, or a cycle; named with file and line.
        """
        if name in self._resolved:
            return self._resolved[name]
        chain: list[str] = []
        current = name
        while current not in self._resolved:
            if current in chain:
                cycle = " → ".join([*chain[chain.index(current):], current])
                first = self.frames[chain[chain.index(current)]]
                raise WorldError(f"{first.file}:{first.line}: the poses of {self.scope} form a cycle: {cycle}")
            placed = self.frames.get(current)
            if placed is None:
                asker = self.frames.get(chain[-1]) if chain else None
                where = f"{asker.file}:{asker.line}: " if asker is not None else where
                known = ", ".join(sorted([self.root, *self.frames]))
                raise WorldError(f"{where}there is no frame '{current}' in {self.scope} (frames: {known})")
            chain.append(current)
            current = placed.relative_to
        pose = self._resolved[current]
        for frame in reversed(chain):
            pose = pose @ self.frames[frame].pose
            self._resolved[frame] = pose
        return self._resolved[name]
