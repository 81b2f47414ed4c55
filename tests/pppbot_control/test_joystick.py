"""The joystick core as ROS's joy node behaves: js_event streams (a recorded one, with its INIT
burst), joy's deadzone scaling and axis sign, when a state is published (coalescing, autorepeat on
an injected clock, sticky buttons), device lookup in a stand-in /dev/input, and the reading loop on
a pty standing in for /dev/input/js0 that is missing, plugged in, pulled and plugged in again;
then joy_node doing the same over DDS."""
from __future__ import annotations

import os
import re
import sys
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from pppbot_common.errors import ParameterError
from pppbot_common.ros.wait import wait_until
from pppbot_control.joystick import (
    EventKind,
    JoySettings,
    JoyState,
    Joystick,
    JoystickError,
    JsEvent,
    JsEventDecoder,
    decode_events,
    scale_axis,
)
from pppbot_control.joystick_device import (
    DeviceSpec,
    JoystickLoop,
    JoystickUnavailable,
    find_device,
    joystick_paths,
    open_device,
)

B, A = EventKind.BUTTON, EventKind.AXIS

#: A gamepad opened at t = 10 s (INIT burst: button 1 held, stick 1 full forward, axis 2 full
#: right), then button 0 pressed, stick 1 half back... as the kernel wrote it on a little-endian
#: machine: time (u32 ms), value (s16), type (u8), number (u8).
RECORDING = bytes.fromhex(
    "10270000 0000 81 00"  # 10000 ms  button 0 = 0        INIT
    "10270000 0100 81 01"  # 10000 ms  button 1 = 1        INIT
    "10270000 0000 82 00"  # 10000 ms  axis 0 = 0          INIT
    "10270000 0180 82 01"  # 10000 ms  axis 1 = -32767     INIT
    "10270000 ff7f 82 02"  # 10000 ms  axis 2 = 32767      INIT
    "2c270000 0100 01 00"  # 10028 ms  button 0 = 1
    "40270000 0040 02 01"  # 10048 ms  axis 1 = 16384
    "41270000 0000 01 00"  # 10049 ms  button 0 = 0
)
EVENTS = [
    JsEvent(10000, 0, B, 0, init=True), JsEvent(10000, 1, B, 1, init=True),
    JsEvent(10000, 0, A, 0, init=True), JsEvent(10000, -32767, A, 1, init=True), JsEvent(10000, 32767, A, 2, init=True),
    JsEvent(10028, 1, B, 0), JsEvent(10048, 16384, A, 1), JsEvent(10049, 0, B, 0),
]
little_endian = pytest.mark.skipif(sys.byteorder != "little", reason="the recording is little-endian")


# ----------------------------------------------------------------------------- js_event streams
@little_endian
def test_a_recorded_stream_decodes_with_its_init_burst():
    assert decode_events(RECORDING) == EVENTS


@little_endian
def test_events_pack_to_the_bytes_the_kernel_writes():
    assert b"".join(event.pack() for event in EVENTS) == RECORDING


@pytest.mark.parametrize("chunk", [1, 3, 5, 8, 13, 64])
def test_reads_that_split_events_decode_the_same(chunk: int):
    stream = b"".join(event.pack() for event in EVENTS)
    decoder = JsEventDecoder()
    events = [e for i in range(0, len(stream), chunk) for e in decoder.feed(stream[i:i + chunk])]
    assert events == EVENTS
    assert decoder.pending_bytes == 0


def test_unknown_event_types_are_skipped_and_counted():
    stream = EVENTS[5].pack() + bytes.fromhex("00000000 0000 04 00") + EVENTS[6].pack()
    decoder = JsEventDecoder()
    assert decoder.feed(stream) == [EVENTS[5], EVENTS[6]]
    assert decoder.unknown == 1


def test_a_stream_cut_inside_an_event_is_refused_naming_the_bytes():
    with pytest.raises(JoystickError, match="a js_event stream of 11 bytes ends 3 bytes into an event"):
        decode_events(EVENTS[0].pack() + b"\0\0\0")


