"""Linux joysticks through the kernel's js interface, with the publishing rules of ROS's ``joy`` node.

The kernel's joystick driver (``Documentation/input/joydev``) gives each joystick a character
device ``/dev/input/jsN``; a read returns 8-byte ``struct js_event`` records (``__u32 time`` in ms,
``__s16 value``, ``__u8 type``, ``__u8 number``; host byte order). ``type`` is
:data:`JS_EVENT_BUTTON` or :data:`JS_EVENT_AXIS`, or'ed with :data:`JS_EVENT_INIT` for the
burst of events that reports every button and axis right after the device is opened.

Pieces, each usable alone:

* :class:`JsEventDecoder` turns bytes (a device read, a recorded stream) into :class:`JsEvent`.
* :func:`scale_axis` is ``joy``'s axis value: a raw ``-32768..32767`` reading inside the deadzone
  is 0, the rest is rescaled to ``[-1, 1]``, and the sign is flipped (the kernel reports a stick
  pushed forward or left as negative; ROS wants it positive).
* :class:`Joystick` keeps a device's state and says when to publish it: a button at once, axis
  changes coalesced for ``coalesce_interval_s``, the last state again at ``autorepeat_rate_hz``
  while nothing happens, ``sticky_buttons`` toggling on presses. It takes the time as an
  argument and reads no clock.

Finding, opening and reading devices is :mod:`pppbot_control.joystick_device`. No rclpy here:
the ``joy_node`` adapter (:mod:`pppbot_control.ros.joy_node`) publishes what these hand it.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass
from enum import Enum

from pppbot_common.errors import PppbotError

JS_EVENT_BUTTON = 0x01
JS_EVENT_AXIS = 0x02
JS_EVENT_INIT = 0x80
#: ``struct js_event``: time (ms), value, type, number; native byte order, standard sizes.
JS_EVENT = struct.Struct("=IhBB")
#: The largest magnitude of a raw axis reading (the kernel's range is -32767..32767; -32768 is clipped).
AXIS_MAX = 32767


class JoystickError(PppbotError):
    """A joystick stream or device problem; the message names the device or the bytes."""


class JoystickUnavailable(JoystickError, OSError):
    """No joystick where one was looked for (missing, unreadable, or none of that name)."""


class EventKind(Enum):
    BUTTON = JS_EVENT_BUTTON
    AXIS = JS_EVENT_AXIS


@dataclass(frozen=True)
class JsEvent:
    """One ``struct js_event``: ``value`` is 0/1 for a button, ``-32768..32767`` for an axis;
    ``init`` marks the events of the burst that reports the state right after opening."""

    time_ms: int
    value: int
    kind: EventKind
    number: int
    init: bool = False

    def pack(self) -> bytes:
        """The event's 8 bytes, as the kernel writes them."""
        return JS_EVENT.pack(self.time_ms, self.value, self.kind.value | (JS_EVENT_INIT if self.init else 0),
                             self.number)


class JsEventDecoder:
    """Bytes → events, across reads that may split an event; unknown event types are counted
    (``unknown``) and skipped, as ``joy_linux`` skips them."""

    def __init__(self) -> None:
        self._partial = b""
        self.unknown = 0

    @property
    def pending_bytes(self) -> int:
        """Bytes of an event not complete yet."""
        return len(self._partial)

    def feed(self, data: bytes) -> list[JsEvent]:
        buffer = self._partial + data
        whole = len(buffer) - len(buffer) % JS_EVENT.size
        self._partial = buffer[whole:]
        events = []
        for time_ms, value, type_, number in JS_EVENT.iter_unpack(buffer[:whole]):
            try:
                kind = EventKind(type_ & ~JS_EVENT_INIT)
            except ValueError:
                self.unknown += 1
                continue
            events.append(JsEvent(time_ms, value, kind, number, bool(type_ & JS_EVENT_INIT)))
        return events


def decode_events(data: bytes) -> list[JsEvent]:
    """The events of a whole recorded stream.

    Raises:
        JoystickError: the stream ends inside an event.
    """
    decoder = JsEventDecoder()
    events = decoder.feed(data)
    if decoder.pending_bytes:
        raise JoystickError(f"a js_event stream of {len(data)} bytes ends {decoder.pending_bytes} bytes into "
                            f"an event (events are {JS_EVENT.size} bytes)")
    return events


