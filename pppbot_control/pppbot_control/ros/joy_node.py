"""``joy_node``: ROS's ``joy`` driver for pppbot, reading the kernel's js interface.

Publishes sensor_msgs/Joy on ``joy`` (frame ``joy``, stamped with the node's clock) with the
parameters of ros-drivers/joy: ``device_id``, ``device_name``, ``deadzone``, ``autorepeat_rate``,
``coalesce_interval_ms``, ``sticky_buttons``; and joy_linux's ``dev`` (a device path; it wins over
the other two). A missing device is reported once and looked for every second, so a joystick
plugged in later is picked up; one unplugged is reported once and waited for the same way. The
node never ends because of its device.

The device is read in a thread of its own (as joy does it: events go out as they come, not at a
timer's next tick); the thread only publishes, and stops before the node is destroyed. The node
takes no part in lockstep: a joystick runs on wall time.
"""
from __future__ import annotations

import sys
import threading
from dataclasses import dataclass

from sensor_msgs.msg import Joy

from pppbot_common.params import ParameterError, check_finite_range, param
from pppbot_common.ros.params import declare_parameters
from pppbot_control.joystick import JoySettings, JoyState
from pppbot_control.joystick_device import DeviceSpec, JoystickLoop
from pppbot_lockstep.ros.node import StepNode
from pppbot_lockstep.ros.runner import run_nodes

#: Wall seconds between looks for a missing device.
RETRY_S = 1.0
#: How long destroying the node waits for the reading thread.
JOIN_TIMEOUT_S = 5.0
#: header.frame_id of the published messages, as joy's.
FRAME_ID = "joy"


@dataclass(frozen=True)
class JoyParameters:
    device_id: int = param(0, "read /dev/input/js<device_id> (when dev and device_name are empty)")
    device_name: str = param("", "read the joystick of this name (exact, else the first containing it); "
                                 "wins over device_id")
    dev: str = param("", "device path (joy_linux's dev); wins over device_id and device_name")
    deadzone: float = param(0.05, "axis readings within this fraction of full travel are 0, in [0, 1)")
    autorepeat_rate: float = param(20.0, "publish the last state again at this rate (Hz) while nothing "
                                         "happens; 0 = only on events")
    coalesce_interval_ms: int = param(1, "axis changes within this many ms go out in one message")
    sticky_buttons: bool = param(False, "a press toggles the button; a release does nothing")

    def validate(self) -> None:
        if self.device_id < 0:
            raise ParameterError("device_id", self.device_id, "must be >= 0 (N of /dev/input/jsN)")
        check_finite_range("deadzone", self.deadzone, 0.0, 1.0)
        if self.deadzone == 1.0:
            raise ParameterError("deadzone", self.deadzone, "must be below 1 (1 would leave no travel)")
        check_finite_range("autorepeat_rate", self.autorepeat_rate, 0.0, 1000.0)
        if self.coalesce_interval_ms < 0:
            raise ParameterError("coalesce_interval_ms", self.coalesce_interval_ms, "must be >= 0")

    def settings(self) -> JoySettings:
        return JoySettings(deadzone=self.deadzone, autorepeat_rate_hz=self.autorepeat_rate,
                           coalesce_interval_s=self.coalesce_interval_ms / 1000.0, sticky_buttons=self.sticky_buttons)

    def spec(self) -> DeviceSpec:
        return DeviceSpec(dev=self.dev, device_id=self.device_id, device_name=self.device_name)


class JoyNode(StepNode):
    def __init__(self, retry_s: float = RETRY_S, **kwargs: object) -> None:
        super().__init__("joy_node", **kwargs)  # type: ignore[arg-type]
        self.params = declare_parameters(self, JoyParameters)
        self.pub = self.create_publisher(Joy, "joy", 10)
        self.loop = JoystickLoop(self.params.spec(), self.params.settings(), publish=self.publish,
                                 log=self.get_logger(), retry_s=retry_s)
        self._reader = threading.Thread(target=self.loop.run, name="joy_node device", daemon=True)
        self._reader.start()

    def publish(self, state: JoyState) -> None:
        msg = Joy()
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = FRAME_ID
        msg.axes = list(state.axes)
        msg.buttons = list(state.buttons)
        self.pub.publish(msg)

    def destroy_node(self) -> None:
        self.loop.stop()
        self._reader.join(JOIN_TIMEOUT_S)
        if not self._reader.is_alive():
            self.loop.close()
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    return run_nodes([JoyNode], "joy_node", args, fatal=(ParameterError,), lockstep=False)


if __name__ == "__main__":
    sys.exit(main())