# ----------------------------------------------------------------------------- joy's axis values
@pytest.mark.parametrize(("raw", "deadzone", "expected"), [
    (0, 0.05, 0.0),
    (1638, 0.05, 0.0),  # inside the deadzone (0.05 * 32767 = 1638.35)
    (-1638, 0.05, 0.0),
    (32767, 0.05, -1.0),  # full travel is exactly 1, with the kernel's sign flipped
    (-32767, 0.05, 1.0),
    (-32768, 0.05, 1.0),  # the kernel's -32768 is clipped to -32767
    (16384, 0.05, -0.4737002729),  # (16384 - 1638.35) / (0.95 * 32767)
    (1639, 0.05, -2.088108543e-05),  # just past the edge: continuous, near 0
    (-16384, 0.0, 0.5000152593),  # no deadzone: raw / 32767
    (-24575, 0.5, 0.4999847407),  # (24575 - 16383.5) / 16383.5
    (16384, 0.5, -3.051850948e-05),
])
def test_axis_values_are_joys(raw: int, deadzone: float, expected: float):
    assert scale_axis(raw, deadzone) == pytest.approx(expected, rel=1e-9, abs=1e-12)


def test_a_stick_pushed_forward_or_left_is_positive():
    # The kernel reports forward (y) and left (x) as negative readings; ROS's joy publishes them positive.
    assert scale_axis(-20000, 0.05) > 0 > scale_axis(20000, 0.05)


# ----------------------------------------------------------------------------- when joy publishes
def joystick(**settings: Any) -> Joystick:
    return Joystick(JoySettings(**{"autorepeat_rate_hz": 0.0, "coalesce_interval_s": 0.01, **settings}))


def test_the_init_burst_goes_out_once_when_the_coalesce_interval_has_passed():
    joy = joystick()
    assert [joy.on_event(e, 0.0) for e in EVENTS[:5]] == [None] * 5
    assert joy.wake_at_s() == pytest.approx(0.01)
    assert joy.on_time(0.009) is None
    assert joy.on_time(0.01) == JoyState(axes=(0.0, 1.0, -1.0), buttons=(0, 1))
    assert joy.wake_at_s() is None  # no autorepeat: quiet until the next event


def test_a_button_goes_out_at_once_with_the_axis_changes_pending():
    joy = joystick()
    for e in EVENTS[:5]:
        joy.on_event(e, 0.0)
    joy.on_time(0.01)
    assert joy.on_event(JsEvent(0, -32767, A, 0), 1.0) is None  # coalescing
    assert joy.on_event(EVENTS[5], 1.002) == JoyState(axes=(1.0, 1.0, -1.0), buttons=(1, 1))
    assert joy.on_time(1.02) is None  # the pending change went out with the button


def test_axis_changes_within_the_coalesce_interval_make_one_message():
    joy = joystick()
    assert joy.on_event(JsEvent(0, -32767, A, 0), 1.0) is None
    assert joy.on_event(JsEvent(0, 32767, A, 1), 1.004) is None
    assert joy.on_time(1.008) is None
    assert joy.on_time(1.01) == JoyState(axes=(1.0, -1.0), buttons=())


def test_an_axis_reading_that_changes_nothing_publishes_nothing():
    joy = joystick()
    joy.on_event(JsEvent(0, 100, A, 0), 0.0)  # inside the deadzone: 0, as it was
    assert joy.wake_at_s() is None


def test_without_a_coalesce_interval_an_axis_change_goes_out_at_once():
    joy = joystick(coalesce_interval_s=0.0)
    assert joy.on_event(JsEvent(0, 32767, A, 0), 0.0) == JoyState(axes=(-1.0,), buttons=())


def test_autorepeat_sends_the_last_state_again_at_its_rate_while_nothing_happens():
    joy = joystick(autorepeat_rate_hz=20.0, coalesce_interval_s=0.0)
    assert joy.wake_at_s() is None  # nothing to repeat before a first publication
    first = joy.on_event(JsEvent(0, 1, B, 0), 1.0)
    assert joy.wake_at_s() == pytest.approx(1.05)
    assert joy.on_time(1.049) is None
    assert joy.on_time(1.05) == first
    assert joy.wake_at_s() == pytest.approx(1.10)
    joy.on_event(JsEvent(0, 0, B, 0), 1.07)  # a publication by an event starts the period again
    assert joy.on_time(1.10) is None
    assert joy.on_time(1.12) == JoyState(axes=(), buttons=(0,))


