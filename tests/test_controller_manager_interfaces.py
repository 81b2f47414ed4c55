"""ros2_control's controller_manager_msgs, built from their definitions where the environment
lacks them (``interfaces/controller_manager_msgs``): every type of Jazzy's release imports and has
its type hash, in the built type descriptions and on DDS, so a Jazzy ``ros2 control`` or spawner
talks to pppbot's controller_manager."""
from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

import pytest

from .interface_hashes import announced_hash, built_hashes

INTERFACES = Path(__file__).resolve().parent.parent / "interfaces" / "controller_manager_msgs"
#: RIHS01 hashes of Jazzy's controller_manager_msgs (ros2_control 4.42 and later), by type under
#: ``controller_manager_msgs/``. The messages' and those of SwitchController, ListControllers,
#: ListHardwareComponents and ListHardwareInterfaces as a build against /opt/ros/jazzy generated them;
#: the other services' computed from Jazzy's definitions by the RIHS01 algorithm (which gives every
#: published one).
JAZZY = {
    "msg/ChainConnection": "RIHS01_2daecd1da4b171f48b291c79747657a651eb1ab8821b68e38b1c88c736bba91c",
    "msg/ControllerManagerActivity": "RIHS01_35b7de5d611b6780e89732de325f2f765eacdb8a7adfe5821a27af4a03a7c244",
    "msg/ControllerState": "RIHS01_9a8780ab9814b6032978a07c6c7033cf1a7894ac8d948a6fb72afea07b04cc83",
    "msg/HardwareComponentState": "RIHS01_8723f76b60e3ea54920065e3e777d93c68b76fc12839ad6a6ca4e0a6439b384c",
    "msg/HardwareInterface": "RIHS01_b4c556991db81ca56a49338b5e8f0675a6707faee54fba161d2bbd4d963d418a",
    "msg/NamedLifecycleState": "RIHS01_b7947b6f8df8f7e93d1cb8d115842fb0eeddfa6fb5c7b86cc0f3cafd55be4c1f",
    "srv/CleanupController": "RIHS01_0e5e0da84cf97150abbb3a4e2249c67e6f43dba01ed9b7228b4deaab8838ec4b",
    "srv/CleanupController_Event": "RIHS01_cafd0b732cfbf29147a195659dc280f4b634daac058deac91c4994c7e6f4c9c0",
    "srv/CleanupController_Request": "RIHS01_a741f98a6de71f691fb4828428ff134d5fc2d4dedee351a3f102b4bacf39975d",
    "srv/CleanupController_Response": "RIHS01_2d36519f4ef8b8f26ea56c266c6a5d179c046eb8f80a56a7c2b1cf002202f8b7",
    "srv/ConfigureController": "RIHS01_b5de498113f4eabc7b932e019ca0498d67304b1ca465fe8a426ea89644865ff9",
    "srv/ConfigureController_Event": "RIHS01_c71eef367688ebd83962810741eb7ae65dc1930ebd36c90e077baed6195677fc",
    "srv/ConfigureController_Request": "RIHS01_027c272c6b945317d5e057515c83c747725ccaf9d345be6f6941383f6472d3a9",
    "srv/ConfigureController_Response": "RIHS01_f22a10e36403ebf6e9a54f5fa76dddb7c0af2e5417f4ff098bb0525bf89a726d",
    "srv/ListControllerTypes": "RIHS01_873e8d2bb81b8b5903ca736d299ba959f929efec4b4a18d17354b8b322822e05",
    "srv/ListControllerTypes_Event": "RIHS01_077f696f1fd887b099aa7a47b7d53c92932d05365444c9df1b12b72ded56e85b",
    "srv/ListControllerTypes_Request": "RIHS01_b6cda89b7e31f5525f7a328119f64f6bf5710db263cecb00f91e59aa9b5d41de",
    "srv/ListControllerTypes_Response": "RIHS01_4e924ba35dac47257de06fabd757aaf7bd05f47da99dc878864c9c3f9a3f721e",
    "srv/ListControllers": "RIHS01_4f8e36bb1fa5afdeba45c2d56ae6a2097b1493a253f961dd6290c085033bd189",
    "srv/ListControllers_Event": "RIHS01_33f64fb8f4d3a7415113d5b6a9fa74f91c732c5f4d491b0077cfe8f7ca15cb2b",
    "srv/ListControllers_Request": "RIHS01_fb985bc3dcc9b07c7d3af4b46787afa5a09ac79da6465ea42b5696f9355c1f70",
    "srv/ListControllers_Response": "RIHS01_445459f6b387bda67942d8bea4dfee82dedf12388317e68d5bc4513993799b86",
    "srv/ListHardwareComponents": "RIHS01_2ff105e609928671af16413362c0fdd089e1dd50c5a49d830db603ba8e4439c8",
    "srv/ListHardwareComponents_Event": "RIHS01_80e1680b8315379ca6ea4ef2d93555787e28117112f9e34ab542b0a02e6864f4",
    "srv/ListHardwareComponents_Request": "RIHS01_4d528f3bba24425b73c788ebcb6462bf77d40eb194b77682138f079f821faeab",
    "srv/ListHardwareComponents_Response": "RIHS01_9607f3bd43ebcfaa25ca4f506701fb2697186a986364f58649b43182d9dd1556",
    "srv/ListHardwareInterfaces": "RIHS01_c3e561a6e8cc7b9d577d8065c783038e51f6950cbe9bed67fb117a3e2e04d8f1",
    "srv/ListHardwareInterfaces_Event": "RIHS01_6aa711d3eb518aa9b69810354d106a740e43e33191d038c7e825f3c24f001b14",
    "srv/ListHardwareInterfaces_Request": "RIHS01_419a204c74b85adb602848d0f288fc756d0216f70bd30ab889c1d9b154ed8098",
    "srv/ListHardwareInterfaces_Response": "RIHS01_32da0652393586234856a1f44a039ff1487bdc1905fbf5068d026b77d4252e63",
    "srv/LoadController": "RIHS01_e37f7596c50c88cf8cb7a10cd376ff7579850cc63b5e787e9c8f11981f9ab4d2",
    "srv/LoadController_Event": "RIHS01_d9fb90df6cc86635447ed4c90b1fdae1b3c6287ddf5b849422431d86e0414a3d",
    "srv/LoadController_Request": "RIHS01_7a6624df1a6c972c13c9c5b71f13eda236226b7c08f118feccbbc60ad1829216",
    "srv/LoadController_Response": "RIHS01_8ce86b422a67d8150b4a2885fcce601670c39a7fddb8601df8609ed0b931ad76",
    "srv/ReloadControllerLibraries": "RIHS01_485cd0040f8a343a9596155b967363e1bc715f034bbb111f795c73d9d8056a9b",
    "srv/ReloadControllerLibraries_Event": "RIHS01_acd2b439f4276fc002218ccc57cab080edaf9db9c5d3ceccfca6a73182e119e9",
    "srv/ReloadControllerLibraries_Request": "RIHS01_c5ae8813adda2aed0e5e5558031e6f4c7834b941aa871746e86adc1cb745cda8",
    "srv/ReloadControllerLibraries_Response": "RIHS01_bea69bb80ebbb4a00023758c51fd0e3eaf308c1ae6640fdf4bbad6793bb967d4",
    "srv/SetHardwareComponentState": "RIHS01_940b15846ed3e1fb561ab45edf77a992b811fd59c574f45d5205a84a0deb2f65",
    "srv/SetHardwareComponentState_Event": "RIHS01_9a0beabf9d13de743ceeefca3134a94fb3bf1163e38934a36e5658bd6fc30ed7",
    "srv/SetHardwareComponentState_Request": "RIHS01_22c9b3e32a02221d411a47dab1fda921003a96ac41e8de7d4d805e2cfd0de21d",
    "srv/SetHardwareComponentState_Response": "RIHS01_c230aa244dd97d761e27ccde7b5056ec4e28e0bb804da283e42cd37944c46592",
    "srv/SwitchController": "RIHS01_d4ad10aa5da7808bc522d55d4123d8ef79de73d049d165639d7663ac37cc9895",
    "srv/SwitchController_Event": "RIHS01_4b6895b5e983daaa9f3fc5adbf26b42a4d0780ece941ac4ca5864c33063cc99d",
    "srv/SwitchController_Request": "RIHS01_d258d35c1ce6d7469e0155900202519be21f82c2641393540babd728a09cfa50",
    "srv/SwitchController_Response": "RIHS01_b7e90d1a67a2e4e3da7064ffb328cfe3111147a1a55cafaafd73b1d66681a251",
    "srv/UnloadController": "RIHS01_4055728e84c041348648d7f808c6681562000e3a9ce9fbb42c3350df25773f16",
    "srv/UnloadController_Event": "RIHS01_36594c047dd22e326ee4717f80df62ae5db0452169b84cf5b95d52ba2b4dfbbb",
    "srv/UnloadController_Request": "RIHS01_90f14a0b402791210988f4931be46a62edc7f6c90d0551c54c9a7cbce1b56ea1",
    "srv/UnloadController_Response": "RIHS01_4636099a7eaa6a9f3b299504878d58d580123f738e235c9df7bc46ef7b8f3461",
}


