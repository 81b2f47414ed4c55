"""Finding, opening and reading Linux joysticks (``/dev/input/jsN``), as ROS's ``joy`` node does.

* :func:`find_device` and :func:`open_device` find a joystick by path (``dev``, joy_linux's
  parameter), by ``device_id`` (``N`` of ``jsN``) or by ``device_name`` (the name the JSIOCGNAME
  ioctl gives), in a directory tests may replace.
* :class:`JoystickLoop` is the loop a node runs in a thread: open, read, decode
  (:mod:`pppbot_control.joystick`) and publish; a missing or unplugged device is reported once
  and looked for again every ``retry_s``, so one plugged in later is picked up.

No rclpy here: the loop publishes through the callable it is given.
"""
from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import re
import select
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

from pppbot_control.joystick import JS_EVENT, JoySettings, JoyState, Joystick, JoystickUnavailable, JsEventDecoder

#: Where the kernel puts joystick devices.
DEV_DIR = Path("/dev/input")
#: How many events one read takes at most.
READ_EVENTS = 64


def _ioc_read(number: int, size: int) -> int:
    """``_IOR('j', number, size)`` of ``linux/joystick.h``."""
    return (2 << 30) | (size << 16) | (ord("j") << 8) | number


JSIOCGAXES = _ioc_read(0x11, 1)
JSIOCGBUTTONS = _ioc_read(0x12, 1)
NAME_LENGTH = 128
JSIOCGNAME = _ioc_read(0x13, NAME_LENGTH)


@dataclass(frozen=True)
class DeviceSpec:
    """Which joystick: ``dev`` (a path, joy_linux's parameter) wins; else ``device_name`` (the first
    joystick of ``dev_dir`` with exactly that name, else the first whose name contains it); else
    ``dev_dir/js<device_id>``."""

    dev: str = ""
    device_id: int = 0
    device_name: str = ""
    dev_dir: Path = DEV_DIR

    def describe(self) -> str:
        """Which joystick, for log lines: ``joystick device_id 0 (/dev/input/js0)``."""
        if self.dev:
            return f"joystick dev '{self.dev}'"
        if self.device_name:
            return f"joystick device_name '{self.device_name}'"
        return f"joystick device_id {self.device_id} ({self.dev_dir / f'js{self.device_id}'})"


@dataclass
class OpenDevice:
    """An opened joystick: its (non-blocking) file descriptor, name and sizes (empty name and 0
    when the ioctls do not answer: a stand-in such as a pty)."""

    path: Path
    fd: int
    name: str
    axes: int
    buttons: int

    def close(self) -> None:
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1


def joystick_paths(dev_dir: Path) -> list[Path]:
    """The ``js<N>`` entries of ``dev_dir``, by ``N`` (none when the directory is missing)."""
    try:
        entries = list(dev_dir.iterdir())
    except OSError:
        return []
    numbered = [(int(m.group(1)), p) for p in entries if (m := re.fullmatch(r"js(\d+)", p.name))]
    return [p for _, p in sorted(numbered)]


def _ioctl_name(fd: int) -> str | None:
    try:
        raw = fcntl.ioctl(fd, JSIOCGNAME, bytes(NAME_LENGTH))
    except OSError:
        return None
    return raw.split(b"\0", 1)[0].decode(errors="replace")


def _ioctl_count(fd: int, request: int) -> int:
    try:
        return fcntl.ioctl(fd, request, b"\0")[0]
    except OSError:
        return 0


def read_name(path: Path) -> str | None:
    """The JSIOCGNAME name of the joystick at ``path`` (None: it cannot be opened or is no joystick)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY)
    except OSError:
        return None
    try:
        return _ioctl_name(fd)
    finally:
        os.close(fd)


def find_device(spec: DeviceSpec, names: Callable[[Path], str | None] = read_name) -> Path:
    """The path of the joystick ``spec`` asks for; ``names`` reads a device's name.

    Raises:
        JoystickUnavailable: ``device_name`` is set and no joystick has that name; the message
            lists the joysticks found.
    """
    if spec.dev:
        return Path(spec.dev)
    if not spec.device_name:
        return spec.dev_dir / f"js{spec.device_id}"
    found = [(path, names(path)) for path in joystick_paths(spec.dev_dir)]
    for matches in (lambda n: n == spec.device_name, lambda n: spec.device_name in n):
        for path, name in found:
            if name is not None and matches(name):
                return path
    listed = ", ".join(f"'{name}' at {path.name}" for path, name in found if name is not None) or "none"
    raise JoystickUnavailable(f"no joystick in {spec.dev_dir} is named '{spec.device_name}' "
                              f"(joysticks there: {listed})")


def open_device(path: Path) -> OpenDevice:
    """Open the joystick at ``path`` for non-blocking reads.

    ``O_NOCTTY``: a terminal standing in for a joystick (a pty in tests) must not become the
    process's controlling terminal, whose hangup would end the process.

    Raises:
        JoystickUnavailable: it cannot be opened; the message names the path and the reason.
    """
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY)
    except OSError as exc:
        hint = " (is this user in the 'input' group?)" if exc.errno == errno.EACCES else ""
        raise JoystickUnavailable(f"cannot open {path}: {exc.strerror}{hint}") from exc
    return OpenDevice(path, fd, _ioctl_name(fd) or "", _ioctl_count(fd, JSIOCGAXES), _ioctl_count(fd, JSIOCGBUTTONS))


class Log(Protocol):
    """Where the loop's lines go (an rclpy logger fits)."""

    def info(self, message: str, /) -> object: ...

    def warning(self, message: str, /) -> object: ...