def test_an_autorepeat_rate_of_zero_publishes_only_on_events():
    joy = joystick(autorepeat_rate_hz=0.0)
    joy.on_event(JsEvent(0, 1, B, 0), 1.0)
    assert joy.wake_at_s() is None
    assert joy.on_time(1000.0) is None


def test_sticky_buttons_toggle_on_presses_and_ignore_releases():
    joy = joystick(sticky_buttons=True)
    joy.on_event(JsEvent(0, 1, B, 3, init=True), 0.0)  # held at opening: no toggle
    assert joy.state.buttons == (0, 0, 0, 0)
    assert joy.on_event(JsEvent(0, 1, B, 3), 1.0) == JoyState(axes=(), buttons=(0, 0, 0, 1))
    assert joy.on_event(JsEvent(0, 0, B, 3), 1.1) is None
    assert joy.on_event(JsEvent(0, 1, B, 3), 1.2) == JoyState(axes=(), buttons=(0, 0, 0, 0))


def test_the_state_has_the_sizes_the_device_reports_and_grows_for_more():
    joy = Joystick(JoySettings(), axes=3, buttons=2)
    assert joy.state == JoyState(axes=(0.0, 0.0, 0.0), buttons=(0, 0))
    joy.on_event(JsEvent(0, 1, B, 4), 0.0)
    assert joy.state.buttons == (0, 0, 0, 0, 1)


# ----------------------------------------------------------------------------- finding devices
def fake_input_dir(tmp_path: Path, names: dict[str, str]) -> tuple[Path, Callable[[Path], str | None]]:
    """A directory of stand-in devices and the names their JSIOCGNAME would give."""
    for entry in [*names, "event3", "mouse0", "js_foo"]:
        (tmp_path / entry).touch()
    return tmp_path, lambda path: names.get(path.name)


def test_joystick_entries_are_the_js_devices_in_number_order(tmp_path: Path):
    dev_dir, _ = fake_input_dir(tmp_path, {"js10": "c", "js2": "b", "js0": "a"})
    assert [p.name for p in joystick_paths(dev_dir)] == ["js0", "js2", "js10"]
    assert joystick_paths(tmp_path / "missing") == []


def test_a_device_is_found_by_name_exactly_before_by_part_of_it(tmp_path: Path):
    dev_dir, names = fake_input_dir(tmp_path, {"js0": "Logitech Gamepad F710 (2)", "js1": "Logitech Gamepad F710",
                                               "js2": "Microsoft X-Box 360 pad"})
    assert find_device(DeviceSpec(device_name="Logitech Gamepad F710", dev_dir=dev_dir), names) == dev_dir / "js1"
    assert find_device(DeviceSpec(device_name="X-Box", dev_dir=dev_dir), names) == dev_dir / "js2"


def test_a_name_no_device_has_is_reported_with_the_devices_there(tmp_path: Path):
    dev_dir, names = fake_input_dir(tmp_path, {"js0": "Logitech Gamepad F710"})
    with pytest.raises(JoystickUnavailable, match=r"no joystick in .* is named 'PS4' "
                                                  r"\(joysticks there: 'Logitech Gamepad F710' at js0\)"):
        find_device(DeviceSpec(device_name="PS4", dev_dir=dev_dir), names)


def test_dev_wins_and_device_id_names_the_js_device(tmp_path: Path):
    dev_dir, names = fake_input_dir(tmp_path, {"js0": "pad"})
    assert find_device(DeviceSpec(device_id=3, dev_dir=dev_dir), names) == dev_dir / "js3"
    assert find_device(DeviceSpec(dev="/tmp/pad", device_id=3, device_name="pad", dev_dir=dev_dir)) == Path("/tmp/pad")


def test_a_missing_device_cannot_be_opened_and_the_error_names_it(tmp_path: Path):
    with pytest.raises(JoystickUnavailable, match=f"cannot open {tmp_path}/js0: No such file or directory"):
        open_device(tmp_path / "js0")


