"""A pty standing in for a joystick: bytes written to it are what a reader of its path reads."""
from __future__ import annotations

import os
import pty
import tty
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from pppbot_control.joystick import EventKind, JsEvent


class PtyJoystick:
    """``path`` reads as ``/dev/input/jsN`` would: the methods write js_events to it; :meth:`unplug`
    closes it (a reader then gets EIO, and the path is gone), as pulling the cable does."""

    def __init__(self) -> None:
        self.master, self.slave = pty.openpty()
        tty.setraw(self.slave)  # bytes through as they are: no line discipline
        self.path = Path(os.ttyname(self.slave))
        self.plugged = True

    def send(self, *events: JsEvent) -> None:
        os.write(self.master, b"".join(event.pack() for event in events))

    def init(self, axes: list[int], buttons: list[int]) -> None:
        """What the kernel sends right after opening: every button, then every axis, flagged INIT."""
        self.send(*(JsEvent(0, v, EventKind.BUTTON, i, init=True) for i, v in enumerate(buttons)),
                  *(JsEvent(0, v, EventKind.AXIS, i, init=True) for i, v in enumerate(axes)))

    def button(self, number: int, pressed: bool) -> None:
        self.send(JsEvent(0, int(pressed), EventKind.BUTTON, number))

    def axis(self, number: int, raw: int) -> None:
        self.send(JsEvent(0, raw, EventKind.AXIS, number))

    def unplug(self) -> None:
        if self.plugged:
            os.close(self.master)
            os.close(self.slave)
            self.plugged = False


@pytest.fixture
def pty_joystick() -> Iterator[Callable[[], PtyJoystick]]:
    """``pty_joystick()`` makes a stand-in joystick; all are unplugged after the test."""
    made: list[PtyJoystick] = []

    def make() -> PtyJoystick:
        made.append(PtyJoystick())
        return made[-1]

    yield make
    for joystick in made:
        joystick.unplug()