def definitions() -> list[tuple[str, str]]:
    return [(kind, path.stem) for kind in ("msg", "srv") for path in sorted((INTERFACES / kind).glob(f"*.{kind}"))]


@pytest.mark.parametrize(("kind", "name"), definitions(), ids=[f"{k}/{n}" for k, n in definitions()])
def test_every_definition_imports(kind: str, name: str):
    assert hasattr(importlib.import_module(f"controller_manager_msgs.{kind}"), name)


def test_every_type_of_the_release_is_there():
    assert len(definitions()) == 17  # 6 messages, 11 services
    assert len(JAZZY) == 6 + 11 * 4  # a service: itself, its request, response and event
    assert {f"{kind}/{name}" for kind, name in definitions()} == {n for n in JAZZY if n.count("_") == 0}


def test_every_type_hash_is_jazzys():
    built = built_hashes("controller_manager_msgs")
    assert {name: built.get(name) for name in JAZZY} == JAZZY


def test_the_shapes_are_jazzys():
    from controller_manager_msgs.msg import ControllerState, HardwareComponentState, HardwareInterface
    from controller_manager_msgs.srv import (
        CleanupController,
        ListControllers,
        ListHardwareInterfaces,
        LoadController,
        SwitchController,
    )

    fields = ControllerState.get_fields_and_field_types()
    assert list(fields) == ["name", "state", "type", "is_async", "update_rate", "claimed_interfaces",
                            "required_command_interfaces", "required_state_interfaces", "is_chainable",
                            "is_chained", "exported_state_interfaces", "reference_interfaces", "chain_connections"]
    assert fields["chain_connections"] == "sequence<controller_manager_msgs/ChainConnection>"
    assert list(HardwareComponentState.get_fields_and_field_types()) == [
        "name", "type", "is_async", "rw_rate", "class_type", "plugin_name", "state", "command_interfaces",
        "state_interfaces"]
    assert list(ListControllers.Response.get_fields_and_field_types()) == ["controller"]
    assert list(HardwareInterface.get_fields_and_field_types()) == ["name", "data_type", "is_available", "is_claimed"]
    assert list(ListHardwareInterfaces.Response.get_fields_and_field_types()) == ["command_interfaces",
                                                                                  "state_interfaces"]
    request = SwitchController.Request.get_fields_and_field_types()
    assert list(request) == ["activate_controllers", "deactivate_controllers", "strictness", "activate_asap",
                             "timeout"]
    assert (SwitchController.Request.BEST_EFFORT, SwitchController.Request.STRICT) == (1, 2)
    assert list(LoadController.Request.get_fields_and_field_types()) == ["name"]
    assert (list(CleanupController.Request.get_fields_and_field_types()),
            list(CleanupController.Response.get_fields_and_field_types())) == (["name"], ["ok"])


@pytest.mark.ros
def test_a_publisher_announces_jazzys_hash_on_dds(ros_node: Any) -> None:
    from controller_manager_msgs.msg import HardwareComponentState

    assert (announced_hash(ros_node, HardwareComponentState, "/controller_manager_interfaces_test")
            == JAZZY["msg/HardwareComponentState"])