def test_a_stand_in_without_the_joystick_ioctls_opens_without_name_or_sizes(pty_joystick):
    device = open_device(pty_joystick().path)
    try:
        assert (device.name, device.axes, device.buttons) == ("", 0, 0)
    finally:
        device.close()


# ----------------------------------------------------------------------------- the reading loop
class Lines:
    """A log that keeps its lines: (level, text)."""

    def __init__(self) -> None:
        self.lines: list[tuple[str, str]] = []

    def info(self, message: str) -> None:
        self.lines.append(("info", message))

    def warning(self, message: str) -> None:
        self.lines.append(("warning", message))

    def warnings(self) -> list[str]:
        return [text for level, text in self.lines if level == "warning"]


@pytest.fixture
def run_loop() -> Iterator[Callable[[JoystickLoop], threading.Thread]]:
    """``run_loop(loop)``: run it in a thread; stopped (and checked to end) after the test."""
    started: list[tuple[JoystickLoop, threading.Thread]] = []

    def start(loop: JoystickLoop) -> threading.Thread:
        thread = threading.Thread(target=loop.run, daemon=True)
        thread.start()
        started.append((loop, thread))
        return thread

    yield start
    for loop, thread in started:
        loop.stop()
        thread.join(5)
        assert not thread.is_alive(), "the joystick loop did not stop"
        loop.close()


def plug(link: Path, joystick: Any) -> None:
    """The device appears at ``link`` (a udev-style symlink to the stand-in)."""
    link.unlink(missing_ok=True)
    link.symlink_to(joystick.path)


def test_the_loop_waits_for_a_missing_device_reads_it_and_waits_again_when_it_goes(tmp_path, pty_joystick, run_loop):
    log, published = Lines(), list[JoyState]()
    loop = JoystickLoop(DeviceSpec(device_id=0, dev_dir=tmp_path), JoySettings(autorepeat_rate_hz=0.0),
                        publish=published.append, log=log, retry_s=0.01)
    thread = run_loop(loop)
    wait_until(lambda: loop.attempts >= 5, 10, "five looks for the missing device")
    assert log.warnings() == [f"waiting for joystick device_id 0 ({tmp_path}/js0): cannot open {tmp_path}/js0: "
                              "No such file or directory; looking again every 0.01 s"]

    pad = pty_joystick()
    plug(tmp_path / "js0", pad)
    wait_until(lambda: loop.sessions == 1, 10, "the device plugged in to be opened")
    pad.init(axes=[0, 0], buttons=[0, 0])
    pad.button(1, True)
    wait_until(lambda: JoyState((0.0, 0.0), (0, 1)) in published, 10, "the button press published")

    pad.unplug()
    (tmp_path / "js0").unlink()
    wait_until(lambda: len(log.warnings()) == 2, 10, "the loss reported")
    attempts = loop.attempts
    wait_until(lambda: loop.attempts >= attempts + 5, 10, "five looks for the lost device")
    assert len(log.warnings()) == 2  # the looks after the loss are not reported again
    assert re.fullmatch(rf"lost joystick device_id 0 \({tmp_path}/js0\) \(.+\); looking for it every 0.01 s",
                        log.warnings()[1])

    pad = pty_joystick()
    plug(tmp_path / "js0", pad)
    wait_until(lambda: loop.sessions == 2, 10, "the device plugged in again to be opened")
    pad.init(axes=[-32767], buttons=[])
    wait_until(lambda: published[-1] == JoyState((1.0,), ()), 10, "the new device's state published")
    assert thread.is_alive() and len(log.warnings()) == 2


def test_the_loop_finds_its_device_by_name(tmp_path, pty_joystick, run_loop):
    pad = pty_joystick()
    plug(tmp_path / "js1", pad)
    published: list[JoyState] = []
    loop = JoystickLoop(DeviceSpec(device_name="Pad", dev_dir=tmp_path), JoySettings(autorepeat_rate_hz=0.0),
                        publish=published.append, log=Lines(), retry_s=0.01,
                        names=lambda path: "Fake Pad" if path.name == "js1" else None)
    run_loop(loop)
    wait_until(lambda: loop.sessions == 1, 10, "the device found by name")
    pad.button(0, True)
    wait_until(lambda: published == [JoyState((), (1,))], 10, "the press published")