def scale_axis(raw: int, deadzone: float) -> float:
    """``joy``'s value of a raw axis reading, in ``[-1, 1]``, positive for a stick pushed forward or left.

    ``|raw| <= deadzone * 32767`` gives 0; beyond, the distance past the deadzone is scaled so that
    full travel is exactly 1 (the output is continuous at the deadzone's edge). ``deadzone`` is in
    ``[0, 1)``.
    """
    edge = AXIS_MAX * deadzone
    value = float(max(raw, -AXIS_MAX))
    if value > edge:
        value -= edge
    elif value < -edge:
        value += edge
    else:
        return 0.0
    return -value / (AXIS_MAX - edge)  # full travel: exactly 1


@dataclass(frozen=True)
class JoySettings:
    """``joy``'s parameters: ``deadzone`` in ``[0, 1)`` of full travel; ``autorepeat_rate_hz``
    (0 = publish only on events); ``coalesce_interval_s`` (axis changes within it go out in one
    message); ``sticky_buttons`` (a press toggles the button, a release does nothing)."""

    deadzone: float = 0.05
    autorepeat_rate_hz: float = 20.0
    coalesce_interval_s: float = 0.001
    sticky_buttons: bool = False


@dataclass(frozen=True)
class JoyState:
    """What a sensor_msgs/Joy carries: axes in ``[-1, 1]``, buttons 0/1."""

    axes: tuple[float, ...]
    buttons: tuple[int, ...]


class Joystick:
    """One opened joystick's state and when to publish it.

    A button event publishes at once; axis changes (and the initial burst) publish
    ``coalesce_interval_s`` after the first of them; with ``autorepeat_rate_hz`` the last state is
    published again once a period has passed since the last publication (only after a first one).
    Each method that can publish returns the state to publish, or None.
    """

    def __init__(self, settings: JoySettings, *, axes: int = 0, buttons: int = 0) -> None:
        self.settings = settings
        self._axes = [0.0] * axes
        self._buttons = [0] * buttons
        self._due_s: float | None = None  # when the coalesced changes go out
        self._last_publish_s: float | None = None

    @property
    def state(self) -> JoyState:
        return JoyState(tuple(self._axes), tuple(self._buttons))

    def on_event(self, event: JsEvent, now_s: float) -> JoyState | None:
        """Apply ``event``, read at ``now_s``; the state to publish now, if any."""
        if event.kind is EventKind.AXIS:
            _grow(self._axes, event.number, 0.0)
            value = scale_axis(event.value, self.settings.deadzone)
            if value == self._axes[event.number] and not event.init:
                return None
            self._axes[event.number] = value
            return self._soon(now_s)
        _grow(self._buttons, event.number, 0)
        pressed = 1 if event.value else 0
        if event.init:
            self._buttons[event.number] = 0 if self.settings.sticky_buttons else pressed
            return self._soon(now_s)
        if self.settings.sticky_buttons:
            if not pressed:
                return None
            self._buttons[event.number] ^= 1
        else:
            self._buttons[event.number] = pressed
        return self._publish(now_s)

    def on_time(self, now_s: float) -> JoyState | None:
        """The state due at ``now_s`` (coalesced changes, or an autorepeat), if any."""
        if self._due_s is not None and now_s >= self._due_s:
            return self._publish(now_s)
        repeat_s = self._repeat_at_s()
        if repeat_s is not None and now_s >= repeat_s:
            return self._publish(now_s)
        return None

    def wake_at_s(self) -> float | None:
        """When :meth:`on_time` will next have something to publish (None: only after an event)."""
        times = [t for t in (self._due_s, self._repeat_at_s()) if t is not None]
        return min(times) if times else None

    def _repeat_at_s(self) -> float | None:
        if self.settings.autorepeat_rate_hz <= 0 or self._last_publish_s is None:
            return None
        return self._last_publish_s + 1.0 / self.settings.autorepeat_rate_hz

    def _soon(self, now_s: float) -> JoyState | None:
        if self._due_s is None:
            self._due_s = now_s + self.settings.coalesce_interval_s
        return self.on_time(now_s)

    def _publish(self, now_s: float) -> JoyState:
        self._due_s = None
        self._last_publish_s = now_s
        return self.state


def _grow(values: list, index: int, fill: object) -> None:
    """Make ``values[index]`` exist (a device may report more than its ioctls said, as joy_linux allows)."""
    if index >= len(values):
        values.extend([fill] * (index + 1 - len(values)))
