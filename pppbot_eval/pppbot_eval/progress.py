"""Progress of a scenario: a bar redrawn in place on a terminal, plain lines otherwise."""
from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import IO

BAR_WIDTH = 30
REDRAW_S = 0.2
PLAIN_STEP = 0.1  # without a terminal: a line every 10 %


class Progress:
    def __init__(self, stream: IO[str], label: str, terminal: bool | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.stream = stream
        self.label = label
        self.terminal = stream.isatty() if terminal is None else terminal
        self.clock = clock
        self._drawn_at = -float("inf")
        self._next_plain = 0.0
        self._open_line = False
        self._lock = threading.RLock()  # other threads' lines (the supervisor's) go through :meth:`lines`

    def update(self, fraction: float, detail: str | Callable[[], str] = "") -> None:
        """Show ``fraction`` (0–1) done; throttled, so it can be called on every message
        (``detail`` may be a callable, formatted only when something is drawn)."""
        fraction = min(max(fraction, 0.0), 1.0)
        if self.terminal:
            now = self.clock()
            if now - self._drawn_at < REDRAW_S and fraction < 1.0:
                return
            self._drawn_at = now
            filled = int(round(fraction * BAR_WIDTH))
            bar = "#" * filled + "." * (BAR_WIDTH - filled)
            self._write(f"\r{self.label} [{bar}] {fraction * 100:5.1f}% {_text(detail)}\033[K")
            self._open_line = True
        elif fraction >= self._next_plain:
            self._write(f"{self.label}: {fraction * 100:.0f}% {_text(detail)}\n")
            self._next_plain = (int(fraction / PLAIN_STEP + 1e-9) + 1) * PLAIN_STEP

    def message(self, text: str) -> None:
        """A line of its own (the bar is redrawn below it on the next update)."""
        self.finish()
        self._write(text + "\n")

    def finish(self) -> None:
        if self._open_line:
            self._write("\n")
            self._open_line = False
            self._drawn_at = -float("inf")

    def lines(self) -> _LinesAbove:
        """A text stream for other output: each write ends the bar's line first, so lines never mix."""
        return _LinesAbove(self)

    def _write(self, text: str) -> None:
        with self._lock:
            try:
                self.stream.write(text)
                self.stream.flush()
            except (OSError, ValueError):
                pass


class _LinesAbove:
    def __init__(self, progress: Progress) -> None:
        self.progress = progress

    def write(self, text: str) -> int:
        with self.progress._lock:
            self.progress.finish()
            self.progress._write(text)
        return len(text)

    def flush(self) -> None:
        pass


def _text(detail: str | Callable[[], str]) -> str:
    return detail() if callable(detail) else detail