def test_the_loop_publishes_the_last_state_again_while_the_stick_is_held(tmp_path, pty_joystick, run_loop):
    pad = pty_joystick()
    published: list[JoyState] = []
    loop = JoystickLoop(DeviceSpec(dev=str(pad.path)), JoySettings(autorepeat_rate_hz=100.0),
                        publish=published.append, log=Lines())
    run_loop(loop)
    wait_until(lambda: loop.sessions == 1, 10, "the device opened")
    pad.axis(1, -32767)
    wait_until(lambda: len(published) >= 5, 10, "the state and four repeats")
    assert set(published) == {JoyState((0.0, 1.0), ())}


# ----------------------------------------------------------------------------- joy_node over DDS
def test_bad_parameters_are_refused_by_name():
    from pppbot_control.ros.joy_node import JoyParameters

    with pytest.raises(ParameterError, match="'deadzone' = 1.0: must be below 1"):
        JoyParameters(deadzone=1.0).validate()
    with pytest.raises(ParameterError, match="'autorepeat_rate' = -1.0"):
        JoyParameters(autorepeat_rate=-1.0).validate()
    with pytest.raises(ParameterError, match="'coalesce_interval_ms' = -1: must be >= 0"):
        JoyParameters(coalesce_interval_ms=-1).validate()


@pytest.mark.ros
def test_joy_node_waits_for_its_device_reports_it_once_and_publishes_once_it_is_there(
        ros_node, spin_in_background, tmp_path, pty_joystick):
    from rcl_interfaces.msg import Log
    from rclpy.parameter import Parameter
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from sensor_msgs.msg import Joy

    from pppbot_control.ros.joy_node import JoyNode

    warnings: list[str] = []

    def on_log(line: Log) -> None:
        if line.name == "joy_node" and line.level == Log.WARN:
            warnings.append(line.msg)

    history = QoSProfile(depth=100, durability=DurabilityPolicy.TRANSIENT_LOCAL)  # lines logged before matching
    ros_node.create_subscription(Log, "/rosout", on_log, history)
    joys: list[Joy] = []
    ros_node.create_subscription(Joy, "joy", joys.append, 10)
    link = tmp_path / "js0"
    node = JoyNode(retry_s=0.05, parameter_overrides=[Parameter("dev", value=str(link)),
                                                      Parameter("autorepeat_rate", value=0.0)])
    spin_in_background(node)
    wait_until(lambda: node.loop.attempts >= 5 and warnings, 10, "five looks for the device", node=ros_node)
    assert warnings == [f"waiting for joystick dev '{link}': cannot open {link}: No such file or directory; "
                        "looking again every 0.05 s"]

    pad = pty_joystick()
    plug(link, pad)
    wait_until(lambda: node.loop.sessions == 1, 10, "the device opened", node=ros_node)
    pad.init(axes=[0, -32767], buttons=[0, 1])
    wait_until(lambda: joys, 10, "a Joy message", node=ros_node)
    assert (list(joys[0].axes), list(joys[0].buttons), joys[0].header.frame_id) == ([0.0, 1.0], [0, 1], "joy")
    assert joys[0].header.stamp.sec > 0

    pad.unplug()
    link.unlink()
    wait_until(lambda: len(warnings) == 2, 10, "the loss reported", node=ros_node)
    attempts = node.loop.attempts
    wait_until(lambda: node.loop.attempts >= attempts + 5, 10, "five looks for the lost device", node=ros_node)
    assert len(warnings) == 2 and warnings[1].startswith(f"lost joystick dev '{link}'")

    pad = pty_joystick()
    plug(link, pad)
    pad.button(0, True)
    wait_until(lambda: joys and list(joys[-1].buttons) == [1], 10, "the replugged device's press", node=ros_node)
    assert ros_node.count_publishers("/joy") == 1 and os.path.exists(pad.path)
