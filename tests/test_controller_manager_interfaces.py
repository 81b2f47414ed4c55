"""ros2_control's controller_manager_msgs, built from their definitions where the environment
lacks them (``interfaces/controller_manager_msgs``): every type imports, with Jazzy's shapes."""
from __future__ import annotations

import importlib
from pathlib import Path

import pytest

INTERFACES = Path(__file__).resolve().parent.parent / "interfaces" / "controller_manager_msgs"


def definitions() -> list[tuple[str, str]]:
    return [(kind, path.stem) for kind in ("msg", "srv") for path in sorted((INTERFACES / kind).glob(f"*.{kind}"))]


@pytest.mark.parametrize(("kind", "name"), definitions(), ids=[f"{k}/{n}" for k, n in definitions()])
def test_every_definition_imports(kind: str, name: str):
    assert hasattr(importlib.import_module(f"controller_manager_msgs.{kind}"), name)


def test_every_type_is_there():
    assert len(definitions()) == 16  # 6 messages, 10 services


def test_the_shapes_are_jazzys():
    from controller_manager_msgs.msg import ControllerState, HardwareInterface
    from controller_manager_msgs.srv import ListControllers, ListHardwareInterfaces, LoadController, SwitchController

    fields = ControllerState.get_fields_and_field_types()
    assert list(fields) == ["name", "state", "type", "is_async", "update_rate", "claimed_interfaces",
                            "required_command_interfaces", "required_state_interfaces", "is_chainable",
                            "is_chained", "exported_state_interfaces", "reference_interfaces", "chain_connections"]
    assert fields["chain_connections"] == "sequence<controller_manager_msgs/ChainConnection>"
    assert list(ListControllers.Response.get_fields_and_field_types()) == ["controller"]
    assert list(HardwareInterface.get_fields_and_field_types()) == ["name", "data_type", "is_available", "is_claimed"]
    assert list(ListHardwareInterfaces.Response.get_fields_and_field_types()) == ["command_interfaces",
                                                                                  "state_interfaces"]
    request = SwitchController.Request.get_fields_and_field_types()
    assert list(request) == ["activate_controllers", "deactivate_controllers", "strictness", "activate_asap",
                             "timeout"]
    assert (SwitchController.Request.BEST_EFFORT, SwitchController.Request.STRICT) == (1, 2)
    assert list(LoadController.Request.get_fields_and_field_types()) == ["name"]
