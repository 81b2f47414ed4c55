"""Parameter dataclasses: ROS names, type coercion, validation messages."""
from __future__ import annotations

from dataclasses import FrozenInstanceError, dataclass, field
from typing import ClassVar

import pytest

from pppbot_common.params import (
    ParameterError,
    check_finite_range,
    description,
    from_values,
    param,
    parameter_fields,
    ros_name,
    updated,
)


@dataclass(frozen=True)
class Example:
    rate_hz: float = param(20.0, "rate")
    max_velocity: float = param(2.0, "limit", ros_name="linear.x.max_velocity")
    enabled: bool = param(True, "switch")
    beams: int = param(640, "count")
    frame: str = param("odom", "frame")
    names: list = param(["a"], "names")

    def validate(self) -> None:
        check_finite_range("rate_hz", self.rate_hz, 0.0, 1000.0, low_open=True)
        if self.beams < 1:
            raise ParameterError("beams", self.beams, "must be at least 1")


def test_defaults_and_dotted_ros_names():
    e = from_values(Example, {"linear.x.max_velocity": 1.5})
    assert (e.rate_hz, e.max_velocity, e.names) == (20.0, 1.5, ["a"])
    with pytest.raises(FrozenInstanceError):
        e.rate_hz = 1.0  # type: ignore[misc]  # the point: it is frozen


def test_integers_are_accepted_for_floats():
    e = from_values(Example, {"rate_hz": 10})
    assert e.rate_hz == 10.0 and isinstance(e.rate_hz, float)


@pytest.mark.parametrize("name, value, message", [
    ("rate_hz", "fast", "parameter 'rate_hz' = 'fast': must be a number"),
    ("enabled", 1, "parameter 'enabled' = 1: must be true or false"),
    ("beams", 2.5, "parameter 'beams' = 2.5: must be an integer"),
    ("frame", 3, "parameter 'frame' = 3: must be a string"),
    ("rate_hz", 0.0, "parameter 'rate_hz' = 0.0: must be a finite number in (0.0, 1000.0]"),
    ("rate_hz", float("nan"), "must be a finite number"),
    ("beams", 0, "parameter 'beams' = 0: must be at least 1"),
    ("bogus", 1, "parameter 'bogus' = 1: unknown parameter of Example"),
])
def test_bad_values_are_named(name, value, message):
    with pytest.raises(ParameterError) as info:
        from_values(Example, {name: value})
    assert message in str(info.value)
    assert info.value.name == name


def test_updated_keeps_other_values_and_validates():
    e = from_values(Example, {"beams": 360})
    assert updated(e, {"rate_hz": 5.0}) == Example(rate_hz=5.0, beams=360)
    with pytest.raises(ParameterError):
        updated(e, {"beams": -1})


@dataclass(frozen=True)
class Settings:
    """A plugin's settings, with no ROS in sight."""

    speed: float = 0.5
    critics: tuple[str, ...] = ("a", "b")
    scale: float = field(default=1.0, metadata={"ros_name": "Critic.scale"})
    radius: float = 0.3  # from elsewhere (the costmap)


@dataclass(frozen=True)
class SettingsParameters(Settings):
    PARAMETERS_OF: ClassVar[str] = "a plugin"
    NOT_PARAMETERS: ClassVar[frozenset[str]] = frozenset({"radius"})


def test_a_settings_dataclass_s_fields_are_parameters_typed_where_declared():
    fields = list(parameter_fields(SettingsParameters))
    assert [ros_name(f) for f in fields] == ["speed", "critics", "Critic.scale"]
    assert description(SettingsParameters, fields[0]) == "a plugin: speed"
    p = from_values(SettingsParameters, {"critics": ["c"], "Critic.scale": 2})
    assert (p.critics, p.scale, p.radius) == (("c",), 2.0, 0.3)  # a list from ROS, a tuple as declared
    with pytest.raises(ParameterError, match="'radius'.*unknown parameter"):
        from_values(SettingsParameters, {"radius": 1.0})
    with pytest.raises(ParameterError, match="'critics' = 'c': must be a list"):
        updated(p, {"critics": "c"})
    assert list(parameter_fields(Settings)) == []  # without PARAMETERS_OF, only param() fields count


def test_throttle_is_per_key():
    from pppbot_common.throttle import Throttle

    t = Throttle(5.0)
    assert t.allow("a", 0.0) and t.allow("b", 1.0)
    assert not t.allow("a", 4.9)
    assert t.allow("a", 5.0)