class StopSignal:
    """A stop request that also wakes a ``select()`` (through a pipe)."""

    def __init__(self) -> None:
        self._event = threading.Event()
        self._read_fd, self._write_fd = os.pipe()

    def set(self) -> None:
        if not self._event.is_set():
            self._event.set()
            os.write(self._write_fd, b"\0")

    def is_set(self) -> bool:
        return self._event.is_set()

    def fileno(self) -> int:
        return self._read_fd

    def wait(self, timeout_s: float) -> bool:
        """Wait up to ``timeout_s`` for the stop; whether it came."""
        return self._event.wait(timeout_s)

    def close(self) -> None:
        for fd in (self._read_fd, self._write_fd):
            with contextlib.suppress(OSError):
                os.close(fd)


class JoystickLoop:
    """Find, open and read a joystick, publishing through ``publish``, until :meth:`stop`.

    A device that is not there is reported once (naming what was looked for) and looked for
    again every ``retry_s``; a device that goes away is reported once and looked for the same
    way. A reason that changes (missing, then unreadable) is reported again. ``attempts`` counts
    the tries to open, ``sessions`` the devices opened.
    """

    def __init__(self, spec: DeviceSpec, settings: JoySettings, *, publish: Callable[[JoyState], None],
                 log: Log, clock: Callable[[], float] = time.monotonic, retry_s: float = 1.0,
                 names: Callable[[Path], str | None] = read_name) -> None:
        self.spec, self.settings = spec, settings
        self.publish, self.log, self.clock, self.retry_s, self.names = publish, log, clock, retry_s, names
        self.stop_signal = StopSignal()
        self.attempts = 0
        self.sessions = 0

    def stop(self) -> None:
        self.stop_signal.set()

    def close(self) -> None:
        self.stop_signal.close()

    def run(self) -> None:
        """Until stopped; never raises (an unexpected error ends the session and is reported)."""
        reported: str | None = None
        lost = False  # right after a loss, the device's absence is what the loss's line said
        while not self.stop_signal.is_set():
            self.attempts += 1
            try:
                device = open_device(find_device(self.spec, self.names))
            except JoystickUnavailable as exc:
                if str(exc) != reported and not lost:
                    self.log.warning(f"waiting for {self.spec.describe()}: {exc}; "
                                     f"looking again every {self.retry_s:g} s")
                reported, lost = str(exc), False
                self.stop_signal.wait(self.retry_s)
                continue
            self.sessions += 1
            name = f"'{device.name}'" if device.name else "(no name)"
            self.log.info(f"opened joystick {name} at {device.path}: {device.axes} axes, {device.buttons} buttons, "
                          f"deadzone {self.settings.deadzone:g}")
            try:
                reason = self.read(device)
            except Exception as exc:  # the loop must go on: report, and look for the device again
                reason = f"{type(exc).__name__}: {exc}"
            finally:
                device.close()
            if reason is None:
                return
            which = self.spec.describe()
            where = "" if str(device.path) in which else f" at {device.path}"
            self.log.warning(f"lost {which}{where} ({reason}); looking for it every {self.retry_s:g} s")
            reported, lost = None, True

    def read(self, device: OpenDevice) -> str | None:
        """Read and publish until the device goes away (the reason) or a stop (None)."""
        joystick = Joystick(self.settings, axes=device.axes, buttons=device.buttons)
        decoder = JsEventDecoder()
        while True:
            wake_s = joystick.wake_at_s()
            timeout_s = None if wake_s is None else max(0.0, wake_s - self.clock())
            ready, _, _ = select.select([device.fd, self.stop_signal.fileno()], [], [], timeout_s)
            if self.stop_signal.is_set():
                return None
            if device.fd in ready:
                try:
                    data = os.read(device.fd, JS_EVENT.size * READ_EVENTS)
                except BlockingIOError:
                    data = None
                except OSError as exc:
                    return exc.strerror or str(exc)
                if data == b"":
                    return "end of file"
                now_s = self.clock()
                for event in decoder.feed(data or b""):
                    state = joystick.on_event(event, now_s)
                    if state is not None:
                        self.publish(state)
            state = joystick.on_time(self.clock())
            if state is not None:
                self.publish(state)
